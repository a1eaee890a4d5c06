#include "mesh_format.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <meshoptimizer.h>

#include "crc32c.h"

namespace tessera::lod::meshfmt {
namespace {

float signNotZero(float v) { return v >= 0.0f ? 1.0f : -1.0f; }

/// The encoded vertex size: 8 (u16 grid offsets and normal) or 16 (u32), plus 4 for colour.
size_t vertexBytes(bool wide, bool colors) { return (wide ? 16u : 8u) + (colors ? 4u : 0u); }

}  // namespace

uint16_t octEncode(glm::vec3 n) {
  const float l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  if (!(l1 > 0.0f) || !std::isfinite(l1)) return octEncode(glm::vec3(0, 0, 1));
  n /= l1;
  glm::vec2 p(n.x, n.y);
  if (n.z < 0.0f)
    p = glm::vec2((1.0f - std::abs(n.y)) * signNotZero(n.x), (1.0f - std::abs(n.x)) * signNotZero(n.y));
  auto q = [](float v) { return uint16_t(std::lround((std::clamp(v, -1.0f, 1.0f) * 0.5f + 0.5f) * 255.0f)); };
  return uint16_t(q(p.x) | q(p.y) << 8);
}

glm::vec3 octDecode(uint16_t v) {
  const glm::vec2 p(float(v & 0xFF) / 255.0f * 2.0f - 1.0f, float(v >> 8) / 255.0f * 2.0f - 1.0f);
  glm::vec3 n(p.x, p.y, 1.0f - std::abs(p.x) - std::abs(p.y));
  if (n.z < 0.0f) {
    n.x = (1.0f - std::abs(p.y)) * signNotZero(p.x);
    n.y = (1.0f - std::abs(p.x)) * signNotZero(p.y);
  }
  return glm::normalize(n);
}

std::vector<uint8_t> encodePatch(std::vector<QuantVertex> vertices, std::vector<uint32_t> indices,
                                 bool colors, MeshNodeRecord& rec) {
  meshopt_optimizeVertexCache(indices.data(), indices.data(), indices.size(), vertices.size());
  std::vector<QuantVertex> fetched(vertices.size());
  const size_t used = meshopt_optimizeVertexFetch(fetched.data(), indices.data(), indices.size(),
                                                  vertices.data(), vertices.size(),
                                                  sizeof(QuantVertex));
  fetched.resize(used);
  glm::i32vec3 lo(std::numeric_limits<int32_t>::max()), hi(std::numeric_limits<int32_t>::min());
  for (const QuantVertex& v : fetched) {
    lo = glm::min(lo, v.grid);
    hi = glm::max(hi, v.grid);
  }
  if (fetched.empty()) lo = hi = glm::i32vec3(0);
  const glm::i64vec3 span = glm::i64vec3(hi) - glm::i64vec3(lo);
  const bool wide = span.x > 0xFFFF || span.y > 0xFFFF || span.z > 0xFFFF;
  const size_t vb = vertexBytes(wide, colors);
  std::vector<uint8_t> raw(fetched.size() * vb, 0);
  for (size_t i = 0; i < fetched.size(); ++i) {
    uint8_t* out = raw.data() + i * vb;
    const glm::u32vec3 d = glm::u32vec3(glm::i64vec3(fetched[i].grid) - glm::i64vec3(lo));
    if (wide) {
      std::memcpy(out, &d, 12);
      std::memcpy(out + 12, &fetched[i].normal, 2);
    } else {
      const uint16_t s[4] = {uint16_t(d.x), uint16_t(d.y), uint16_t(d.z), fetched[i].normal};
      std::memcpy(out, s, 8);
    }
    if (colors) std::memcpy(out + (wide ? 16 : 8), &fetched[i].color, 4);
  }
  std::vector<uint8_t> vbuf(meshopt_encodeVertexBufferBound(fetched.size(), vb));
  vbuf.resize(meshopt_encodeVertexBuffer(vbuf.data(), vbuf.size(), raw.data(), fetched.size(), vb));
  std::vector<uint8_t> ibuf(meshopt_encodeIndexBufferBound(indices.size(), fetched.size()));
  ibuf.resize(meshopt_encodeIndexBuffer(ibuf.data(), ibuf.size(), indices.data(), indices.size()));
  rec.vertices = uint32_t(fetched.size());
  rec.triangles = uint32_t(indices.size() / 3);
  rec.wide = wide ? 1 : 0;
  rec.grid_base = lo;
  Writer w;
  w.put(uint32_t(vbuf.size()));
  w.bytes.insert(w.bytes.end(), vbuf.begin(), vbuf.end());
  w.bytes.insert(w.bytes.end(), ibuf.begin(), ibuf.end());
  return std::move(w.bytes);
}

MeshPatch decodePatch(const uint8_t* data, size_t size, const MeshNodeRecord& rec,
                      const MeshSummary& summary, const std::string& where) {
  if (crc32c(data, size) != rec.payload_crc)
    throw StoreError(where + ": checksum mismatch (the patch's bytes are corrupt)");
  Reader r{data, size};
  const uint32_t vbytes = r.get<uint32_t>();
  if (!r.ok() || vbytes > size - 4)
    throw StoreError(where + ": vertex block of " + std::to_string(vbytes) +
                     " bytes does not fit the payload of " + std::to_string(size));
  const size_t vb = vertexBytes(rec.wide != 0, summary.colors);
  std::vector<uint8_t> raw(size_t(rec.vertices) * vb);
  if (meshopt_decodeVertexBuffer(raw.data(), rec.vertices, vb, data + 4, vbytes) != 0)
    throw StoreError(where + ": vertex data does not decode");
  MeshPatch p;
  p.indices.resize(size_t(rec.triangles) * 3);
  if (meshopt_decodeIndexBuffer(p.indices.data(), p.indices.size(), 4, data + 4 + vbytes,
                                size - 4 - vbytes) != 0)
    throw StoreError(where + ": index data does not decode");
  for (uint32_t i : p.indices) {
    if (i >= rec.vertices)
      throw StoreError(where + ": index " + std::to_string(i) + " beyond its " +
                       std::to_string(rec.vertices) + " vertices");
  }
  // One offset for every patch of the store, so a vertex shared by two patches is the same float
  // in both (no sub-pixel cracks along patch borders).
  p.offset = summary.bbox_min;
  p.positions.resize(rec.vertices);
  p.normals.resize(rec.vertices);
  p.grid.resize(rec.vertices);
  if (summary.colors) p.colors.resize(rec.vertices);
  for (size_t i = 0; i < rec.vertices; ++i) {
    const uint8_t* in = raw.data() + i * vb;
    glm::u32vec3 d;
    uint16_t n;
    if (rec.wide) {
      std::memcpy(&d, in, 12);
      std::memcpy(&n, in + 12, 2);
    } else {
      uint16_t s[4];
      std::memcpy(s, in, 8);
      d = glm::u32vec3(s[0], s[1], s[2]);
      n = s[3];
    }
    const glm::dvec3 grid = glm::dvec3(glm::i64vec3(rec.grid_base) + glm::i64vec3(d));
    p.positions[i] = glm::vec3(grid * summary.step);
    p.grid[i] = glm::i32vec3(glm::i64vec3(rec.grid_base) + glm::i64vec3(d));
    p.normals[i] = octDecode(n);
    if (summary.colors) std::memcpy(&p.colors[i], in + (rec.wide ? 16 : 8), 4);
  }
  return p;
}

std::vector<uint8_t> writeHeader(const MeshSummary& s, uint64_t table_offset, uint32_t table_crc) {
  Writer w;
  w.bytes.assign(kMagic, kMagic + 8);
  w.put(kVersion);
  w.put(uint32_t(s.colors ? kFlagColors : 0));
  w.put(uint64_t(s.input_triangles));
  w.put(uint64_t(s.input_vertices));
  w.put(uint64_t(s.stored_triangles));
  w.put(uint32_t(s.nodes));
  w.put(uint32_t(s.depth));
  for (const glm::dvec3* v : {&s.origin, &s.bbox_min, &s.bbox_max})
    for (int i = 0; i < 3; ++i) w.put(double((*v)[i]));
  w.put(s.step);
  w.put(table_offset);
  w.put(uint64_t(s.file_bytes));
  w.put(table_crc);
  w.put(crc32c(w.bytes.data(), w.bytes.size()));
  return std::move(w.bytes);
}

std::vector<uint8_t> writeNode(const MeshNodeRecord& r) {
  Writer w;
  for (int i = 0; i < 3; ++i) w.put(r.box_min[i]);
  for (int i = 0; i < 3; ++i) w.put(r.box_max[i]);
  w.put(r.error);
  w.put(r.triangles);
  w.put(r.vertices);
  w.put(r.first_child);
  w.put(r.child_count);
  w.put(r.level);
  w.put(r.wide);
  w.put(uint8_t(0));
  for (int i = 0; i < 3; ++i) w.put(r.grid_base[i]);
  w.put(r.payload_offset);
  w.put(r.payload_bytes);
  w.put(r.payload_crc);
  return std::move(w.bytes);
}

MeshNodeRecord readNode(const uint8_t* data) {
  Reader rd{data, kNodeBytes};
  MeshNodeRecord r;
  for (int i = 0; i < 3; ++i) r.box_min[i] = rd.get<float>();
  for (int i = 0; i < 3; ++i) r.box_max[i] = rd.get<float>();
  r.error = rd.get<float>();
  r.triangles = rd.get<uint32_t>();
  r.vertices = rd.get<uint32_t>();
  r.first_child = rd.get<uint32_t>();
  r.child_count = rd.get<uint8_t>();
  r.level = rd.get<uint8_t>();
  r.wide = rd.get<uint8_t>();
  rd.get<uint8_t>();
  for (int i = 0; i < 3; ++i) r.grid_base[i] = rd.get<int32_t>();
  r.payload_offset = rd.get<uint64_t>();
  r.payload_bytes = rd.get<uint32_t>();
  r.payload_crc = rd.get<uint32_t>();
  return r;
}

}  // namespace tessera::lod::meshfmt
