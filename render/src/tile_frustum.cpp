#include <tessera/render/tile_frustum.h>

#include <tessera/sync/vec3.h>

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

namespace tessera::render {
using sync::vec;

glm::dmat4 cameraView(const config::Camera& camera) {
  return glm::lookAt(vec(camera.eye()), vec(camera.target()), vec(camera.up()));
}

glm::dmat4 offAxisProjection(const glm::dvec3& eye, double x0, double x1, double y0, double y1,
                             double near, double far) {
  // The window edges relative to the eye, scaled from the wall plane (distance eye.z) to the
  // near plane: Kooima 2008, eq. for l, r, b, t with an axis-aligned screen.
  const double s = near / eye.z;
  return glm::frustum((x0 - eye.x) * s, (x1 - eye.x) * s, (y0 - eye.y) * s, (y1 - eye.y) * s, near,
                      far);
}

bool hasOwnPlane(const config::Tile& tile) {
  return tile.has_origin() || tile.has_right() || tile.has_up();
}

bool isRoom(const config::WallConfig& wall) {
  return std::any_of(wall.tiles().begin(), wall.tiles().end(), hasOwnPlane);
}

TilePlane tilePlane(const config::Tile& tile) {
  TilePlane p;
  p.width = tile.width();
  p.height = tile.height();
  if (!hasOwnPlane(tile)) {
    p.origin = glm::dvec3(tile.x(), tile.y(), 0.0);
    return p;
  }
  p.origin = vec(tile.origin());
  if (tile.has_right()) p.right = glm::normalize(vec(tile.right()));
  if (tile.has_up()) p.up = glm::normalize(vec(tile.up()));
  p.normal = glm::normalize(glm::cross(p.right, p.up));
  return p;
}

bool samePlane(const TilePlane& a, const TilePlane& b) {
  return glm::length(a.normal - b.normal) < 1e-6 &&
         std::abs(glm::dot(a.origin - b.origin, a.normal)) < 1e-6;
}

void screenProjection(const TilePlane& plane, const glm::dvec3& eye, double near, double far,
                      glm::dmat4& rotation, glm::dmat4& projection) {
  // Kooima 2008: va, vb, vc from the eye to the lower-left, lower-right and upper-left corners;
  // d the eye's distance from the screen plane; the frustum edges scaled to the near plane.
  const glm::dvec3 va = plane.origin - eye, vb = va + plane.right * plane.width,
                   vc = va + plane.up * plane.height;
  const double d = -glm::dot(plane.normal, va);
  const double s = near / d;
  projection = glm::frustum(glm::dot(plane.right, va) * s, glm::dot(plane.right, vb) * s,
                            glm::dot(plane.up, va) * s, glm::dot(plane.up, vc) * s, near, far);
  // M^T: the rows are the screen's axes.
  rotation = glm::dmat4(1.0);
  for (int c = 0; c < 3; ++c) {
    rotation[c][0] = plane.right[c];
    rotation[c][1] = plane.up[c];
    rotation[c][2] = plane.normal[c];
  }
}

glm::ivec2 roomNetOffset(const config::WallConfig& wall, const config::Tile& tile) {
  int x = 0;
  for (const auto& t : wall.tiles()) {
    if (&t == &tile || t.name() == tile.name()) break;
    x += int(t.pixel_width()) + kRoomNetGap;
  }
  return {x, 0};
}

glm::uvec2 roomNetSize(const config::WallConfig& wall) {
  glm::uvec2 size(0);
  for (const auto& t : wall.tiles()) {
    size.x += t.pixel_width() + (size.x > 0 ? kRoomNetGap : 0);
    size.y = std::max(size.y, t.pixel_height());
  }
  return size;
}

ViewSetup eyeView(const config::WallConfig& wall, const config::Camera& camera, uint32_t width,
                  uint32_t height, double fov_degrees) {
  ViewSetup v;
  v.view = cameraView(camera);
  const double half = std::tan(glm::radians(fov_degrees) * 0.5) * wall.near();
  const double aspect = double(width) / double(height);
  const double hx = aspect >= 1 ? half : half * aspect, hy = aspect >= 1 ? half / aspect : half;
  v.projection = glm::frustum(-hx, hx, -hy, hy, wall.near(), wall.far());
  v.width = width;
  v.height = height;
  v.eye_world = vec(camera.eye());
  return v;
}

ViewSetup tileView(const config::WallConfig& wall, const config::Tile& tile,
                   const config::Camera& camera, const glm::dvec3& eye_offset) {
  ViewSetup v;
  // Camera space is the wall frame with the viewer's eye at the origin; an eye moved by
  // `eye_offset` sees camera space moved the other way, through its own off-axis window.
  const glm::dmat4 mono = cameraView(camera);
  v.view = glm::translate(glm::dmat4(1.0), -eye_offset) * mono;
  if (hasOwnPlane(tile)) {
    glm::dmat4 rotation;
    screenProjection(tilePlane(tile), vec(wall.eye()) + eye_offset, wall.near(), wall.far(),
                     rotation, v.projection);
    v.view = rotation * v.view;
  } else {
    v.projection =
        offAxisProjection(vec(wall.eye()) + eye_offset, tile.x(), tile.x() + tile.width(),
                          tile.y(), tile.y() + tile.height(), wall.near(), wall.far());
  }
  v.width = tile.pixel_width();
  v.height = tile.pixel_height();
  v.eye_offset = eye_offset;
  v.eye_world = glm::dvec3(glm::inverse(mono) * glm::dvec4(eye_offset, 1.0));
  v.pixels_per_metre =
      glm::dvec2(tile.pixel_width() / tile.width(), tile.pixel_height() / tile.height());
  v.origin = tileOffsetInWhole(wall, tile);
  if (!isRoom(wall)) {
    const ViewSetup whole = wholeWallView(wall, camera);
    v.whole_size = {whole.width, whole.height};
  }
  return v;
}

ViewSetup wholeView(const ViewSetup& part) {
  if (part.whole_size == glm::uvec2(0)) return part;
  // The inverse of subView() (poster.h): part NDC -> whole NDC, x' = s x + t, in clip space.
  const double W = part.whole_size.x, H = part.whole_size.y;
  const double w = part.width, h = part.height;
  glm::dmat4 m(1.0);
  m[0][0] = w / W;
  m[1][1] = h / H;
  m[3][0] = (2.0 * part.origin.x + w) / W - 1.0;
  m[3][1] = 1.0 - (2.0 * part.origin.y + h) / H;
  ViewSetup v = part;
  v.projection = m * part.projection;
  v.width = part.whole_size.x;
  v.height = part.whole_size.y;
  v.origin = glm::ivec2(0);
  v.whole_size = glm::uvec2(0);
  return v;
}

ViewSetup withGuardBand(const ViewSetup& view, uint32_t band) {
  ViewSetup v = view;
  if (band == 0) return v;
  v.width = view.width + 2 * band;
  v.height = view.height + 2 * band;
  // NDC x' = x * width / width': pixel x' = pixel x + band, the same pixel size.
  glm::dmat4 scale(1.0);
  scale[0][0] = double(view.width) / double(v.width);
  scale[1][1] = double(view.height) / double(v.height);
  v.projection = scale * view.projection;
  v.origin = view.origin - glm::ivec2(int(band));
  if (view.whole_size == glm::uvec2(0)) v.whole_size = {view.width, view.height};
  return v;
}

glm::dvec4 wallExtent(const config::WallConfig& wall) {
  glm::dvec4 e(1e300, 1e300, -1e300, -1e300);
  for (const auto& t : wall.tiles()) {
    e = glm::dvec4(std::min(e.x, t.x()), std::min(e.y, t.y()), std::max(e.z, t.x() + t.width()),
                   std::max(e.w, t.y() + t.height()));
  }
  return e;
}

ViewSetup wholeWallView(const config::WallConfig& wall, const config::Camera& camera) {
  if (isRoom(wall)) {
    const glm::uvec2 net = roomNetSize(wall);
    return eyeView(wall, camera, net.x, net.y, 120.0);
  }
  const config::Tile& first = wall.tiles(0);
  const double ppm_x = first.pixel_width() / first.width(),
               ppm_y = first.pixel_height() / first.height();
  const glm::dvec4 e = wallExtent(wall);
  ViewSetup v;
  v.view = cameraView(camera);
  v.width = uint32_t(std::lround((e.z - e.x) * ppm_x));
  v.height = uint32_t(std::lround((e.w - e.y) * ppm_y));
  // Snap the extent to whole pixels so tiles land on pixel boundaries.
  v.projection = offAxisProjection(vec(wall.eye()), e.x, e.x + v.width / ppm_x,
                                   e.w - v.height / ppm_y, e.w, wall.near(), wall.far());
  v.eye_world = vec(camera.eye());
  v.pixels_per_metre = glm::dvec2(ppm_x, ppm_y);
  return v;
}

glm::ivec2 tileOffsetInWhole(const config::WallConfig& wall, const config::Tile& tile) {
  if (isRoom(wall)) return roomNetOffset(wall, tile);
  const config::Tile& first = wall.tiles(0);
  const double ppm_x = first.pixel_width() / first.width(),
               ppm_y = first.pixel_height() / first.height();
  const glm::dvec4 e = wallExtent(wall);
  return {int(std::lround((tile.x() - e.x) * ppm_x)),
          int(std::lround((e.w - (tile.y() + tile.height())) * ppm_y))};
}

Frustum Frustum::fromMatrix(const glm::dmat4& m) {
  // Rows of the matrix (glm is column-major: m[col][row]).
  auto row = [&](int r) { return glm::dvec4(m[0][r], m[1][r], m[2][r], m[3][r]); };
  Frustum f;
  f.planes = {row(3) + row(0), row(3) - row(0), row(3) + row(1),
              row(3) - row(1), row(3) + row(2), row(3) - row(2)};
  for (auto& p : f.planes) p /= glm::length(glm::dvec3(p));
  return f;
}

bool Frustum::intersects(const glm::dvec3& lo, const glm::dvec3& hi) const {
  for (const auto& p : planes) {
    // The box corner farthest along the plane normal (the "p-vertex").
    glm::dvec3 v(p.x >= 0 ? hi.x : lo.x, p.y >= 0 ? hi.y : lo.y, p.z >= 0 ? hi.z : lo.z);
    if (glm::dot(glm::dvec3(p), v) + p.w < 0) return false;
  }
  return true;
}

}  // namespace tessera::render
