// The foveal inset (Atelier3D, section 4.2, after Godin et al. 2004): a high-resolution
// rectangle projected inside the wall's lower-resolution context, so a group sees the whole
// object and the detail under study at once. Each inset (config::WallConfig::insets) is driven by
// nodes as tiles are: a slot "<name>" (mono) or "<name>/left" and "<name>/right" (stereo), listed
// after the tiles (wallSlots()), so the master's tile table and the nodes' join treat it as one
// more tile.
//
// Geometry: the inset's rectangle R on the wall plane has the config's size and the scene's
// centre (scene::Settings::inset, else the config's (x, y) corner); a slot renders R's off-axis
// view from the viewer's head (sync/viewer_head.h; moved by -/+ half the eye separation along
// its right axis for a stereo eye) at the inset's own pixel size, exactly as tileView() renders
// a tile of that rectangle. A stereo wall's tiles are slots per eye the same way.
//
// Blending, in linear light (gamma 2.2): with d the distance of a wall point inside R's edge and
// b the blend band, the context's weight is 1 outside R, 1 - d / b across the band and 0 deeper
// in; the inset's weight is 1 minus it. Each picture is multiplied by its weight where it is
// made (the context tiles are black under the inset minus the band, the inset black outside it),
// so the wall's light is the sum of the two, one picture. Nodes and `tessera-render --mosaic`
// weigh on the GPU (InsetPass, every frame, presented and read back alike); applySlotWeights() is
// the same on the CPU in double precision, the reference the tests hold the GPU pass to.
//
// The wall screenshot (assembleInsetWall()) is assembleWallMosaic()'s picture at the context's
// density with each inset's weighted pixels averaged down onto it and added in linear light;
// insetDetail() is R at the inset's density, the weighted context sampled up (nearest pixel) and
// the inset added. Both are pure functions of the slots' pictures, so the master's screenshot and
// `tessera-render --mosaic` give the same bytes.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tessera/camera_path.pb.h>
#include <tessera/render/gl_buffer.h>
#include <tessera/render/gl_objects.h>
#include <tessera/render/image.h>
#include <tessera/render/tile_frustum.h>
#include <tessera/scene.pb.h>
#include <tessera/sync/viewer_head.h>

namespace tessera::render {

/// One node's part of a wall: a tile (inset < 0), one eye of a stereo wall's tile, or one eye
/// of an inset.
struct WallSlot {
  /// The tile, named as its slot ("<tile>" on a mono wall; "<tile>/left", "<tile>/right" on a
  /// stereo one), or for an inset a tile named as its slot ("<name>", "<name>/left",
  /// "<name>/right") with the inset's config rectangle and pixel size.
  config::Tile tile;
  int inset = -1;  ///< index in wall.insets(), or -1 for a tile
  int eye = 0;     ///< -1 left, +1 right, 0 mono, kBothEyes (eyes_on_one_node)
  int tile_index = -1;  ///< a tile's index in wall.tiles(), or -1 for an inset
};

/// WallSlot::eye of a stereo wall's tile whose node draws both eyes (eyes_on_one_node): its
/// picture is the left eye's and the right eye's side by side, twice the tile's width.
constexpr int kBothEyes = 2;

/// The wall's tiles in config order (a stereo wall's: each tile's left eye, then its right; with
/// eyes_on_one_node one slot a tile for both), then each inset's slots (mono: one; stereo: left,
/// right).
std::vector<WallSlot> wallSlots(const config::WallConfig& wall);

/// The slot of one eye (-1, +1) of a kBothEyes slot: its config tile at its own pixel size.
WallSlot eyeOfSlot(const config::WallConfig& wall, const WallSlot& both, int eye);

/// Copies an eye's picture (RGBA8 words, width x height, top row first) into its half of a
/// kBothEyes slot's picture (2 width x height): the left eye's into the left half. Runs on the
/// GPU (a row a copy); a GL 4.5 context must be current.
void copyEyeIntoPair(uint32_t eye_buffer, uint32_t pair_buffer, uint32_t width, uint32_t height,
                     int eye);

/// The pictures of one eye of a wall, as the slots of `wall` without stereo tiles
/// (monoWall()): each tile's picture for `eye` (-1 left, +1 right; a mono wall's tiles whatever
/// the eye; a kBothEyes slot's half), then every inset slot's as it is. `slots[i]` is the
/// picture of wallSlots(wall)[i].
/// Precondition (TESSERA_CHECK): one picture a slot.
std::vector<Image> eyePictures(const config::WallConfig& wall, std::span<const Image> slots,
                               int eye);
/// `wall` with `stereo` cleared: the wall one eye of it shows (its slots: one per tile).
config::WallConfig monoWall(const config::WallConfig& wall);

/// An inset's rectangle on the wall plane (metres) and its blend band (metres).
struct InsetRect {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  double band = 0;
  /// False when the scene switches the inset off (scene::InsetCentre::hidden): the context's
  /// weight is 1 over it and the inset's 0.
  bool shown = true;
};

/// Inset `index`'s rectangle where the scene places it: its centre from `placement` when it names
/// the inset, else the config's (x, y) corner; moved the least amount that keeps it inside the
/// wall's extent (wallExtent()), so a node never draws outside it. Precondition (TESSERA_CHECK):
/// index < wall.insets_size().
InsetRect insetRect(const config::WallConfig& wall, int index,
                    const scene::InsetPlacement& placement);

/// What is wrong with placing an inset at `centre` on `wall` (an inset it does not have, a
/// centre that is not finite or puts the inset outside the wall's extent), or nothing.
std::optional<std::string> insetPlacementProblem(const config::WallConfig& wall,
                                                 const scene::InsetCentre& centre);

/// The context's weight at wall point (x, y), metres: 1 outside every inset, 0 under an inset
/// beyond its band, linear across the band (the product over the insets).
double contextWeight(const config::WallConfig& wall, const scene::InsetPlacement& placement,
                     double x, double y);
/// One inset's weight at (x, y): 0 outside its rectangle, 1 minus the context's weight of that
/// inset inside it.
double insetWeight(const InsetRect& rect, double x, double y);

/// The view a slot renders from the viewer's head `head` (sync/viewer_head.h; null: the wall's
/// eye, right axis +x): tileView() of its tile with the eye offset sync::eyeOffset() gives for
/// the slot's eye (a stereo wall's tile: at the wall's eye separation); for an inset, the
/// off-axis view of its rectangle (insetRect()) at its pixel size from that eye (at the inset's
/// separation), its origin 0 (a picture of its own). A head without a separation of its own
/// uses the slot's. Precondition (TESSERA_CHECK): not a kBothEyes slot (eyeOfSlot() gives its
/// eyes).
ViewSetup slotView(const config::WallConfig& wall, const WallSlot& slot,
                   const scene::InsetPlacement& placement, const config::Camera& camera,
                   const sync::ViewerHead* head = nullptr);

/// Multiplies a slot's picture (slotView()'s size, RGBA, top row first) by its weight in linear
/// light (gamma 2.2; alpha kept): a tile by the context's weight, an inset by its own, with its
/// border (config::Inset::border, light grey) drawn just inside the band. A wall without insets
/// leaves tiles as they are. Precondition (TESSERA_CHECK): the image has the slot's pixel size.
void applySlotWeights(const config::WallConfig& wall, const WallSlot& slot,
                      const scene::InsetPlacement& placement, Image& image);

/// applySlotWeights() on the GPU (shaders/inset.comp), for nodes and `tessera-render --mosaic`:
/// the same weights in single precision, so a pixel may differ from the CPU's by one level where
/// its value rounds half way. Writes into a buffer of its own (the rendered picture is kept for
/// the renderer's next frame). A GL 4.5 context must be current for the object's whole life.
class InsetPass {
 public:
  InsetPass();
  /// Weighs `image_buffer` (RGBA8 words, top row first, the slot's pixel size:
  /// ViewRenderer::imageBuffer()) for `slot`. Precondition (TESSERA_CHECK): at most 64 insets.
  /// Cost: one pass over the pixels, a weight per inset for a tile.
  void run(uint32_t image_buffer, const config::WallConfig& wall, const WallSlot& slot,
           const scene::InsetPlacement& placement);
  /// The last run's picture: a GL buffer (for a window to present) and read back.
  uint32_t imageBuffer() const { return mOut.name(); }
  Image read() const;

