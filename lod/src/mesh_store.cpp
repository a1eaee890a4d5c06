#include <tessera/lod/mesh_store.h>

#include <cmath>
#include <fstream>

#include "crc32c.h"
#include "mesh_format.h"
#include "triangle_grid.h"

namespace tessera::lod {
namespace {

std::string nodeName(const std::string& store, NodeId id) {
  return "lod::MeshStore: " + store + ": patch " + std::to_string(id);
}

bool finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

bool isMeshStore(const std::filesystem::path& path) {
  // Only regular files are opened: a FIFO or a device would block or never end.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  return in.gcount() == 8 && std::equal(magic, magic + 8, meshfmt::kMagic);
}

std::unique_ptr<MeshStore> MeshStore::open(const std::filesystem::path& path) {
  std::unique_ptr<RangeSource> source;
  try {
    source = std::make_unique<FileRangeSource>(path);
  } catch (const RangeError& e) {
    throw StoreError("lod::MeshStore: " + path.string() + ": " + e.what());
  }
  return open(std::move(source));
}

std::unique_ptr<MeshStore> MeshStore::open(std::unique_ptr<RangeSource> source) {
  std::unique_ptr<MeshStore> s(new MeshStore());
  s->mPath = source->name();
  const std::string where = "lod::MeshStore: " + s->mPath.string();
  auto read = [&](uint64_t offset, size_t n, const char* what) {
    if (offset > source->size() || n > source->size() - offset)
      throw StoreError(where + ": truncated: " + what + " at byte " + std::to_string(offset) +
                       " (+" + std::to_string(n) + ") beyond the file's " +
                       std::to_string(source->size()) + " bytes");
    std::vector<uint8_t> bytes(n);
    try {
      source->read(offset, bytes.data(), n);
    } catch (const RangeError& e) {
      throw StoreError(where + ": reading " + what + ": " + e.what());
    }
    return bytes;
  };
  const std::vector<uint8_t> h = read(0, meshfmt::kHeaderBytes, "the header");
  if (!std::equal(h.begin(), h.begin() + 8, meshfmt::kMagic))
    throw StoreError(where + ": not a Tessera mesh store (.tmesh): wrong magic");
  meshfmt::Reader r{h.data(), h.size(), 8};
  MeshSummary& m = s->mSummary;
  m.version = r.get<uint32_t>();
  if (m.version != meshfmt::kVersion)
    throw StoreError(where + ": format version " + std::to_string(m.version) +
                     ", this build reads version " + std::to_string(meshfmt::kVersion));
  const uint32_t flags = r.get<uint32_t>();
  m.colors = (flags & meshfmt::kFlagColors) != 0;
  m.input_triangles = r.get<uint64_t>();
  m.input_vertices = r.get<uint64_t>();
  m.stored_triangles = r.get<uint64_t>();
  m.nodes = r.get<uint32_t>();
  m.depth = r.get<uint32_t>();
  for (glm::dvec3* v : {&m.origin, &m.bbox_min, &m.bbox_max})
    for (int i = 0; i < 3; ++i) (*v)[i] = r.get<double>();
  m.step = r.get<double>();
  const uint64_t table_offset = r.get<uint64_t>();
  m.file_bytes = r.get<uint64_t>();
  const uint32_t table_crc = r.get<uint32_t>();
  const size_t crc_at = r.at;
  const uint32_t header_crc = r.get<uint32_t>();
  if (crc32c(h.data(), crc_at) != header_crc)
    throw StoreError(where + ": header checksum mismatch (corrupt header)");
  if (m.file_bytes != source->size())
    throw StoreError(where + ": the header says " + std::to_string(m.file_bytes) +
                     " bytes, the file has " + std::to_string(source->size()) + " (truncated?)");
  if (m.nodes == 0 || m.nodes > meshfmt::kMaxNodes || !(m.step > 0) || !std::isfinite(m.step))
    throw StoreError(where + ": bad header: " + std::to_string(m.nodes) + " nodes, step " +
                     std::to_string(m.step));
  const std::vector<uint8_t> table =
      read(table_offset, size_t(m.nodes) * meshfmt::kNodeBytes, "the node table");
  if (crc32c(table.data(), table.size()) != table_crc)
    throw StoreError(where + ": node table checksum mismatch (corrupt table)");
  s->mNodes.resize(m.nodes);
  uint64_t payload = 0;
  for (size_t i = 0; i < m.nodes; ++i) {
    MeshNodeRecord& n = s->mNodes[i];
    n = meshfmt::readNode(table.data() + i * meshfmt::kNodeBytes);
    const std::string at = where + ": node " + std::to_string(i);
    // A tree stored breadth-first: children after their parent, inside the table.
    if (n.child_count > meshfmt::kMaxChildren ||
        (n.child_count > 0 && (n.first_child <= i || n.first_child > m.nodes ||
                               n.child_count > m.nodes - n.first_child)))
      throw StoreError(at + ": children " + std::to_string(n.first_child) + " (+" +
                       std::to_string(n.child_count) + ") do not form a tree");
    if (n.triangles > meshfmt::kMaxPatchTriangles || n.vertices > 3 * n.triangles ||
        (n.triangles > 0 && n.vertices == 0))
      throw StoreError(at + ": " + std::to_string(n.triangles) + " triangles, " +
                       std::to_string(n.vertices) + " vertices: not a patch");
    if (!finite(n.box_min) || !finite(n.box_max) || !std::isfinite(n.error) || n.error < 0)
      throw StoreError(at + ": non-finite bounds or error");
    if (n.payload_offset > m.file_bytes || n.payload_bytes > m.file_bytes - n.payload_offset)
      throw StoreError(at + ": payload beyond the end of the file");
    if (n.payload_bytes < 4)  // a payload starts with its vertex block's size
      throw StoreError(at + ": payload of " + std::to_string(n.payload_bytes) + " bytes");
    payload += n.payload_bytes;
  }
  // Each node but the root has exactly one parent.
  std::vector<uint8_t> parents(m.nodes, 0);
  for (const MeshNodeRecord& n : s->mNodes)
    for (uint32_t c = 0; c < n.child_count; ++c) ++parents[n.first_child + c];
  for (size_t i = 0; i < m.nodes; ++i) {
    if (parents[i] != (i == 0 ? 0 : 1))
      throw StoreError(where + ": node " + std::to_string(i) + " has " +
                       std::to_string(parents[i]) + " parents: not a tree");
  }
  m.payload_bytes = payload;
  s->mParents.assign(m.nodes, kNoNode);
  for (size_t i = 0; i < m.nodes; ++i)
    for (uint32_t c = 0; c < s->mNodes[i].child_count; ++c)
      s->mParents[s->mNodes[i].first_child + c] = NodeId(i);
  s->mSource = std::move(source);
  return s;
}

MeshStore::~MeshStore() = default;

NodeInfo MeshStore::node(NodeId id) const {
  const MeshNodeRecord& r = mNodes.at(id);
  NodeInfo n;
  n.level = r.level;
  n.cell = glm::u32vec3(id, 0, 0);  // a name the same in every process
  n.box_min = glm::dvec3(r.box_min);
  n.box_max = glm::dvec3(r.box_max);
  n.points = r.triangles;
  n.spacing = r.error;
  n.error_bound = r.error;
  n.child_mask = uint8_t(r.child_count >= 8 ? 0xFF : (1u << r.child_count) - 1u);
  return n;
}

std::vector<NodeId> MeshStore::children(NodeId id) {
  const MeshNodeRecord& r = mNodes.at(id);
  std::vector<NodeId> out(r.child_count);
  for (uint32_t c = 0; c < r.child_count; ++c) out[c] = r.first_child + c;
  return out;
}

MeshPatch MeshStore::readPatch(NodeId id, std::stop_token cancel) const {
  const MeshNodeRecord& r = mNodes.at(id);
  const std::string where = nodeName(mPath.string(), id);
  std::vector<uint8_t> bytes(r.payload_bytes);
  auto read = [&] {
    try {
      mSource->read(r.payload_offset, bytes.data(), bytes.size(), cancel);
    } catch (const ReadCancelled&) {
      throw;
    } catch (const RangeError& e) {
      throw StoreError(where + ": " + e.what());
    }
  };
  read();
  // A copy that fails its checksum is read once more where the source can fetch it again (a
  // site's disk cache of a chunk server's ranges: range_source.h), as PointStore does.
  if (crc32c(bytes.data(), bytes.size()) != r.payload_crc &&
      mSource->refetch(r.payload_offset, bytes.size()))
    read();
  return meshfmt::decodePatch(bytes.data(), bytes.size(), r, mSummary, where);
}

MeshStore::MorphTargets MeshStore::morphTargets(NodeId id, const MeshPatch& patch,
                                                std::stop_token cancel) const {
  const NodeId up = parent(id);
  if (up == kNoNode) return {patch.positions, patch.normals};
  const MeshPatch p = readPatch(up, cancel);
  // Both patches are in the store's one frame (MeshPatch::offset is the store's box minimum).
  std::vector<glm::dvec3> parent_pos(p.positions.begin(), p.positions.end());
  const TriangleGrid grid(parent_pos, p.indices);
  MorphTargets out;
  out.positions.resize(patch.positions.size());
  out.normals.resize(patch.positions.size());
  for (size_t i = 0; i < out.positions.size(); ++i) {
    uint32_t t = 0;
    const glm::dvec3 q = grid.closest(glm::dvec3(patch.positions[i]), &t);
    out.positions[i] = glm::vec3(q);
    // The parent's normal at q: its vertex normals by q's barycentric coordinates.
    const glm::dvec3 a = parent_pos[p.indices[3 * t]], b = parent_pos[p.indices[3 * t + 1]],
                     c = parent_pos[p.indices[3 * t + 2]];
    const glm::dvec3 n = glm::cross(b - a, c - a);
    const double area = glm::dot(n, n);
    glm::dvec3 w(1.0 / 3.0);
    if (area > 0) {
      w.x = glm::dot(glm::cross(c - b, q - b), n) / area;
      w.y = glm::dot(glm::cross(a - c, q - c), n) / area;
      w.z = 1.0 - w.x - w.y;
    }
    const glm::vec3 m = float(w.x) * p.normals[p.indices[3 * t]] +
                        float(w.y) * p.normals[p.indices[3 * t + 1]] +
                        float(w.z) * p.normals[p.indices[3 * t + 2]];
    const float len = glm::length(m);
    out.normals[i] = len > 0 ? m / len : patch.normals[i];
  }
  return out;
}

}  // namespace tessera::lod
