// Screen-space ambient occlusion (render/ao_pass.h) on depth planes written directly from
// analytic surfaces: planes facing the camera or tilted 60 degrees under an off-axis frustum are
// unoccluded; a 90 degree groove's visibility near its crease equals the cosine-weighted
// hemisphere integral over the wedge (numerical, with the same radius and falloff) and rises
// monotonically away from it; a CPU reference of the same estimator (same hash, directions,
// taps, denoise and upsample) agrees pixel for pixel; the same frames give the same image, a
// tile of a wall the same pixels as the whole; accumulated frames approach many slices; half
// resolution stays near full resolution on smooth relief; the denoise keeps a depth step's far
// side unoccluded; bad options are refused with a message.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <numbers>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/core/check.h>
#include <tessera/render/ao_pass.h>
#include <tessera/render/gl_context.h>

namespace tessera::render {
namespace {

constexpr uint8_t kGrey = 200;
constexpr float kPi = std::numbers::pi_v<float>;

class AoPassTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { sContext = GlContext::createHeadless().release(); }
  static void TearDownTestSuite() { delete sContext; }
  static GlContext* sContext;
};
GlContext* AoPassTest::sContext = nullptr;

/// A surface as its view depth (positive, along -z) on the ray through view-space direction
/// (dx, dy, -1); NaN or <= 0: nothing there.
using Surface = std::function<double(double dx, double dy)>;

/// A picture: its size, projection and depth plane (raster order).
struct Picture {
  uint32_t width = 0, height = 0;
  glm::dmat4 projection{1.0};
  std::vector<uint32_t> depth;
};

/// The frustum (left, right, bottom, top at near 1) of a centred perspective view.
glm::dvec4 frustumOf(double fovy_degrees, double aspect) {
  const double t = std::tan(glm::radians(fovy_degrees) / 2.0);
  return {-t * aspect, t * aspect, -t, t};
}

/// `surface` seen through frustum `f` (at near 1, so a pixel's ray direction is read off it):
/// window depth per pixel centre.
Picture draw(uint32_t w, uint32_t h, const glm::dvec4& f, const Surface& surface) {
  Picture p;
  p.width = w;
  p.height = h;
  const double near = 0.1, far = 100.0;
  p.projection = glm::frustum(f.x * near, f.y * near, f.z * near, f.w * near, near, far);
  p.depth.assign(size_t(w) * h, kEmptyDepth);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const double dx = f.x + (f.y - f.x) * (x + 0.5) / w;
      const double dy = f.z + (f.w - f.z) * (y + 0.5) / h;
      const double z = surface(dx, dy);
      if (!(z > 0.0)) continue;
      const double ndc = (p.projection[2][2] * -z + p.projection[3][2]) / z;
      p.depth[size_t(y) * w + x] = std::bit_cast<uint32_t>(float(ndc * 0.5 + 0.5));
    }
  return p;
}

void upload(const GlBuffer& to, const std::vector<uint32_t>& words) {
  const GlBuffer from(words.size() * 4, words.data());
  glCopyNamedBufferSubData(from.name(), to.name(), 0, 0, GLsizeiptr(words.size() * 4));
}

/// A target holding the picture's depth and a grey image (black where empty).
std::unique_ptr<FrameTarget> targetOf(const Picture& p) {
  auto t = std::make_unique<FrameTarget>(p.width, p.height);
  upload(t->depth(), p.depth);
  std::vector<uint32_t> image(p.depth.size());
  for (uint32_t y = 0; y < p.height; ++y)
    for (uint32_t x = 0; x < p.width; ++x)
      image[size_t(p.height - 1 - y) * p.width + x] =
          p.depth[size_t(y) * p.width + x] == kEmptyDepth
              ? 0xFF000000u
              : kGrey | kGrey << 8 | kGrey << 16 | 0xFF000000u;
  upload(t->image(), image);
  return t;
}

/// The pass run on the picture for frames 0 .. frames - 1: the last visibility.
std::vector<float> visibility(const Picture& p, const AoOptions& o, int frames = 1,
                              glm::ivec2 origin = glm::ivec2(0), Image* image = nullptr) {
  auto target = targetOf(p);
  AoPass pass;
  for (int f = 0; f < frames; ++f) pass.run(*target, o, p.projection, uint32_t(f), origin);
  if (image) *image = target->readImage();
  return pass.readVisibility();
}

