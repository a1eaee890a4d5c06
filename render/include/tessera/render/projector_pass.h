// Projectors: overlapping tiles with soft-edge blend masks and warp meshes, the last screen pass
// of a node (what the projector shows and what its read-back holds), and the recomposition of
// the screen from the projectors' pictures for the master's wall screenshot.
//
// A tile's rendered image is its screen rectangle seen from the eye (tile_frustum.h). A
// projector pixel (x, y) of a tile lands on the screen at the tile's (u, v) = warp(s, t), where
// (s, t) = ((x + 0.5) / width, (y + 0.5) / height) and the warp is a grid of (u, v) vertices spread
// evenly over the projector's raster, vertex (i, j) at (s, t) = (i / (grid_width - 1),
// j / (grid_height - 1)), interpolated bilinearly (no warp: (u, v) = (s, t)); u runs right and v
// down from the rectangle's top-left corner. The projector shows the rendered image there
// (bilinear, black outside [0, 1]^2), times the blend weight w of the pixel (the fraction of the
// light it gives, linear light) applied through the projector's gamma: value * w^(1 / gamma).
//
// The automatic blend (Tile.blend "auto") gives each projector pixel w = r_i / sum_j r_j over the
// projectors on the same plane whose pictures reach its landing point, r the distance of the
// point from the nearest edge of each projector's raster (s, t units, through the inverse warp):
// 1 where a projector is alone, linear ramps over the overlap, and weights that sum to 1, so
// in linear light the projectors together give what one would.
//
// Files: a warp is a PFM (three floats a vertex: u, v and one unused; rows bottom to top as PFM
// stores them), a blend a greyscale or RGB PNG of the tile's pixel size (the weight in linear
// light, the first channel), an MPCDI file (VESA Multiple Projection Common Data Interchange
// 1.0, profiles "2d" and "3d": a zip of mpcdi.xml, per region a geometry warp PFM and an alpha
// PNG) gives the tiles named by its region ids their warps and blends. Every bad file is a
// RenderError naming the file and the field.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/render/gl_objects.h>
#include <tessera/render/image.h>
#include <tessera/sync/config.h>

namespace tessera::render {

/// What one projector does to its tile's picture: its warp grid and blend weights (CPU data).
struct ProjectorMap {
  uint32_t width = 0, height = 0;  ///< the projector's pixels (the tile's)
  double gamma = 2.2;              ///< light = value^gamma
  /// Weight per projector pixel in linear light, [0, 1], top row first; empty: no blend.
  std::vector<float> blend;
  uint32_t grid_width = 0, grid_height = 0;
  /// (u, v) per grid vertex, top row first; empty: no warp.
  std::vector<glm::vec2> warp;

  /// Whether the projector changes nothing (no blend, no warp).
  bool identity() const { return blend.empty() && warp.empty(); }
  /// (u, v) where the projector point (s, t) (0..1 over its raster) lands.
  glm::dvec2 warpAt(const glm::dvec2& st) const;
};

/// The inverse of a projector's warp: which projector point (s, t) lands on (u, v). A bucket
/// grid over the warp's cells finds the cell, Newton's method the point in it. O(cells) to build.
class WarpInverse {
 public:
  explicit WarpInverse(const ProjectorMap& map);
  /// (s, t) in [0, 1]^2, or nothing where no projector point lands on (u, v).
  std::optional<glm::dvec2> operator()(const glm::dvec2& uv) const;

 private:
  const ProjectorMap* mMap;
  glm::dvec2 mLo{0.0}, mHi{1.0};
  int mBuckets = 0;
  std::vector<std::vector<uint32_t>> mCells;  ///< per bucket: cells (j * (gw - 1) + i) overlapping
};

/// Whether any tile of the wall has a blend or a warp, or the wall names an MPCDI file.
bool hasProjectors(const config::WallConfig& wall);

/// Every tile's projector map from the wall's files (Tile.warp, Tile.blend, WallConfig.mpcdi;
/// a tile's own fields win over the MPCDI file's) and, where Tile.blend is "auto", the
/// automatic blend (`with_blend` false: warps only, what the recomposition needs;
/// `only_blend` >= 0: the automatic blend of that tile only, what its node needs). Throws
/// RenderError "render::loadProjectorMaps(): FILE: FIELD: what" for a missing or bad file: a PFM
/// that is not one, of fewer than 2 x 2 vertices, with NaN or infinities; a PNG not of the
/// tile's size; an MPCDI that is not a zip, lacks mpcdi.xml or an element, names a profile other
/// than 2d or 3d, or a region whose resolution is not its tile's. CPU only.
std::vector<ProjectorMap> loadProjectorMaps(const config::WallConfig& wall, bool with_blend = true,
                                           int only_blend = -1);

/// The automatic blend of tile `index` given every tile's map (warps set): see the file comment.
std::vector<float> autoBlend(const config::WallConfig& wall, std::span<const ProjectorMap> maps,
                             int index);

/// The projector's picture from the rendered one on the CPU (the pass's reference).
Image applyProjector(const ProjectorMap& map, const Image& rendered);

/// What the room sees: the light of every projector summed in linear light where it lands,
/// through each one's inverse warp, back in the tiles' gamma (that of the first tile reaching a
/// pixel). For a planar wall wholeWallView()'s picture (the tiles' rectangles at
/// tileOffsetInWhole()), for a room its net (each tile's rectangle with the light of every
/// projector on its plane); kBezelGrey where no projector reaches. `pictures[i]`: what tile i's
/// projector shows. Precondition (TESSERA_CHECK): one picture and one map per tile, of its size.
Image recomposeScreen(const config::WallConfig& wall, std::span<const Image> pictures,
                      std::span<const ProjectorMap> maps);

/// Reads a PFM (Portable Float Map: "PF" three channels or "Pf" one, either byte order), rows
/// top first. Throws RenderError naming `name` and what is wrong.
struct FloatImage {
  uint32_t width = 0, height = 0, channels = 0;
  std::vector<float> values;  ///< width * height * channels, top row first
};
FloatImage readPfm(std::span<const uint8_t> bytes, const std::string& name);
/// Writes a PFM (little-endian, rows bottom to top as the format stores them).
std::vector<uint8_t> writePfm(const FloatImage& image);

/// The projector pass on the GPU (shaders/projector.comp): reads a rendered RGBA8 image buffer
/// (top row first, as ViewRenderer::imageBuffer()), writes the projector's picture into a
/// buffer of its own. Cost: one pass over the pixels, 4 texel reads each with a warp (plus 4
/// grid vertices), 1 without, one weight with a blend. A GL 4.5 context must be current for the
/// object's whole life.
class ProjectorPass {
 public:
  /// Uploads the map's grid and weights. Precondition (TESSERA_CHECK): a map with a size.
  explicit ProjectorPass(const ProjectorMap& map);
  /// Runs the pass on `image_buffer` (width x height words of the map's size).
  void run(uint32_t image_buffer);
  /// The GL buffer with the last run's picture (top row first).
  uint32_t imageBuffer() const { return mOut.name(); }
  /// Reads the last run's picture back.
  Image read() const;

 private:
  uint32_t mWidth, mHeight;
  GlProgram mProgram;
  GlBuffer mOut, mBlend, mWarp;
  GlBufferTexture mBlendTexels, mWarpTexels;
  uint32_t mGridWidth = 0, mGridHeight = 0;
  bool mHasBlend = false, mHasWarp = false;
  float mInvGamma = 1.0f / 2.2f;
};

}  // namespace tessera::render
