#include <tessera/render/reference_compositor.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/lod_selector.h>
#include <tessera/render/spbr.h>

namespace tessera::render {
namespace {

struct Fragment {
  float depth;  ///< view distance along the axis, world units
  uint16_t model;
  glm::u8vec3 color;
  float cosine;  ///< cos(theta) / cos(phi) of the point's surface (1 when unknown)
  float gap;     ///< three spacings: the depth gap that separates surface layers
};

}  // namespace

Image referenceSeeThrough(std::span<const ModelInstance> models, const ViewSetup& view,
                          const ReferenceOptions& options) {
  const uint32_t W = view.width, H = view.height;
  std::vector<std::vector<Fragment>> pixels(size_t(W) * H);
  const double kpx = pixelsPerUnitAtDistanceOne(view);
  for (size_t mi = 0; mi < models.size(); ++mi) {
    const ModelInstance& m = models[mi];
    if (!m.store) continue;  // the reference composites points only
    lod::PointStore& store = *m.store;
    const double unit = std::cbrt(std::abs(glm::determinant(glm::dmat3(m.model))));
    const glm::dmat4 clip_from_local = view.projection * view.view * m.model;
    const Frustum frustum = Frustum::fromMatrix(clip_from_local);
    std::vector<lod::NodeId> stack{store.root()};
    while (!stack.empty()) {
      const lod::NodeId id = stack.back();
      stack.pop_back();
      const lod::NodeInfo n = store.node(id);
      if (!frustum.intersects(n.box_min, n.box_max)) continue;
      if (!n.leaf()) {
        for (lod::NodeId c : store.children(id)) stack.push_back(c);
        continue;
      }
      const auto chunk = store.decodeChunk(id);
      const double spacing = double(n.spacing) * unit;
      const std::vector<uint32_t> normals = estimateNormals(chunk->positions, 2.5 * n.spacing);
      const glm::dmat4 to_view =
          view.view * m.model * glm::translate(glm::dmat4(1.0), chunk->offset);
      const glm::dmat4 to_clip = view.projection * to_view;
      const glm::dmat3 normal_to_view = glm::transpose(glm::inverse(glm::dmat3(to_view)));
      for (size_t i = 0; i < chunk->size(); ++i) {
        const glm::dvec4 c = to_clip * glm::dvec4(glm::dvec3(chunk->positions[i]), 1.0);
        if (c.w <= 0) continue;
        const glm::dvec3 ndc = glm::dvec3(c) / c.w;
        if (ndc.z < -1 || ndc.z > 1) continue;
        const glm::dvec2 pos((ndc.x * 0.5 + 0.5) * W, (ndc.y * 0.5 + 0.5) * H);
        const double r = 0.5 * options.splat_scale * spacing * kpx / c.w;
        const glm::dvec3 pv =
            glm::dvec3(to_view * glm::dvec4(glm::dvec3(chunk->positions[i]), 1.0));
        float cosine = 1.0f;
        if (const uint32_t q = normals[i]) {
          const glm::dvec3 nl(double(int32_t(q << 22) >> 22), double(int32_t(q << 12) >> 22),
                              double(int32_t(q << 2) >> 22));
          // Discs face the image plane (their radius goes as 1 / view depth), so the gain is
          // cos(phi) / cos(theta): theta between the normal and the ray, phi between the ray and
          // the view axis; |n . p| / |p.z| in view space.
          const glm::dvec3 nv = glm::normalize(normal_to_view * nl);
          cosine = float(std::abs(glm::dot(nv, pv)) / std::max(std::abs(pv.z), 1e-30));
        }
        glm::u8vec3 color = m.color != glm::u8vec3(0) ? m.color : options.default_color;
        if (!chunk->colors.empty()) color = glm::u8vec3(chunk->colors[i]);
        const Fragment f{float(-pv.z), uint16_t(mi), color, cosine, float(3.0 * spacing)};
        // Pixels whose centres the disc contains, and always the point's own pixel.
        const int reach = int(std::floor(r + 0.5));
        const glm::ivec2 centre(int(std::floor(pos.x)), int(std::floor(pos.y)));
        for (int dy = -reach; dy <= reach; ++dy)
          for (int dx = -reach; dx <= reach; ++dx) {
            const glm::ivec2 q = centre + glm::ivec2(dx, dy);
            if (q.x < 0 || q.y < 0 || q.x >= int(W) || q.y >= int(H)) continue;
            const glm::dvec2 off = glm::dvec2(q) + 0.5 - pos;
            if ((dx || dy) && glm::dot(off, off) > r * r) continue;
            pixels[size_t(q.y) * W + size_t(q.x)].push_back(f);
          }
      }
    }
  }
  Image img;
  img.width = W;
  img.height = H;
  img.rgba.assign(size_t(W) * H * 4, 255);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W; ++x) {
      auto& frags = pixels[size_t(y) * W + x];
      std::sort(frags.begin(), frags.end(),
                [](const Fragment& a, const Fragment& b) { return a.depth < b.depth; });
      glm::dvec3 color(0.0);
      double transmittance = 1.0;
      for (size_t i = 0; i < frags.size() && transmittance > 1e-6;) {
        // One surface layer: fragments of one model without a gap of three spacings.
        size_t j = i + 1;
        while (j < frags.size() && frags[j].model == frags[i].model &&
               frags[j].depth - frags[j - 1].depth < std::max(frags[j].gap, frags[j - 1].gap))
          ++j;
        glm::dvec3 mean(0.0);
        double cosine = 0.0;
        for (size_t k = i; k < j; ++k) {
          mean += glm::dvec3(frags[k].color);
          cosine += frags[k].cosine;
        }
        mean /= double(j - i);
        cosine = std::max(cosine / double(j - i), 0.05);
        const double alpha = std::min(1.0, double(models[frags[i].model].opacity));
        const double a = options.slant_shading && alpha < 1.0
                             ? 1.0 - std::pow(1.0 - alpha, 1.0 / cosine)
                             : alpha;
        color += transmittance * a * mean;
        transmittance *= 1.0 - a;
        i = j;
      }
      color += transmittance * glm::dvec3(options.background) * 255.0;
      uint8_t* out = &img.rgba[(size_t(H - 1 - y) * W + x) * 4];  // row 0 at the top
      for (int c = 0; c < 3; ++c) out[c] = uint8_t(std::clamp(color[c] + 0.5, 0.0, 255.0));
    }
  return img;
}

}  // namespace tessera::render