/// Enabled, at full resolution unless a test asks for half.
AoOptions enabled() {
  AoOptions o;
  o.enabled = true;
  o.half_resolution = false;
  return o;
}

// ---- surfaces ------------------------------------------------------------------------------

/// The plane through (0, 0, -z0) with unit normal n (view space).
Surface plane(double z0, const glm::dvec3& n) {
  return [=](double dx, double dy) {
    const glm::dvec3 d(dx, dy, -1.0);
    const double t = glm::dot(n, glm::dvec3(0, 0, -z0)) / glm::dot(n, d);
    return t;  // the depth along -z: d.z = -1
  };
}

/// A 90 degree groove, its crease along the view's y axis at depth `crease`, each face at 45
/// degrees to the view axis (the crease farthest).
Surface groove(double crease) {
  return [=](double dx, double) { return crease / (1.0 + std::abs(dx)); };
}

// ---- the reference: the same estimator on the CPU, in float --------------------------------

uint32_t pcg(uint32_t v) {
  const uint32_t state = v * 747796405u + 2891336453u;
  const uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

/// ao.comp's stages 0-2 for frames 0 .. frames - 1, from the same uniforms as AoPass sets.
struct Reference {
  const Picture& pic;
  AoOptions o;
  glm::ivec2 origin;
  glm::ivec2 size, grid, parity;
  glm::vec2 ndc_scale;
  glm::vec4 proj;
  float p22, p32, pixel_scale, edge_tau;
  std::vector<glm::vec2> dirs;

  Reference(const Picture& p, const AoOptions& options, glm::ivec2 org)
      : pic(p), o(options), origin(org) {
    size = glm::ivec2(int(p.width), int(p.height));
    parity = o.half_resolution ? (origin & 1) : glm::ivec2(0);
    grid = o.half_resolution ? (size - parity + 1) / 2 : size;
    ndc_scale = glm::vec2(float(2.0 / size.x), float(2.0 / size.y));
    proj = glm::vec4(float(p.projection[0][0]), float(p.projection[1][1]),
                     float(p.projection[2][0]), float(p.projection[2][1]));
    p22 = float(p.projection[2][2]);
    p32 = float(p.projection[3][2]);
    const double scale = p.projection[1][1] * double(size.y) / 2.0;
    pixel_scale = float(scale);
    edge_tau = float(4.0 / scale);
    for (int i = 0; i < kAoDirections; ++i) {
      const double a = std::numbers::pi * double(i) / kAoDirections;
      dirs.emplace_back(float(std::cos(a)), float(std::sin(a)));
    }
  }

  bool inside(glm::ivec2 q) const { return q.x >= 0 && q.y >= 0 && q.x < size.x && q.y < size.y; }
  uint32_t bits(glm::ivec2 q) const { return pic.depth[size_t(q.y) * size.x + q.x]; }
  float linear(uint32_t b) const {
    const float ndc = std::bit_cast<float>(b) * 2.0f - 1.0f;
    return p32 / (ndc + p22);
  }
  glm::vec3 point(glm::ivec2 q, uint32_t b) const {
    const float z = linear(b);
    const float nx = (float(q.x) + 0.5f) * ndc_scale.x - 1.0f;
    const float ny = (float(q.y) + 0.5f) * ndc_scale.y - 1.0f;
    return {z * (nx + proj.z) / proj.x, z * (ny + proj.w) / proj.y, -z};
  }
  glm::ivec2 target(glm::ivec2 g) const { return o.half_resolution ? 2 * g + parity : g; }

  glm::vec3 normal(glm::ivec2 p, const glm::vec3& P, uint32_t b) const {
    glm::vec3 d[2];
    const float dp = std::bit_cast<float>(b);
    auto at = [&](glm::ivec2 q) { return inside(q) ? bits(q) : kEmptyDepth; };
    for (int axis = 0; axis < 2; ++axis) {
      const glm::ivec2 step = axis == 0 ? glm::ivec2(1, 0) : glm::ivec2(0, 1);
      const glm::ivec2 a = p + step, b = p - step;
      const uint32_t da = at(a), db = at(b), daa = at(a + step), dbb = at(b - step);
      auto error = [&](uint32_t d1, uint32_t d2) {
        return d1 != kEmptyDepth && d2 != kEmptyDepth
                   ? std::abs(dp - 2.0f * std::bit_cast<float>(d1) + std::bit_cast<float>(d2))
                   : 1e30f;
      };
      const bool use_a = da != kEmptyDepth && (db == kEmptyDepth || error(da, daa) <= error(db, dbb));
      const glm::vec3 A = da != kEmptyDepth ? point(a, da) : P;
      const glm::vec3 B = db != kEmptyDepth ? point(b, db) : P;
      d[axis] = use_a ? A - P : P - B;
    }
    glm::vec3 n = glm::cross(d[0], d[1]);
    const float len = glm::length(n);
    if (!(len > 0.0f)) return glm::normalize(-P);
    n /= len;
    return glm::dot(n, P) > 0.0f ? -n : n;
  }

  float gtao(glm::ivec2 p, uint32_t b, uint32_t frame) const {
    const glm::vec3 P = point(p, b);
    const glm::vec3 V = glm::normalize(-P);
    const glm::vec3 N = normal(p, P, b);
    const float z = -P.z;
    float r_px = o.radius > 0.0f ? o.radius * pixel_scale / z : o.radius_px;
    r_px = std::clamp(r_px, 1.0f, kAoMaxRadiusPx);
    const float r = r_px * z / pixel_scale;
    const float mul = -1.0f / (kAoFalloff * r), add = 1.0f / kAoFalloff;
    const glm::uvec2 global = glm::uvec2(p + origin);
    const uint32_t h = pcg(global.x + pcg(global.y)), h2 = pcg(h);
    const double turn = double(frame) * 0.6180339887498949;
    const double shift = double(frame) * 0.7548776662466927;
    const uint32_t base =
        (h & 255u) + uint32_t((turn - std::floor(turn)) * double(kAoDirections / o.slices));
    const float jitter =
        float((h2 + uint32_t((shift - std::floor(shift)) * 65536.0)) & 0xFFFFu) / 65536.0f;
    float sum = 0.0f, open = 0.0f;
    for (int slice = 0; slice < o.slices; ++slice) {
      const glm::vec2 dir = dirs[(base + uint32_t(slice * 256 / o.slices)) & 255u];
      const glm::vec3 dv(dir, 0.0f);
      const glm::vec3 ortho = dv - glm::dot(dv, V) * V;
      const glm::vec3 axis = glm::normalize(glm::cross(ortho, V));
      const glm::vec3 np = N - axis * glm::dot(N, axis);
      const float np_len = glm::length(np);
      if (!(np_len > 1e-6f)) continue;
      const float cos_n = std::clamp(glm::dot(np, V) / np_len, -1.0f, 1.0f);
      const float n = (glm::dot(ortho, np) < 0.0f ? -1.0f : 1.0f) * std::acos(cos_n);
      const float sin_n = std::sin(n);
      float e0 = 0.0f, e1 = 0.0f;
      const float to_sine = 1.0f / np_len;
      for (int k = 0; k < o.steps; ++k) {
        const float s = (float(k) + jitter) / float(o.steps);
        const float t = 1.0f + s * s * (r_px - 1.0f);
        const glm::vec2 offset = dir * t;
        const glm::ivec2 off(int(std::floor(offset.x + 0.5f)), int(std::floor(offset.y + 0.5f)));
        for (int side = 0; side < 2; ++side) {
          const glm::ivec2 q = side == 0 ? p + off : p - off;
          if (!inside(q) || bits(q) == kEmptyDepth) continue;
          const glm::vec3 delta = point(q, bits(q)) - P;
          const float dist = glm::length(delta);
          if (!(dist > 0.0f)) continue;
          const float w = std::clamp(dist * mul + add, 0.0f, 1.0f);
          const float e = w * glm::dot(delta, N) / dist * to_sine;
          float& top = side == 0 ? e0 : e1;
          top = std::max(top, e);
        }
      }
      const float h0 = n - kPi / 2 + std::asin(std::min(e1, 1.0f));
      const float h1 = n + kPi / 2 - std::asin(std::min(e0, 1.0f));
      sum += np_len * 0.25f *
             (-std::cos(2 * h0 - n) + cos_n + 2 * h0 * sin_n - std::cos(2 * h1 - n) + cos_n +
              2 * h1 * sin_n);
      open += np_len * (cos_n + n * sin_n);
    }
    return open > 0.0f ? std::clamp(sum / open, 0.0f, 1.0f) : 1.0f;
  }

  /// The visibility per target pixel after frames 0 .. frames - 1 (-1 where empty).
  std::vector<float> run(int frames) const {
    std::vector<float> mean(size_t(grid.x) * grid.y, -1.0f);
    for (int f = 0; f < std::min(frames, o.max_frames); ++f)
      for (int y = 0; y < grid.y; ++y)
        for (int x = 0; x < grid.x; ++x) {
          const glm::ivec2 p = target({x, y});
          const uint32_t b = inside(p) ? bits(p) : kEmptyDepth;
          if (b == kEmptyDepth) continue;
          const float v = gtao(p, b, uint32_t(f));
          float& m = mean[size_t(y) * grid.x + x];
          m = f == 0 || m < 0.0f ? v : m + (v - m) / float(f + 1);
        }
    std::vector<float> plane = mean;
    if (o.denoise) {
      const float binomial[5] = {1, 4, 6, 4, 1};
      for (int y = 0; y < grid.y; ++y)
        for (int x = 0; x < grid.x; ++x) {
          const float c = mean[size_t(y) * grid.x + x];
          if (c < 0.0f) continue;
          const glm::ivec2 p = target({x, y});
          const float z = linear(bits(p));
          float sum = 0.0f, weight = 0.0f;
          for (int dy = -2; dy <= 2; ++dy)
            for (int dx = -2; dx <= 2; ++dx) {
              const glm::ivec2 g(x + dx, y + dy);
              if (g.x < 0 || g.y < 0 || g.x >= grid.x || g.y >= grid.y) continue;
              const float v = mean[size_t(g.y) * grid.x + g.x];
              const glm::ivec2 q = target(g);
              if (v < 0.0f || !inside(q)) continue;
              const float apart = glm::length(glm::vec2(q - p));
              if (std::abs(linear(bits(q)) - z) > edge_tau * z * (1.0f + apart)) continue;
              sum += binomial[dx + 2] * binomial[dy + 2] * v;
              weight += binomial[dx + 2] * binomial[dy + 2];
            }
          plane[size_t(y) * grid.x + x] = sum / weight;
        }
    }
    std::vector<float> out(size_t(size.x) * size.y, -1.0f);
    for (int y = 0; y < size.y; ++y)
      for (int x = 0; x < size.x; ++x) {
        const glm::ivec2 p(x, y);
        if (bits(p) == kEmptyDepth) continue;
        float& v = out[size_t(y) * size.x + x];
        if (!o.half_resolution) {
          v = plane[size_t(y) * size.x + x];
          continue;
        }
        const float z = linear(bits(p));
        const glm::ivec2 rel = p - parity;
        const glm::ivec2 g0(int(std::floor(rel.x * 0.5f)), int(std::floor(rel.y * 0.5f)));
        const glm::vec2 f = glm::vec2(rel) * 0.5f - glm::vec2(g0);
        float sum = 0.0f, weight = 0.0f, nearest = -1.0f, nearest_dz = 1e30f;
        for (int k = 0; k < 9; ++k) {
          const glm::ivec2 g = g0 + glm::ivec2(k % 3 - 1, k / 3 - 1);
          if (g.x < 0 || g.y < 0 || g.x >= grid.x || g.y >= grid.y) continue;
          const float pv = plane[size_t(g.y) * grid.x + g.x];
          if (pv < 0.0f) continue;
          const glm::ivec2 q = target(g);
          const float dz = std::abs(linear(bits(q)) - z);
          if (dz < nearest_dz) nearest_dz = dz, nearest = pv;
          const glm::ivec2 cell = g - g0;
          if (cell.x < 0 || cell.y < 0) continue;
          if (dz > edge_tau * z * (1.0f + glm::length(glm::vec2(q - p)))) continue;
          const float w = (cell.x == 0 ? 1.0f - f.x : f.x) * (cell.y == 0 ? 1.0f - f.y : f.y);
          sum += w * pv;
          weight += w;
        }
        v = weight > 0.0f ? sum / weight : nearest >= 0.0f ? nearest : 1.0f;
      }
    return out;
  }
};

/// Covered pixels at least `border` from the picture's edge.
template <typename F>
void forInterior(const Picture& p, int border, F f) {
  for (int y = border; y < int(p.height) - border; ++y)
    for (int x = border; x < int(p.width) - border; ++x)
      if (p.depth[size_t(y) * p.width + x] != kEmptyDepth) f(x, y, size_t(y) * p.width + x);
}

// ---- tests ---------------------------------------------------------------------------------

TEST_F(AoPassTest, APlaneFacingTheCameraIsUnoccluded) {
  const Picture p = draw(96, 64, frustumOf(40.0, 1.5), plane(3.0, {0, 0, 1}));
  for (bool half : {false, true}) {
    AoOptions o = enabled();
    o.radius_px = 12.0f;
    o.half_resolution = half;
    const std::vector<float> v = visibility(p, o);
    const int border = AoPass::reach(o, p.projection, p.height, 3.0f);
    float worst = 1.0f;
    size_t n = 0;
    forInterior(p, border, [&](int, int, size_t i) { worst = std::min(worst, v[i]), ++n; });
    EXPECT_GT(n, 1000u);
    EXPECT_GT(worst, 0.995f) << (half ? "half" : "full") << " resolution";
  }
}

TEST_F(AoPassTest, APlaneTilted60DegreesUnderAnOffAxisFrustumIsUnoccluded) {
  // An off-axis frustum (a wall tile's) and a plane turned 60 degrees about the view's x axis:
  // a wrong unprojection (a centred frustum assumed) or a wrong normal bends the plane and
  // occludes one side.
  const glm::dvec4 f(-0.1, 0.5, -0.15, 0.25);
  const double a = glm::radians(60.0);
  const Picture p = draw(96, 64, f, plane(3.0, {0.0, std::sin(a), std::cos(a)}));
  AoOptions o = enabled();
  o.radius = 0.3f;
  o.slices = 4;
  const std::vector<float> v = visibility(p, o);
  const int border = AoPass::reach(o, p.projection, p.height, 2.0f);
  float worst = 1.0f;
  size_t n = 0;
  forInterior(p, border, [&](int, int, size_t i) { worst = std::min(worst, v[i]), ++n; });
  EXPECT_GT(n, 200u);
  EXPECT_GT(worst, 0.99f);
}

/// The cosine-weighted visibility of a point on one face of a 90 degree groove, `s` from the
/// crease, the other face a wall; occlusion weighted by the pass's falloff for radius r:
/// integrated on the projected disc (Malley: uniform on the disc is cosine-weighted on the
/// hemisphere), the crease's direction along the disc's x axis.
double grooveVisibility(double s, double r) {
  const int n = 1000;
  double occluded = 0.0;
  size_t count = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = 2.0 * (i + 0.5) / n - 1.0, y = 2.0 * (j + 0.5) / n - 1.0;
      if (x * x + y * y > 1.0) continue;
      ++count;
      if (x <= 0.0) continue;  // away from the wall
      const double t = s / x;  // the distance to the wall's plane along the ray
      occluded += std::clamp((r - t) / (kAoFalloff * r), 0.0, 1.0);
    }
  return 1.0 - occluded / double(count);
}

