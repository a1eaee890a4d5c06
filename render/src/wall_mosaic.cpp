#include <tessera/render/wall_mosaic.h>

#include <cstring>
#include <filesystem>
#include <functional>

#include <tessera/core/check.h>
#include <tessera/render/projector_pass.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::render {

Image lostTileImage(uint32_t width, uint32_t height) {
  Image img;
  img.width = width;
  img.height = height;
  img.rgba.resize(size_t(width) * height * 4);
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      const bool red = ((x + y) / 16) % 2 == 0;
      uint8_t* p = &img.rgba[(size_t(y) * width + x) * 4];
      p[0] = red ? 200 : 20;
      p[1] = red ? 30 : 20;
      p[2] = red ? 30 : 20;
      p[3] = 255;
    }
  }
  return img;
}

namespace {

/// A width x height picture of kBezelGrey with each of `tiles` copied to its offset, clipped.
Image pasteTiles(uint32_t width, uint32_t height, std::span<const Image> tiles,
                 const std::function<glm::ivec2(size_t)>& offset) {
  Image result;
  result.width = width;
  result.height = height;
  result.rgba.assign(size_t(result.width) * result.height * 4, 0);
  for (size_t i = 0; i < result.rgba.size(); i += 4) {
    result.rgba[i] = result.rgba[i + 1] = result.rgba[i + 2] = kBezelGrey;
    result.rgba[i + 3] = 255;
  }
  for (size_t t = 0; t < tiles.size(); ++t) {
    const Image& img = tiles[t];
    TESSERA_CHECK(img.rgba.size() == size_t(img.width) * img.height * 4,
                  "a tile image of width * height RGBA pixels");
    const glm::ivec2 off = offset(t);
    for (uint32_t y = 0; y < img.height; ++y) {
      if (off.y + int(y) < 0 || off.y + y >= result.height) continue;
      for (uint32_t x = 0; x < img.width; ++x) {
        if (off.x + int(x) < 0 || off.x + x >= result.width) continue;
        std::memcpy(&result.rgba[(size_t(off.y + y) * result.width + off.x + x) * 4],
                    &img.rgba[(size_t(y) * img.width + x) * 4], 4);
      }
    }
  }
  return result;
}

}  // namespace

glm::uvec2 wallPictureSize(const config::WallConfig& wall) {
  // The wall's pixel size does not depend on the camera; any valid one will do.
  config::Camera camera;
  camera.mutable_eye()->set_z(1.0);
  camera.mutable_up()->set_y(1.0);
  const ViewSetup whole = wholeWallView(wall, camera);
  return {whole.width, whole.height};
}

Image assembleWallMosaic(const config::WallConfig& wall, std::span<const Image> tiles) {
  TESSERA_CHECK(tiles.size() == size_t(wall.tiles_size()), "one image per tile of the wall");
  // Projectors' pictures are warped and blended: what the room sees is their light recomposed.
  if (hasProjectors(wall)) return recomposeScreen(wall, tiles, loadProjectorMaps(wall, false));
  const glm::uvec2 size = wallPictureSize(wall);
  return pasteTiles(size.x, size.y, tiles,
                    [&](size_t t) { return tileOffsetInWhole(wall, wall.tiles(int(t))); });
}

Image assembleProjectorFrames(const config::WallConfig& wall, std::span<const Image> pictures) {
  TESSERA_CHECK(pictures.size() == size_t(wall.tiles_size()), "one image per tile of the wall");
  const glm::uvec2 size = roomNetSize(wall);
  return pasteTiles(size.x, size.y, pictures,
                    [&](size_t t) { return roomNetOffset(wall, wall.tiles(int(t))); });
}

std::string projectorFramesPath(const std::string& screenshot) {
  const std::filesystem::path p(screenshot);
  return (p.parent_path() / (p.stem().string() + "-projectors" + p.extension().string()))
      .string();
}

}  // namespace tessera::render