 private:
  GlProgram mProgram;
  GlBuffer mOut;
  uint32_t mWidth = 0, mHeight = 0;
};

/// The wall screenshot: assembleWallMosaic() of the tiles' (weighted) pictures, bezels weighted
/// as the context, with each inset's weighted picture (a stereo inset's left eye) averaged down
/// to the context's density over its rectangle and added in linear light. `slots[i]` is the
/// picture of wallSlots(wall)[i]. A wall without insets: assembleWallMosaic(). A stereo wall:
/// its left eye (assembleWallEye()). Preconditions as assembleWallMosaic's, one picture a slot.
Image assembleInsetWall(const config::WallConfig& wall, std::span<const Image> slots,
                        const scene::InsetPlacement& placement);
/// One eye of a stereo wall (-1 left, +1 right): assembleInsetWall() of monoWall(wall) with
/// that eye's tiles (eyePictures()). A mono wall gives the same picture for either eye.
Image assembleWallEye(const config::WallConfig& wall, std::span<const Image> slots,
                      const scene::InsetPlacement& placement, int eye);

/// Inset `index`'s rectangle at its own density: the weighted context (the tiles and bezels of
/// assembleInsetWall(), before any inset is added) sampled up, nearest pixel, plus the inset's
/// weighted picture for `eye` (-1 left, +1 right; 0 for a mono inset) in linear light. On a
/// stereo wall the context is that eye's (a mono inset's: the left's).
Image insetDetail(const config::WallConfig& wall, std::span<const Image> slots,
                  const scene::InsetPlacement& placement, int index, int eye);

/// Where insetDetail() of an inset is written beside a wall screenshot: "shot.png" gives
/// "shot-inset-NAME.png" (stereo: "shot-inset-NAME-left.png", "-right.png").
std::string insetPicturePath(const std::string& screenshot, const std::string& name, int eye);

/// Throws RenderError "FILE: actions[i].setInset: what" for a path's setInset action that
/// names an inset the wall lacks or leaves the wall (insetPlacementProblem()).
void checkPathInsets(const config::CameraPath& path, const config::WallConfig& wall,
                     const std::string& file);

/// Gamma 2.2: an 8-bit value's light in [0, 1], and back (rounded, clamped).
double linearFromByte(uint8_t v);
uint8_t byteFromLinear(double light);

}  // namespace tessera::render