TEST_F(AoPassTest, AGrooveMatchesTheWedgeIntegralAtTheCreaseAndBrightensAwayFromIt) {
  const uint32_t w = 128, h = 96;
  const double crease = 4.0;
  const Picture p = draw(w, h, frustumOf(40.0, double(w) / h), groove(crease));
  AoOptions o = enabled();
  o.radius = 0.6f;  // about 25 pixels at the crease
  o.slices = 8;
  o.steps = 16;
  o.denoise = false;
  o.max_frames = 16;
  const std::vector<float> v = visibility(p, o, 16);
  // Per column right of the crease, the mean over the middle rows, against the integral at the
  // column's distance from the crease (along the face: its view x times sqrt(2)).
  const Reference ref(p, o, glm::ivec2(0));
  std::vector<double> got;
  for (uint32_t x = w / 2; x < w / 2 + 40; ++x) {
    double sum = 0.0;
    int n = 0;
    for (uint32_t y = h / 4; y < 3 * h / 4; ++y, ++n) sum += v[size_t(y) * w + x];
    got.push_back(sum / n);
    const glm::vec3 point = ref.point({int(x), int(h / 2)}, p.depth[size_t(h / 2) * w + x]);
    const double s = std::sqrt(2.0) * point.x;
    const double want = grooveVisibility(s, o.radius);
    // Next to the crease nearly every ray towards the other face meets it at once (a half
    // exactly on the crease). Further out GTAO's falloff (a tap's elevation pulled down to the
    // tangent line by its distance) and the reference's per-ray weight differ by up to 0.06,
    // GTAO the brighter.
    const double tolerance = x < w / 2 + 2 ? 0.03 : 0.06;
    EXPECT_NEAR(got.back(), want, tolerance) << "column " << x - w / 2 << " from the crease, s " << s;
    if (x == w / 2) EXPECT_NEAR(want, 0.5, 0.03);
  }
  for (size_t i = 1; i < got.size(); ++i)
    EXPECT_GE(got[i], got[i - 1] - 0.002) << "column " << i << " from the crease";
  EXPECT_GT(got.back(), 0.99);
  // The other face is the mirror image.
  double left = 0.0;
  for (uint32_t y = h / 4; y < 3 * h / 4; ++y) left += v[size_t(y) * w + w / 2 - 1];
  EXPECT_NEAR(left / (h / 2), got.front(), 0.02);
}

