// The .tmesh byte format (mesh_store.h): header, node records and patch payloads, shared by the
// builder (mesh_builder.cpp), the store (mesh_store.cpp) and the verifier.
//
// Header, 152 bytes: "TESMESH1", u32 version, u32 flags (bit 0: colour), u64 input triangles,
// u64 input vertices, u64 stored triangles, u32 nodes, u32 depth, f64x3 origin, f64x3 bbox_min,
// f64x3 bbox_max, f64 step, u64 table offset, u64 file bytes, u32 table CRC, u32 header CRC
// (over the bytes before it).
// Node record, 72 bytes: f32x3 box_min, f32x3 box_max, f32 error, u32 triangles, u32 vertices,
// u32 first child, u8 child count, u8 level, u8 wide, u8 0, i32x3 grid base, u64 payload offset,
// u32 payload bytes, u32 payload CRC.
// Payload: u32 encoded vertex bytes, meshopt vertex codec, meshopt index codec. A vertex is
// u16x3 grid offsets and an octahedral normal (2 x u8) when `wide` is 0, u32x3 and the normal
// and 2 bytes of zeros otherwise; then rgba when the store has colour.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <tessera/lod/mesh_store.h>

namespace tessera::lod::meshfmt {

constexpr char kMagic[9] = "TESMESH1";
constexpr uint32_t kVersion = 1;
constexpr uint32_t kFlagColors = 1;
constexpr size_t kHeaderBytes = 152;
constexpr size_t kNodeBytes = 72;
/// Bounds a reader accepts (a corrupt table must not make it allocate the world).
constexpr uint32_t kMaxNodes = 1u << 24;
constexpr uint32_t kMaxPatchTriangles = 1u << 22;
constexpr uint32_t kMaxChildren = 64;

/// A vertex as the builder hands it to encodePatch(): grid coordinates, normal, colour.
struct QuantVertex {
  glm::i32vec3 grid{0};
  uint16_t normal = 0;  ///< octahedral, octEncode()
  glm::u8vec4 color{255};
};

/// Octahedral unit-vector encoding in 2 x 8 bits (Cigolle et al. 2014, "A survey of efficient
/// representations for independent unit vectors"): about 1 degree of error.
uint16_t octEncode(glm::vec3 n);
glm::vec3 octDecode(uint16_t v);

/// Encodes a patch (vertices in any order, 3 indices a triangle): optimises the vertex cache and
/// fetch order, picks the narrowest grid offsets, fills rec's vertices, triangles, wide and
/// grid_base. Returns the payload bytes (rec's offset and CRC are the caller's).
std::vector<uint8_t> encodePatch(std::vector<QuantVertex> vertices, std::vector<uint32_t> indices,
                                 bool colors, MeshNodeRecord& rec);

/// Decodes a payload checked against its CRC. Throws StoreError starting with `where`.
MeshPatch decodePatch(const uint8_t* data, size_t size, const MeshNodeRecord& rec,
                      const MeshSummary& summary, const std::string& where);

/// Little-endian field writer and bounds-checked reader.
struct Writer {
  std::vector<uint8_t> bytes;
  template <class T>
  void put(const T& v) {
    const size_t at = bytes.size();
    bytes.resize(at + sizeof(T));
    std::memcpy(bytes.data() + at, &v, sizeof(T));
  }
};
struct Reader {
  const uint8_t* data;
  size_t size, at = 0;
  template <class T>
  T get() {
    T v{};
    if (at + sizeof(T) <= size) std::memcpy(&v, data + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
  bool ok() const { return at <= size; }
};

std::vector<uint8_t> writeHeader(const MeshSummary& s, uint64_t table_offset, uint32_t table_crc);
std::vector<uint8_t> writeNode(const MeshNodeRecord& r);
MeshNodeRecord readNode(const uint8_t* data);

}  // namespace tessera::lod::meshfmt
