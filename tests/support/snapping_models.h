// Test models of known labels for lazy snapping, shared by tests/master/lazy_snapping_test.cpp
// and bench/lazy_snapping.cpp: a sphere with a coloured cap, the Stanford bunny's ear.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <random>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/annotate/lazy_snapping.h>

namespace tessera::test {

using annotate::ScreenView;
using annotate::SurfaceSamples;

/// A UV sphere of radius 1 with `rings` latitude rings; vertices with z > 0.5 (the cap) are
/// red, the rest blue, each channel with uniform noise of +-20.
inline lod::Mesh cappedSphere(uint32_t rings, std::vector<uint8_t>* cap) {
  lod::Mesh mesh;
  const uint32_t segments = 2 * rings;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> noise(-20, 20);
  auto add = [&](const glm::dvec3& p) {
    mesh.positions.push_back(p);
    const bool in_cap = p.z > 0.5;
    const glm::ivec3 base = in_cap ? glm::ivec3(200, 60, 50) : glm::ivec3(60, 90, 180);
    mesh.colors.emplace_back(base.r + noise(rng), base.g + noise(rng), base.b + noise(rng), 255);
    if (cap) cap->push_back(in_cap ? 1 : 0);
  };
  add({0, 0, 1});
  for (uint32_t r = 1; r < rings; ++r) {
    const double theta = M_PI * double(r) / double(rings);
    for (uint32_t s = 0; s < segments; ++s) {
      const double phi = 2 * M_PI * double(s) / double(segments);
      add({std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)});
    }
  }
  add({0, 0, -1});
  const uint32_t south = uint32_t(mesh.positions.size() - 1);
  auto ring = [&](uint32_t r, uint32_t s) { return 1 + (r - 1) * segments + s % segments; };
  for (uint32_t s = 0; s < segments; ++s) {
    mesh.triangles.emplace_back(0, ring(1, s), ring(1, s + 1));
    mesh.triangles.emplace_back(south, ring(rings - 1, s + 1), ring(rings - 1, s));
    for (uint32_t r = 1; r + 1 < rings; ++r) {
      mesh.triangles.emplace_back(ring(r, s), ring(r + 1, s), ring(r + 1, s + 1));
      mesh.triangles.emplace_back(ring(r, s), ring(r + 1, s + 1), ring(r, s + 1));
    }
  }
  return mesh;
}

/// Samples within `r` of the 3D polyline: a stroke as the pick under it would give it.
inline std::vector<uint32_t> samplesNear(const SurfaceSamples& s,
                                         const std::vector<glm::dvec3>& line, double r) {
  std::vector<uint32_t> out;
  for (uint32_t i = 0; i < s.size(); ++i)
    for (size_t k = 0; k + 1 < line.size(); ++k) {
      const glm::dvec3 ab = line[k + 1] - line[k];
      const double t =
          std::clamp(glm::dot(s.positions[i] - line[k], ab) / glm::dot(ab, ab), 0., 1.);
      if (glm::length(s.positions[i] - (line[k] + t * ab)) <= r) {
        out.push_back(i);
        break;
      }
    }
  return out;
}

/// An orthographic view of [-1.2, 1.2]^2 from +z, 480 x 480 pixels (200 pixels per unit).
inline ScreenView topView() {
  ScreenView v;
  v.view = glm::lookAt(glm::dvec3(0, 0, 5), glm::dvec3(0), glm::dvec3(0, 1, 0));
  v.projection = glm::ortho(-1.2, 1.2, -1.2, 1.2, 0.1, 10.0);
  v.viewport = {480, 480};
  return v;
}

/// The bunny's right (taller, free-standing) ear, fixed by looking at bun_zipper.ply (y up):
/// its axis runs from its root near (-0.055, 0.152, 0) to its tip, the highest vertex, at
/// about (-0.016, 0.187, -0.02). The ear is the set of vertices connected to the tip through
/// vertices beyond a plane across that axis. Moving the plane towards the head in 1 mm steps,
/// the set grows by ~30 vertices a step until, 5 mm before the root point, it leaks into the
/// head (2113 -> 4143 vertices): that last plane before the leak is the ear's base. Loose
/// vertices of no triangle (the scan has 1113) are not surface and never in the set.
inline std::vector<uint8_t> bunnyEar(const SurfaceSamples& s) {
  constexpr double kBase = -0.005;  // metres along the axis from the root point
  const glm::dvec3 axis = glm::normalize(glm::dvec3(0.039, 0.035, -0.02));
  const glm::dvec3 root(-0.055, 0.152, 0.0);
  uint32_t tip = 0;
  for (uint32_t i = 0; i < s.size(); ++i)
    if (s.positions[i].y > s.positions[tip].y) tip = i;
  std::vector<uint8_t> ear(s.size(), 0);
  std::vector<uint32_t> frontier{tip};
  ear[tip] = 1;
  for (size_t k = 0; k < frontier.size(); ++k)
    for (uint32_t j : s.neighboursOf(frontier[k]))
      if (!ear[j] && glm::dot(s.positions[j] - root, axis) > kBase) {
        ear[j] = 1;
        frontier.push_back(j);
      }
  return ear;
}

/// The bunny seen from +z, orthographic, [-0.11, 0.07] x [0.02, 0.2] on 540 x 540 pixels
/// (3000 pixels per metre, a vertex every 2 to 3 pixels).
inline ScreenView bunnyView() {
  ScreenView v;
  v.view = glm::lookAt(glm::dvec3(0, 0, 1), glm::dvec3(0), glm::dvec3(0, 1, 0));
  v.projection = glm::ortho(-0.11, 0.07, 0.02, 0.2, 0.1, 2.0);
  v.viewport = {540, 540};
  return v;
}

inline glm::dvec2 bunnyPixel(double x, double y) {
  return {(x + 0.11) * 3000.0, (y - 0.02) * 3000.0};
}

/// Strokes as a user draws them on bunnyView() (4 pixels wide): along the ear from near its
/// tip to near its base; across the head and down the back.
inline std::vector<glm::dvec2> bunnyEarStroke() {
  return {bunnyPixel(-0.02, 0.178), bunnyPixel(-0.045, 0.162)};
}
inline std::vector<glm::dvec2> bunnyHeadStroke() {
  return {bunnyPixel(-0.085, 0.13), bunnyPixel(-0.06, 0.14), bunnyPixel(-0.03, 0.125),
          bunnyPixel(0.0, 0.12)};
}

/// The robust lasso's heavy stroke as a user would draw it around the ear: the convex hull
/// (counter-clockwise, Andrew's monotone chain) of the ear's visible vertices on the screen.
inline std::vector<glm::dvec2> earOutline(const SurfaceSamples& s, const std::vector<uint8_t>& ear,
                                          const std::vector<uint8_t>& visible,
                                          const ScreenView& view) {
  std::vector<glm::dvec2> p;
  for (uint32_t i = 0; i < s.size(); ++i)
    if (ear[i] && visible[i]) p.push_back(annotate::project(view, s.positions[i]).pixel);
  std::sort(p.begin(), p.end(),
            [](auto a, auto b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  if (p.size() < 3) return p;
  auto cross = [](glm::dvec2 o, glm::dvec2 a, glm::dvec2 b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
  };
  std::vector<glm::dvec2> h(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}

/// The Stanford bunny's reconstruction (35947 vertices, 69451 triangles).
inline std::filesystem::path bunnyMeshPath(const std::filesystem::path& data_dir) {
  return data_dir / "stanford-bunny/reconstruction/bun_zipper.ply";
}

}  // namespace tessera::test