/// A groove with a round bump on one face, a raised box on the other, a hole and the empty
/// top-right corner: creases, silhouettes, depth steps and empty neighbours.
Picture busyScene(uint32_t w, uint32_t h) {
  const Surface g = groove(3.0);
  return draw(w, h, frustumOf(45.0, double(w) / h), [&](double dx, double dy) {
    if (dx > 0.2 && dy > 0.15) return 0.0;                   // empty
    if (std::abs(dx + 0.05) < 0.03 && std::abs(dy) < 0.05) return 6.0;  // a hole to a far wall
    double z = g(dx, dy);
    const double bump = 0.09 - (dx - 0.15) * (dx - 0.15) - (dy + 0.1) * (dy + 0.1);
    if (bump > 0.0) z -= 2.0 * std::sqrt(bump);
    if (dx < -0.15 && dx > -0.3 && dy > 0.0) z -= 0.4;  // a box standing out of the face
    return z;
  });
}

TEST_F(AoPassTest, TheGpuPassEqualsACpuReferenceOfTheSameEstimator) {
  const Picture p = busyScene(64, 48);
  struct Case {
    bool half, denoise;
    int frames;
    glm::ivec2 origin;
  };
  for (const Case& c : {Case{false, false, 1, {0, 0}}, Case{false, true, 3, {7, -5}},
                        Case{true, false, 2, {0, 0}}, Case{true, true, 3, {3, 8}}}) {
    AoOptions o = enabled();
    o.radius = 0.35f;
    o.half_resolution = c.half;
    o.denoise = c.denoise;
    const std::vector<float> got = visibility(p, o, c.frames, c.origin);
    const std::vector<float> want = Reference(p, o, c.origin).run(c.frames);
    ASSERT_EQ(got.size(), want.size());
    size_t covered = 0, darker = 0;
    float worst = 0.0f;
    for (size_t i = 0; i < got.size(); ++i) {
      ASSERT_EQ(got[i] < 0.0f, want[i] < 0.0f) << "pixel " << i;
      if (want[i] < 0.0f) continue;
      ++covered;
      darker += want[i] < 0.9f;
      worst = std::max(worst, std::abs(got[i] - want[i]));
    }
    EXPECT_LT(worst, 1e-3f) << "half " << c.half << " denoise " << c.denoise;
    EXPECT_GT(covered, size_t(64 * 48 / 2));
    EXPECT_GT(darker, covered / 20) << "the scene must have occlusion to compare";
  }
}

