// The bunny's ear as labels of space, for tests and benches of selections on stores built from
// the bunny (its reconstruction as a mesh store, its scans as a point store), whose elements are
// not the reconstruction's vertices.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <unordered_map>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/mesh.h>
#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>
#include <tessera/annotate/lazy_snapping.h>
#include <tessera/annotate/selection.h>

#include "snapping_models.h"

namespace tessera::test {

/// The ear of the bunny's reconstruction (tests/support/snapping_models.h bunnyEar()) as labels
/// of space: a position is "ear" or "not ear" by the nearest reconstruction vertex within 2 mm
/// (a grid of 2 mm cells), unknown farther away and where vertices of both labels lie within
/// `margin` (the ear's base, decided to a few millimetres only).
class EarLabels {
 public:
  explicit EarLabels(const std::filesystem::path& data_dir) {
    mSamples = annotate::surfaceFromMesh(lod::readMesh(bunnyMeshPath(data_dir)));
    mEar = bunnyEar(mSamples);
    for (uint32_t i = 0; i < mSamples.size(); ++i)
      if (!mSamples.neighboursOf(i).empty()) mGrid[key(cell(mSamples.positions[i]))].push_back(i);
  }
  /// 1 ear, 0 not ear, -1 unknown.
  int label(const glm::dvec3& p, double margin = 0.0) const {
    const glm::ivec3 c = cell(p);
    double best = kReach * kReach;
    int out = -1;
    bool ear = false, other = false;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it = mGrid.find(key(c + glm::ivec3(dx, dy, dz)));
          if (it == mGrid.end()) continue;
          for (uint32_t i : it->second) {
            const glm::dvec3 d = mSamples.positions[i] - p;
            const double d2 = glm::dot(d, d);
            if (d2 < best) {
              best = d2;
              out = mEar[i];
            }
            if (d2 < margin * margin) (mEar[i] ? ear : other) = true;
          }
        }
    return ear && other ? -1 : out;
  }
  const annotate::SurfaceSamples& samples() const { return mSamples; }

 private:
  static constexpr double kReach = 0.002;
  static glm::ivec3 cell(const glm::dvec3& p) { return glm::ivec3(glm::floor(p / kReach)); }
  static int64_t key(const glm::ivec3& c) {
    return (int64_t(c.x) & 0xfffff) | (int64_t(c.y) & 0xfffff) << 20 |
           (int64_t(c.z) & 0xfffff) << 40;
  }
  annotate::SurfaceSamples mSamples;
  std::vector<uint8_t> mEar;
  std::unordered_map<int64_t, std::vector<uint32_t>> mGrid;
};

/// IoU of a selection of a mesh store's leaf triangles against the ear: the triangles whose
/// three vertices are the ear's.
inline double earIoU(const lod::MeshStore& store, const annotate::Selection& sel,
                     const EarLabels& ear) {
  std::vector<uint8_t> got, want;
  for (lod::NodeId id = 0; id < store.nodeCount(); ++id) {
    if (!store.node(id).leaf()) continue;
    const lod::MeshPatch p = store.readPatch(id);
    const glm::dvec3 at = store.summary().origin + p.offset;
    for (uint32_t t = 0; t < p.triangles(); ++t) {
      bool in = true;
      for (int k = 0; k < 3; ++k)
        in = in && ear.label(at + glm::dvec3(p.positions[p.indices[3 * t + k]])) == 1;
      want.push_back(in);
      got.push_back(sel.contains(id, t));
    }
  }
  return annotate::intersectionOverUnion(got, want);
}

/// IoU of a selection of a point store's leaf points against the ear (points with no
/// reconstruction vertex within 2 mm, scan noise, left out).
inline double earIoU(lod::PointStore& store, const annotate::Selection& sel, const EarLabels& ear) {
  std::vector<uint8_t> got, want;
  std::vector<lod::NodeId> stack{store.root()};
  while (!stack.empty()) {
    const lod::NodeId id = stack.back();
    stack.pop_back();
    if (!store.node(id).leaf()) {
      for (lod::NodeId c : store.children(id)) stack.push_back(c);
      continue;
    }
    const auto c = store.loadChunk(id);
    for (uint32_t k = 0; k < c->size(); ++k) {
      const int label = ear.label(store.summary().origin + c->offset + glm::dvec3(c->positions[k]));
      if (label < 0) continue;
      want.push_back(uint8_t(label));
      got.push_back(sel.contains(id, k));
    }
  }
  return annotate::intersectionOverUnion(got, want);
}

/// A selection payload's elements.
inline annotate::Selection selectionOf(const std::string& bytes) {
  return annotate::Selection::deserialize(
      {reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()});
}

}  // namespace tessera::test
