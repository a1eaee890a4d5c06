// Off-axis (generalized perspective) projections for the tiles of a display wall, after
// Kooima's "Generalized Perspective Projection": each tile is a window on the wall plane seen
// from the viewer's eye, so geometry continues straight across bezels and a wall of tiles shows
// exactly what one large view of the whole wall would (Atelier3D, section on walls).
//
// Frames: the wall frame has the wall plane at z = 0 (x right, y up, metres) and the eye at
// z > 0. The scene camera (eye, target, up) places the wall eye in the world: camera space is
// the wall frame translated so the eye is at the origin, looking down -z.
//
// Rooms: a tile with a plane of its own (Tile.origin, right, up: a CAVE's walls and floor, an
// L-shaped or angled wall, facets of a curved screen) gets Kooima's general form: the wall frame
// rotated into the screen's basis (right, up, normal), then the asymmetric frustum of the
// rectangle at its distance from the eye. The wall screenshot of a room is its net
// (roomNetOffset()): the tiles side by side in the order of the config.
#pragma once

#include <array>
#include <cstdint>

#include <glm/glm.hpp>

#include <tessera/sync/config.h>

namespace tessera::render {

/// What one view renders: world -> camera, camera -> clip, and its pixel size; for a wall view
/// also which eye sees it and at what pixel density, so stereo eyes and insets at another
/// density fit the same mosaic code.
struct ViewSetup {
  glm::dmat4 view{1.0};
  glm::dmat4 projection{1.0};
  uint32_t width = 0, height = 0;
  glm::dvec3 eye_world{0.0};  ///< this view's eye in the world (eye offset included)
  /// The eye's offset from the wall's viewer eye, wall frame, metres (stereo: -/+ half the
  /// interpupillary distance along x; 0 for a mono view).
  glm::dvec3 eye_offset{0.0};
  /// Pixels per metre on the wall plane, x and y (0 for views that are not of a wall).
  glm::dvec2 pixels_per_metre{0.0};
  /// This view's top-left pixel in the larger picture it is a part of (a tile in the whole
  /// wall: tileOffsetInWhole(); 0 for a picture of its own). Passes that seed their samples by
  /// pixel use the position in that picture, so a tile draws what the whole wall draws there.
  glm::ivec2 origin{0};
  /// The size of that larger picture, pixels (a tile: the whole wall's, wholeWallView(); a
  /// poster's part: the poster's; a view with a guard band: the view without it); 0 for a
  /// picture of its own. With `origin` it rebuilds the whole picture's view (wholeView()),
  /// whose LOD cut the parts share. A room's tiles (screens on planes of their own) have none.
  glm::uvec2 whole_size{0};
};

/// The view of the whole picture `part` belongs to (ViewSetup::whole_size): the same eye and
/// projection plane, the frustum widened in NDC to the whole's pixels. `part` itself when it
/// is a picture of its own.
ViewSetup wholeView(const ViewSetup& part);

/// World -> camera matrix of a scene camera (right-handed, looking down -z, y up).
glm::dmat4 cameraView(const config::Camera& camera);

/// Projection of the wall-plane rectangle [x0, x1] x [y0, y1] (metres) seen from `eye` (wall
/// frame, eye.z > 0): an asymmetric frustum with the given near and far distances (metres).
glm::dmat4 offAxisProjection(const glm::dvec3& eye, double x0, double x1, double y0, double y1,
                             double near, double far);

/// The view of one tile, seen from the wall's eye moved by `eye_offset` (wall frame, metres;
/// a stereo pair is two views with -/+ half the interpupillary distance along x: points on the
/// wall plane land on the same pixel in both, points behind it further apart).
ViewSetup tileView(const config::WallConfig& wall, const config::Tile& tile,
                   const config::Camera& camera, const glm::dvec3& eye_offset = glm::dvec3(0.0));

/// A tile's rectangle in the wall frame: lower-left corner, unit axes and the normal towards the
/// eye (right x up), metres. A tile without a plane of its own: (x, y, 0), +x, +y, +z.
struct TilePlane {
  glm::dvec3 origin{0.0}, right{1.0, 0.0, 0.0}, up{0.0, 1.0, 0.0}, normal{0.0, 0.0, 1.0};
  double width = 0, height = 0;
  /// The point at (u, v) of the rectangle (0..1, u right, v down from the top-left corner).
  glm::dvec3 at(double u, double v) const {
    return origin + right * (u * width) + up * ((1.0 - v) * height);
  }
  /// (u, v) of a point on the plane (the inverse of at()).
  glm::dvec2 uv(const glm::dvec3& p) const {
    return {glm::dot(p - origin, right) / width, 1.0 - glm::dot(p - origin, up) / height};
  }
};

/// Whether the tile has a plane of its own (any of origin, right, up set).
bool hasOwnPlane(const config::Tile& tile);
/// Whether any tile of the wall has a plane of its own: the wall is a room, its screenshot a net.
bool isRoom(const config::WallConfig& wall);
TilePlane tilePlane(const config::Tile& tile);
/// Whether two tiles lie on one plane (normals within 1e-6, offsets within 1e-6 m): where
/// projectors may overlap and blend.
bool samePlane(const TilePlane& a, const TilePlane& b);

/// Kooima's general projection: world -> clip for the screen `plane` seen from `eye` (wall
/// frame) as a matrix on camera space (wall frame translated by -eye), i.e. P M^T of the paper:
/// `rotation` takes camera space into the screen's basis, `projection` is the frustum.
void screenProjection(const TilePlane& plane, const glm::dvec3& eye, double near, double far,
                      glm::dmat4& rotation, glm::dmat4& projection);

/// Pixels between tiles in a room's net.
constexpr int kRoomNetGap = 16;

/// Where a tile's pixel (0, 0) falls in a room's net: the tiles side by side, left to right in
/// the order of the config, tops aligned, kRoomNetGap pixels apart.
glm::ivec2 roomNetOffset(const config::WallConfig& wall, const config::Tile& tile);
/// The net's size in pixels.
glm::uvec2 roomNetSize(const config::WallConfig& wall);

/// A single wide-angle view from the wall's eye (the reference a room's tiles are compared
/// with): looking where the camera looks, `fov_degrees` across the wider side.
ViewSetup eyeView(const config::WallConfig& wall, const config::Camera& camera, uint32_t width,
                  uint32_t height, double fov_degrees);

/// `view` grown by `band` pixels on every side: the same pixels at the same places, with
/// (width + 2 band) x (height + 2 band) pixels and its frustum widened to match (the projection
/// scaled in NDC), its origin moved up and left by `band`. Screen passes whose kernels reach
/// `band` pixels draw the inner pixels as a larger picture would (a wall tile's guard band).
ViewSetup withGuardBand(const ViewSetup& view, uint32_t band);

/// The whole wall's extent as one view, at the pixel density of its first tile (pixels per metre),
/// so tile pixels and whole-wall pixels line up one to one. For a room (isRoom()): eyeView() at
/// the net's size (roomNetSize()), 120 degrees across.
ViewSetup wholeWallView(const config::WallConfig& wall, const config::Camera& camera);

/// Where a tile's pixel (0, 0) (top-left) falls in the whole-wall image of wholeWallView(); for a
/// room, in its net (roomNetOffset()).
glm::ivec2 tileOffsetInWhole(const config::WallConfig& wall, const config::Tile& tile);

/// The wall's bounding rectangle on its plane: min x, min y, max x, max y (metres).
glm::dvec4 wallExtent(const config::WallConfig& wall);

/// Six planes (a, b, c, d), inside where a x + b y + c z + d >= 0, of a clip matrix (Gribb and
/// Hartmann's extraction), in the space the matrix takes points from.
struct Frustum {
  std::array<glm::dvec4, 6> planes;
  static Frustum fromMatrix(const glm::dmat4& clip_from_space);
  /// Conservative box test: false only if the box is entirely outside one plane.
  bool intersects(const glm::dvec3& box_min, const glm::dvec3& box_max) const;
};

}  // namespace tessera::render