TEST_F(AoPassTest, TheSameFramesGiveTheSameImageAndATileEqualsTheWholePicture) {
  const uint32_t W = 160, H = 120;
  const glm::dvec4 f = frustumOf(45.0, double(W) / H);
  const Picture whole = draw(W, H, f, [&](double dx, double dy) {
    if (dx > 0.25 && dy > 0.2) return 0.0;  // empty
    return groove(3.0)(dx, dy) - 0.3 * std::sin(9.0 * dy);
  });
  for (bool half : {false, true}) {
    AoOptions o = enabled();
    o.radius = 0.15f;
    o.half_resolution = half;
    Image a, b;
    const std::vector<float> va = visibility(whole, o, 4, {0, 0}, &a);
    visibility(whole, o, 4, {0, 0}, &b);
    EXPECT_EQ(a.rgba, b.rgba);
    // A tile at an odd origin, with its own off-axis frustum and the whole's depth there.
    for (glm::ivec2 origin : {glm::ivec2(37, 21), glm::ivec2(64, 40)}) {
      const glm::ivec2 size(88, 72);
      Picture tile;
      tile.width = uint32_t(size.x);
      tile.height = uint32_t(size.y);
      const glm::dvec4 tf(f.x + (f.y - f.x) * origin.x / W, f.x + (f.y - f.x) * (origin.x + size.x) / W,
                          f.z + (f.w - f.z) * origin.y / H, f.z + (f.w - f.z) * (origin.y + size.y) / H);
      tile.projection = glm::frustum(tf.x * 0.1, tf.y * 0.1, tf.z * 0.1, tf.w * 0.1, 0.1, 100.0);
      for (int y = 0; y < size.y; ++y)
        for (int x = 0; x < size.x; ++x)
          tile.depth.push_back(whole.depth[size_t(origin.y + y) * W + origin.x + x]);
      const std::vector<float> vt = visibility(tile, o, 4, origin);
      // The surface's nearest depth: 3 / 1.55 - 0.3.
      const int border = AoPass::reach(o, tile.projection, tile.height, 1.6f);
      float worst = 0.0f;
      size_t compared = 0;
      forInterior(tile, border, [&](int x, int y, size_t i) {
        worst = std::max(worst, std::abs(vt[i] - va[size_t(origin.y + y) * W + origin.x + x]));
        ++compared;
      });
      EXPECT_GT(compared, 50u);
      EXPECT_LT(worst, 1e-3f) << "half " << half << " tile at " << origin.x << "," << origin.y;
    }
  }
}

