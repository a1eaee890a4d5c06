// The whole wall as one picture from its tiles' pictures: each tile at its place in
// wholeWallView()'s image, the bezels (the gaps between tiles) dark grey. What
// `tessera-render --mosaic` writes and what the master assembles from its nodes' read-backs for a
// wall screenshot ("The frame", step 6), so both give the same pixels.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include <glm/glm.hpp>

#include <tessera/render/image.h>
#include <tessera/sync/config.h>

namespace tessera::render {

/// The R, G and B of bezel pixels (opaque).
constexpr uint8_t kBezelGrey = 24;

/// What a wall screenshot shows for a tile whose node is lost (dead, hung, never joined): red and
/// near-black diagonal stripes 16 pixels wide, so a lost tile is never mistaken for a stale or
/// dark picture. width x height RGBA. Cost: one pass over the image.
Image lostTileImage(uint32_t width, uint32_t height);

/// The size of the wall's picture (assembleWallMosaic(), the screenshot): wholeWallView()'s,
/// which does not depend on the camera.
glm::uvec2 wallPictureSize(const config::WallConfig& wall);

/// The wall image: wholeWallView(wall, ...).width x height, RGBA top row first. `tiles[i]` is
/// the image of wall.tiles(i) (tileView() size); each is copied to tileOffsetInWhole() and clipped
/// to the wall image; for a room (isRoom()) the image is its net (roomNetOffset()). A wall with
/// projectors (hasProjectors(): blends, warps, MPCDI) shows what the room sees instead:
/// recomposeScreen() of the tiles' pictures, reading the warps (RenderError for a bad file).
/// Precondition (TESSERA_CHECK): one image per tile, each width * height * 4 bytes. Cost: one
/// pass over the wall image; with projectors an inverse warp a pixel and tile.
Image assembleWallMosaic(const config::WallConfig& wall, std::span<const Image> tiles);

/// What a wall's projectors show, each its own frame: `pictures[i]` (what tile i's projector
/// shows: its render through the projector pass, projector_pass.h) side by side in the order of
/// the config, tops aligned, kRoomNetGap pixels apart (roomNetOffset(), roomNetSize()), the gaps
/// kBezelGrey. The master writes it beside a projector wall's screenshot, and `tessera-render
/// --mosaic` beside its picture (projectorFramesPath()). Precondition (TESSERA_CHECK): one image
/// per tile, each width * height * 4 bytes. Cost: one pass over the pictures.
Image assembleProjectorFrames(const config::WallConfig& wall, std::span<const Image> pictures);

/// The projectors' frames beside a screenshot: DIR/STEM-projectors.EXT for DIR/STEM.EXT.
std::string projectorFramesPath(const std::string& screenshot);

}  // namespace tessera::render