TEST_F(AoPassTest, SixteenFramesOfTwoSlicesApproachThirtyTwoSlices) {
  const Picture p = busyScene(96, 72);
  AoOptions o = enabled();
  o.radius = 0.35f;
  o.denoise = false;
  AoOptions many = o;
  many.slices = 32;
  const std::vector<float> truth = visibility(p, many, 1);
  auto error = [&](const std::vector<float>& v) {
    double e = 0.0;
    size_t n = 0;
    for (size_t i = 0; i < v.size(); ++i)
      if (truth[i] >= 0.0f) e += std::abs(v[i] - truth[i]), ++n;
    return e / double(n);
  };
  const double one = error(visibility(p, o, 1)), sixteen = error(visibility(p, o, 16));
  EXPECT_LT(sixteen, 0.5 * one) << "frame 0 " << one << ", 16 frames " << sixteen;
  // Beyond max_frames the mean stays.
  o.max_frames = 4;
  EXPECT_EQ(visibility(p, o, 4), visibility(p, o, 9));
}

TEST_F(AoPassTest, HalfResolutionStaysNearFullResolutionOnSmoothRelief) {
  const Picture p = draw(128, 96, frustumOf(40.0, 128.0 / 96.0), [](double dx, double dy) {
    return 3.0 + 0.35 * std::sin(14.0 * dx) * std::sin(11.0 * dy);
  });
  AoOptions o = enabled();
  o.radius = 0.5f;
  AoOptions half = o;
  half.half_resolution = true;
  const std::vector<float> full = visibility(p, o, 16), low = visibility(p, half, 16);
  const int border = AoPass::reach(half, p.projection, p.height, 2.5f);
  std::vector<float> diff;
  float darkest = 1.0f;
  forInterior(p, border, [&](int, int, size_t i) {
    diff.push_back(std::abs(full[i] - low[i]));
    darkest = std::min(darkest, full[i]);
  });
  std::sort(diff.begin(), diff.end());
  double mean = 0.0;
  for (float d : diff) mean += d;
  mean /= double(diff.size());
  EXPECT_LT(darkest, 0.85f) << "the relief must occlude";
  EXPECT_LT(mean, 0.02);
  EXPECT_LT(diff[diff.size() * 99 / 100], 0.06f);
}

TEST_F(AoPassTest, TheDenoiseDoesNotBlurAcrossADepthStep) {
  // A groove at depth 3 over the upper half, a wall facing the camera at depth 6 below it: the
  // wall's pixels next to the dark crease are unoccluded (the groove lies beyond the radius),
  // and the crease's pixels next to the wall keep their darkness. A blur blind to depth would
  // mix the two across the 5x5 window (a third of its weight from the other side).
  const uint32_t w = 96, h = 64;
  const Picture p = draw(w, h, frustumOf(40.0, 1.5), [](double dx, double dy) {
    return dy > 0.0 ? groove(3.0)(dx, dy) : 6.0;
  });
  for (bool half : {false, true}) {
    AoOptions o = enabled();
    o.radius = 0.5f;
    o.half_resolution = half;
    AoOptions raw = o;
    raw.denoise = false;
    const std::vector<float> v = visibility(p, o, 4), r = visibility(p, raw, 4);
    float wall = 1.0f, crease = 0.0f;
    for (uint32_t y = h / 2 - 6; y < h / 2; ++y)
      for (uint32_t x = w / 2 - 3; x < w / 2 + 3; ++x) wall = std::min(wall, v[size_t(y) * w + x]);
    // What the denoise does to the crease beside the step and far above it (there it blurs
    // along the faces only): the same.
    auto change = [&](uint32_t y) {
      float c = 0.0f;
      for (uint32_t x = w / 2 - 1; x <= w / 2; ++x) {
        const size_t i = size_t(y) * w + x;
        crease = std::max(crease, r[i]);
        c += v[i] - r[i];
      }
      return c / 2.0f;
    };
    const float crease_change = std::abs(change(h / 2) - change(h / 2 + 16));
    EXPECT_GT(wall, 0.99f) << (half ? "half" : "full");
    EXPECT_LT(crease, 0.8f) << (half ? "half" : "full");
    EXPECT_LT(crease_change, 0.03f) << (half ? "half" : "full");
  }
}

TEST_F(AoPassTest, TheImageIsMultipliedWhereCoveredAndUntouchedElsewhere) {
  const Picture p = busyScene(64, 48);
  AoOptions o = enabled();
  o.radius = 0.35f;
  o.strength = 2.0f;
  Image img;
  const std::vector<float> v = visibility(p, o, 1, {0, 0}, &img);
  size_t checked = 0;
  for (uint32_t y = 0; y < p.height; ++y)
    for (uint32_t x = 0; x < p.width; ++x) {
      const uint8_t* px = &img.rgba[(size_t(p.height - 1 - y) * p.width + x) * 4];
      const float vis = v[size_t(y) * p.width + x];
      if (vis < 0.0f) {
        EXPECT_EQ(px[0], 0);  // the background stays
        continue;
      }
      EXPECT_NEAR(px[0], kGrey * std::pow(vis, 2.0f), 0.6);
      EXPECT_EQ(px[3], 255);
      ++checked;
    }
  EXPECT_GT(checked, 1000u);
}

TEST_F(AoPassTest, BadOptionsAreRefusedWithAMessage) {
  const Picture p = draw(32, 32, frustumOf(40.0, 1.0), plane(3.0, {0, 0, 1}));
  auto target = targetOf(p);
  AoPass pass;
  auto refused = [&](AoOptions o, const char* why) {
    EXPECT_FALSE(aoOptionsError(o).empty()) << why;
    EXPECT_THROW(pass.run(*target, o, p.projection, 0), PreconditionError) << why;
  };
  AoOptions o = enabled();
  o.radius = std::nanf("");
  refused(o, "NaN radius");
  o = enabled();
  o.radius = 0.0f;
  o.radius_px = -1.0f;
  refused(o, "no radius");
  o = enabled();
  o.steps = -3;
  refused(o, "negative steps");
  o = enabled();
  o.slices = 0;
  refused(o, "no slices");
  o = enabled();
  o.strength = std::numeric_limits<float>::infinity();
  refused(o, "infinite strength");
  o = enabled();
  o.max_frames = 0;
  refused(o, "no frames");
  try {
    o = enabled();
    o.slices = 0;
    pass.run(*target, o, p.projection, 0);
  } catch (const PreconditionError& e) {
    EXPECT_NE(std::string(e.what()).find("slices"), std::string::npos) << e.what();
  }
  EXPECT_THROW(pass.run(*target, enabled(), glm::ortho(-1.0, 1.0, -1.0, 1.0, 0.1, 10.0), 0),
               PreconditionError);
  // Disabled or zero strength: nothing is touched, bad fields are not looked at.
  o.enabled = false;
  EXPECT_EQ(pass.run(*target, o, p.projection, 0), 0.0);
  EXPECT_TRUE(aoOptionsError(enabled()).empty());
}

}  // namespace
}  // namespace tessera::render
