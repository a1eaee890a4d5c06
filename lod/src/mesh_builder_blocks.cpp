// The mesh build in blocks, for meshes whose in-memory build would not fit `memory_mb`
// (10^8 triangles within a memory budget). Out of core as the batched multiresolution
// builders do it (Cignoni et al., Batched Multi-Triangulation, 2005: the mesh is cut into
// pieces built one at a time, whose shared borders stay locked until the pieces meet):
//  1. the inputs are streamed once into files beside the output (vertices, triangles); the
//     vertex files are mapped, the triangles read in passes;
//  2. passes over the triangles give the box, the grid step (as the in-memory build chooses
//     it), the normals (area-weighted, summed per vertex in triangle order: the same normals)
//     and each triangle's block: consecutive ranges of 2^18 Morton cells of the centroids, each
//     range at most the triangles the budget allows a block;
//  3. each block is built as a mesh of its own (leaf patches, levels bottom up, every group's
//     border locked, so the block's border stays the input's edges) until at most `arity`
//     nodes are left; every patch is encoded to a payload file and dropped, the block's top
//     nodes keep their triangles;
//  4. the tops of all blocks, which share the blocks' border edges, are grouped and simplified
//     up to one root as any level is; the store is written from the payload file.
// Memory: the vertex arrays (about 45 bytes a vertex, mapped from the file where they are
// read) and one block's build (about 170 bytes a triangle of the block); the rest is on disk.
#include <sys/mman.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <numeric>
#include <thread>

#include <fcntl.h>
#include <unistd.h>

#include <tessera/core/check.h>
#include <tessera/lod/point_reader.h>

#include "file_io.h"
#include "mesh_build_steps.h"
#include "morton.h"

namespace tessera::lod::meshbuild {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// Bytes a block's build takes per triangle: the in-memory build's 110 and its vertices' 64
/// (about half a vertex a triangle), the block's triangles and their local numbering table.
constexpr uint64_t kBlockBytesPerTriangle = 170;
/// Per input vertex: position (24), normal or normal sum (12), colour (4), use flag (1), index
/// in the block (4).
constexpr uint64_t kVertexBytes = 45;
/// Morton cells the blocks are made of: 2^18 (6 levels of an octree).
constexpr int kCellBits = 18;
/// A block holds at least this many leaf patches' triangles (a smaller budget is refused).
constexpr uint64_t kMinBlockPatches = 16;

/// A temporary file beside the output, written through a buffer, then mapped read-only;
/// removed with the object.
class TempFile {
 public:
  TempFile(std::filesystem::path path, const char* what)
      : mPath(std::move(path)), mFd(mPath, O_RDWR | O_CREAT | O_TRUNC, what) {}
  ~TempFile() {
    if (mMap != nullptr) ::munmap(mMap, mBytes);
    std::error_code ec;
    std::filesystem::remove(mPath, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;

  void append(const void* data, size_t n) {
    const auto* b = static_cast<const uint8_t*>(data);
    mBuffer.insert(mBuffer.end(), b, b + n);
    if (mBuffer.size() >= (8u << 20)) flush();
  }
  void flush() {
    pwriteAll(mFd.get(), mBuffer.data(), mBuffer.size(), mBytes, mFd.name());
    mBytes += mBuffer.size();
    mBuffer.clear();
  }
  void writeAt(const void* data, size_t n, uint64_t offset) {
    pwriteAll(mFd.get(), data, n, offset, mFd.name());
    mBytes = std::max<uint64_t>(mBytes, offset + n);
  }
  void readAt(void* data, size_t n, uint64_t offset) const {
    preadAll(mFd.get(), data, n, offset, mFd.name());
  }
  /// The whole file, read-only (nullptr when empty); flushes first.
  const uint8_t* map() {
    flush();
    std::vector<uint8_t>().swap(mBuffer);
    if (mMap == nullptr && mBytes > 0) {
      void* m = ::mmap(nullptr, mBytes, PROT_READ, MAP_SHARED, mFd.get(), 0);
      if (m == MAP_FAILED) throw StoreError("lod::buildMeshStore(): cannot map " + mFd.name());
      mMap = static_cast<uint8_t*>(m);
    }
    return mMap;
  }
  uint64_t bytes() const { return mBytes + mBuffer.size(); }
  /// Drops the mapping (its pages leave this process's memory; the file stays).
  void unmap() {
    if (mMap != nullptr) ::munmap(mMap, mBytes);
    mMap = nullptr;
  }

 private:
  std::filesystem::path mPath;
  ScopedFd mFd;
  std::vector<uint8_t> mBuffer;
  uint64_t mBytes = 0;
  uint8_t* mMap = nullptr;
};

/// The mesh the blocks are cut from: arrays in memory (a Mesh) or mapped from spilled files.
struct Source {
  glm::dvec3 origin{0.0};
  const glm::dvec3* positions = nullptr;
  size_t vertices = 0;
  const glm::vec3* normals = nullptr;     ///< null: none in the input
  const glm::u8vec4* colors = nullptr;    ///< null: none in the input
  const Triangle* tris = nullptr;
  size_t triangles = 0;
};

/// The inputs streamed into files beside the output (fused into the first one's frame as
/// readMeshes() fuses them; attributes kept only when every input has them).
struct Spilled {
  std::unique_ptr<TempFile> positions, normals, colors, tris;
  Source source;
};

/// Where a build's temporary files go: out + ".partial" or the same name in `temp_dir`.
std::string tempBase(const std::filesystem::path& out, const std::filesystem::path& temp_dir) {
  return (temp_dir.empty() ? out : temp_dir / out.filename()).string() + ".partial";
}

Spilled spill(const std::vector<std::filesystem::path>& inputs, const std::filesystem::path& out,
              const std::filesystem::path& temp_dir, bool quiet) {
  std::vector<std::unique_ptr<PointReader>> readers;
  bool colors = true, normals = true;
  for (const auto& in : inputs) {
    readers.push_back(openPointReader(in));
    colors = colors && (readers.back()->info().attributes & kColor);
    normals = normals && (readers.back()->info().attributes & kNormal);
  }
  Spilled s;
  const std::string base = tempBase(out, temp_dir);
  s.positions = std::make_unique<TempFile>(base + ".positions", "the build's vertex file");
  s.tris = std::make_unique<TempFile>(base + ".triangles", "the build's triangle file");
  if (normals) s.normals = std::make_unique<TempFile>(base + ".normals", "the build's normal file");
  if (colors) s.colors = std::make_unique<TempFile>(base + ".colors", "the build's colour file");
  const glm::dvec3 origin = readers.front()->info().origin;
  uint64_t vertices = 0, triangles = 0;
  Progress progress("read", 0, "triangles", quiet);
  PointBatch batch;
  std::vector<glm::dvec3> shifted;
  std::vector<Triangle> tris;
  for (size_t i = 0; i < readers.size(); ++i) {
    const glm::dvec3 shift = readers[i]->info().origin - origin;
    const uint64_t first = vertices;
    uint64_t file_triangles = 0;
    while (readers[i]->next(batch)) {
      shifted.resize(batch.positions.size());
      for (size_t k = 0; k < shifted.size(); ++k) shifted[k] = batch.positions[k] + shift;
      s.positions->append(shifted.data(), shifted.size() * sizeof(glm::dvec3));
      if (normals) s.normals->append(batch.normals.data(), batch.normals.size() * sizeof(glm::vec3));
      if (colors)
        s.colors->append(batch.colors.data(), batch.colors.size() * sizeof(glm::u8vec4));
      vertices += batch.positions.size();
      if (vertices > 0xFFFFFFF0ull)
        throw ReadError("lod::buildMeshStore(): more than 2^32 vertices (" + inputs[i].string() +
                        ")");
      tris.resize(batch.triangles.size());
      for (size_t k = 0; k < tris.size(); ++k) tris[k] = batch.triangles[k] + uint32_t(first);
      s.tris->append(tris.data(), tris.size() * sizeof(Triangle));
      file_triangles += tris.size();
      triangles += tris.size();
      progress.update(triangles);
    }
    if (file_triangles == 0)
      throw ReadError("lod::readMesh(): " + inputs[i].string() +
                      ": no triangles (a point cloud, not a mesh)");
  }
  progress.finish();
  s.source.origin = origin;
  s.source.vertices = vertices;
  s.source.triangles = triangles;
  s.source.positions = reinterpret_cast<const glm::dvec3*>(s.positions->map());
  s.source.tris = reinterpret_cast<const Triangle*>(s.tris->map());
  if (normals) s.source.normals = reinterpret_cast<const glm::vec3*>(s.normals->map());
  if (colors) s.source.colors = reinterpret_cast<const glm::u8vec4*>(s.colors->map());
  return s;
}

/// The store's frame over the whole source, as prepare() makes it for a mesh in memory.
struct Frame {
  glm::dvec3 lo{0.0}, hi{0.0};
  double step = 1.0, quant_error = 0.0;
  uint64_t kept = 0, dropped = 0, used_vertices = 0;
  int shift = 0;  ///< grid bits dropped for the 21-bit Morton cells
  std::vector<uint8_t> used;            ///< per vertex: used by a kept triangle
  detail::HugeVector<glm::vec3> normal;  ///< per vertex, when the source has none
  bool usable(const Triangle& t, size_t nv) const { return usableTriangle(t, nv); }
  glm::i32vec3 grid(const glm::dvec3& v) const {
    return glm::i32vec3(
        glm::clamp(glm::round((v - lo) / step), glm::dvec3(0.0), glm::dvec3(double(1 << 30))));
  }
  uint64_t cell(const Source& src, const Triangle& t) const {
    const glm::i64vec3 c = (glm::i64vec3(grid(src.positions[t.x])) +
                            glm::i64vec3(grid(src.positions[t.y])) +
                            glm::i64vec3(grid(src.positions[t.z]))) /
                           int64_t(3);
    const uint64_t code =
        mortonEncode(uint64_t(c.x >> shift), uint64_t(c.y >> shift), uint64_t(c.z >> shift));
    return code >> (63 - kCellBits);
  }
};

Frame frameOf(const Source& src, uint32_t threads) {
  Frame f;
  const size_t nv = src.vertices, nt = src.triangles;
  f.used.assign(nv, 0);
  const UsableTriangles u =
      usableTriangles(src.positions, nv, src.tris, nt, threads, f.used.data());
  f.kept = u.kept;
  f.lo = u.lo;
  f.hi = u.hi;
  f.dropped = nt - f.kept;
  for (uint8_t used : f.used) f.used_vertices += used;
  // The grid step from the same sample of edges as the in-memory build's.
  std::vector<double> edges;
  const size_t stride = std::max<size_t>(1, f.kept / 4096);
  for (size_t i = 0, k = 0; i < nt; ++i) {
    const Triangle& t = src.tris[i];
    if (!f.usable(t, nv)) continue;
    if (k++ % stride != 0) continue;
    const double e = glm::length(src.positions[t.x] - src.positions[t.y]);
    if (e > 0) edges.push_back(e);
  }
  f.step = gridStep(edges, std::max({f.hi.x - f.lo.x, f.hi.y - f.lo.y, f.hi.z - f.lo.z}));
  const size_t ranges = std::max<size_t>(1, std::min<size_t>(threads, nv / 65536 + 1));
  std::vector<double> errors(ranges, 0.0);
  parallelFor(ranges, threads, [&](size_t r) {
    for (size_t i = nv * r / ranges; i < nv * (r + 1) / ranges; ++i) {
      const glm::dvec3 v = src.positions[i];
      if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) continue;
      errors[r] = std::max(errors[r], glm::length(glm::dvec3(f.grid(v)) * f.step - (v - f.lo)));
    }
  });
  for (double e : errors) f.quant_error = std::max(f.quant_error, e);
  const glm::dvec3 top = glm::dvec3(f.grid(f.hi));
  f.shift = std::max(
      0, int(std::ceil(std::log2(std::max({top.x, top.y, top.z, 1.0}) + 1))) - 21);
  // Normals where the input has none: area-weighted face normals summed per vertex in triangle
  // order, from the grid positions, as prepare() sums them.
  if (src.normals == nullptr) {
    detail::assignHuge(f.normal, nv, glm::vec3(0.0f));
    for (size_t i = 0; i < nt; ++i) {
      const Triangle& t = src.tris[i];
      if (!f.usable(t, nv)) continue;
      const glm::dvec3 a = glm::dvec3(f.grid(src.positions[t.x])) * f.step;
      const glm::dvec3 b = glm::dvec3(f.grid(src.positions[t.y])) * f.step;
      const glm::dvec3 c = glm::dvec3(f.grid(src.positions[t.z])) * f.step;
      const glm::vec3 n(glm::cross(b - a, c - a));
      for (int k = 0; k < 3; ++k) f.normal[t[k]] += n;
    }
  }
  return f;
}

/// A node as the final tree holds it: its record (payload fields, box, error, level, child
/// count), where its payload lies in the payload file, its children by their place here.
struct Placed {
  MeshNodeRecord rec;
  uint64_t temp_offset = 0;
  std::vector<uint32_t> children;
};

/// A block's (or the top's) vertices on the store's grid: the Prepared of `tris` (ids of the
/// source), renumbered; `verts` gets the source ids. `local_id`: per source vertex UINT32_MAX,
/// used to number the subset's and left as it was.
Prepared prepareSubset(const Source& src, const Frame& f, const std::vector<Triangle>& tris,
                       std::vector<uint32_t>& local_id, std::vector<uint32_t>& verts,
                       uint32_t threads) {
  // Numbered in order of first use, as localVertices() numbers them, through a per-vertex
  // table (a hash table sized for a block would be as large and slower).
  verts.clear();
  detail::HugeVector<Triangle> local;
  detail::sizeHuge(local, tris.size());
  for (size_t t = 0; t < tris.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      uint32_t& id = local_id[tris[t][k]];
      if (id == UINT32_MAX) {
        id = uint32_t(verts.size());
        verts.push_back(tris[t][k]);
      }
      local[t][k] = id;
    }
  for (uint32_t v : verts) local_id[v] = UINT32_MAX;
  Prepared p;
  p.origin = src.origin;
  p.lo = f.lo;
  p.hi = f.hi;
  p.step = f.step;
  p.quant_error = f.quant_error;
  const size_t n = verts.size();
  detail::sizeHuge(p.grid, n);
  detail::sizeHuge(p.pos, n);
  detail::sizeHuge(p.normals, n);
  if (src.colors != nullptr) p.colors.resize(n);
  parallelFor((n + 65535) / 65536, threads, [&](size_t c) {
    for (size_t i = c * 65536; i < std::min(n, (c + 1) * 65536); ++i) {
      const uint32_t v = verts[i];
      p.grid[i] = f.grid(src.positions[v]);
      p.pos[i] = glm::dvec3(p.grid[i]) * f.step;
      p.normals[i] = meshfmt::octEncode(src.normals != nullptr ? src.normals[v] : f.normal[v]);
      if (src.colors != nullptr) p.colors[i] = src.colors[v];
    }
  });
  p.tris = std::move(local);
  return p;
}

/// Encodes nodes[first..] of a build over `p` to the payload file and appends them to `placed`;
/// `place_of[i]` gets node i's index in `placed` (children already placed are looked up there).
void place(const Prepared& p, const std::vector<BuildNode>& nodes, size_t first,
           std::vector<uint32_t>& place_of, std::vector<Placed>& placed, TempFile& payloads,
           uint32_t threads) {
  std::vector<std::vector<uint8_t>> bytes(nodes.size() - first);
  std::vector<MeshNodeRecord> recs(nodes.size() - first);
  parallelFor(bytes.size(), threads,
              [&](size_t i) { bytes[i] = encodeNode(p, nodes[first + i], recs[i]); });
  place_of.resize(nodes.size());
  for (size_t i = first; i < nodes.size(); ++i) {
    Placed node;
    node.rec = recs[i - first];
    node.temp_offset = payloads.bytes();
    payloads.append(bytes[i - first].data(), bytes[i - first].size());
    for (uint32_t c : nodes[i].children) node.children.push_back(place_of[c]);
    place_of[i] = uint32_t(placed.size());
    placed.push_back(std::move(node));
  }
}

/// The build of `src`; `tris_file`, when the triangles are mapped from it, is unmapped once
/// they are in block order.
MeshBuildReport build(const Source& src, const std::filesystem::path& out,
                      const MeshBuildOptions& o, double seconds_read, Clock::time_point t0,
                      TempFile* tris_file) {
  checkOptions(o);
  const uint32_t threads =
      threadCount(int(o.threads));
  MeshBuildReport r;
  r.seconds_read = seconds_read;
  // The budget: the vertex arrays, then blocks as large as the rest allows.
  const uint64_t budget = o.memory_mb << 20;
  const uint64_t vertex_bytes = uint64_t(src.vertices) * kVertexBytes + (16ull << 20);  // + block buffers
  const uint64_t least = kMinBlockPatches * o.patch_triangles;
  uint64_t cap = o.block_triangles;
  if (cap == 0) {
    if (budget < vertex_bytes + least * kBlockBytesPerTriangle)
      throw ReadError("lod::buildMeshStore(): " + std::to_string(src.triangles) +
                      " triangles over " + std::to_string(src.vertices) +
                      " vertices need at least " +
                      std::to_string((vertex_bytes + least * kBlockBytesPerTriangle) >> 20) +
                      " MB to build in blocks, beyond --memory-mb " +
                      std::to_string(o.memory_mb));
    cap = (budget - vertex_bytes) / kBlockBytesPerTriangle;
  }
  cap = std::max<uint64_t>(cap, o.patch_triangles);
  MetisPool metis(threads > 1 ? threads : 0);

  const Frame f = frameOf(src, threads);
  std::vector<uint32_t> local_id(src.vertices, UINT32_MAX);  // prepareSubset()'s numbering
  r.triangles = f.kept;
  r.dropped_triangles = f.dropped;
  r.step = f.step;
  r.quant_error = f.quant_error;
  r.vertices = f.used_vertices;

  // Blocks: consecutive Morton cells up to `cap` triangles (a fuller cell is split in order).
  const auto tp = Clock::now();
  const size_t nv = src.vertices, nt = src.triangles;
  std::vector<uint32_t> cell_count(size_t(1) << kCellBits, 0);
  for (size_t i = 0; i < nt; ++i)
    if (f.usable(src.tris[i], nv)) ++cell_count[f.cell(src, src.tris[i])];
  std::vector<uint32_t> cell_block(cell_count.size());
  std::vector<uint64_t> block_size;
  for (size_t c = 0; c < cell_count.size(); ++c) {
    const uint64_t n = cell_count[c];
    if (block_size.empty() || (n > 0 && block_size.back() + n > cap && block_size.back() > 0))
      block_size.push_back(0);
    cell_block[c] = uint32_t(block_size.size() - 1);
    for (uint64_t left = n; left > 0;) {  // a cell beyond the cap takes blocks of its own
      const uint64_t take = std::min(left, cap - block_size.back());
      block_size.back() += take;
      left -= take;
      if (left > 0) block_size.push_back(0);
    }
  }
  while (block_size.size() > 1 && block_size.back() == 0) block_size.pop_back();
  const size_t blocks = block_size.size();
  std::vector<uint64_t> block_start(blocks + 1, 0);
  for (size_t b = 0; b < blocks; ++b) block_start[b + 1] = block_start[b] + block_size[b];
  // The triangles in block order, through a buffer per block.
  TempFile ordered(tempBase(out, o.temp_dir) + ".blocks", "the build's block file");
  {
    const size_t per = std::max<size_t>(1024, (16u << 20) / sizeof(Triangle) / blocks);
    std::vector<std::vector<Triangle>> buffers(blocks);
    std::vector<uint64_t> cursor(block_start.begin(), block_start.end() - 1);
    auto drain = [&](size_t b) {
      ordered.writeAt(buffers[b].data(), buffers[b].size() * sizeof(Triangle),
                      cursor[b] * sizeof(Triangle));
      cursor[b] += buffers[b].size();
      buffers[b].clear();
    };
    for (size_t i = 0; i < nt; ++i) {
      const Triangle& t = src.tris[i];
      if (!f.usable(t, nv)) continue;
      const uint64_t c = f.cell(src, t);
      // The block of the cell's k-th triangle: the cell's first, or a later one once that is
      // full (cursor past its end).
      size_t b = cell_block[c];
      while (cursor[b] + buffers[b].size() >= block_start[b + 1]) ++b;
      buffers[b].push_back(t);
      if (buffers[b].size() >= per) drain(b);
    }
    for (size_t b = 0; b < blocks; ++b) drain(b);
  }
  if (tris_file != nullptr) tris_file->unmap();  // src.tris is not read again
  r.seconds_partition += since(tp);

  // Each block bottom up to at most `arity` nodes; its patches go to the payload file.
  TempFile payloads(tempBase(out, o.temp_dir) + ".payloads", "the build's patch file");
  std::vector<Placed> placed;
  struct Top {
    uint32_t placed;
    std::vector<Triangle> tris;  ///< source vertex ids
    float error;
    uint8_t level;
    glm::dvec3 lo, hi;
  };
  std::vector<Top> tops;
  Progress progress("blocks", nt, "triangles", o.quiet);
  Progress quiet_progress("block levels", 0, "patches", true);
  for (size_t b = 0; b < blocks; ++b) {
    const auto tb = Clock::now();
    std::vector<Triangle> tris(block_size[b]);
    ordered.readAt(tris.data(), tris.size() * sizeof(Triangle), block_start[b] * sizeof(Triangle));
    std::vector<uint32_t> verts;
    Prepared p = prepareSubset(src, f, tris, local_id, verts, threads);
    std::vector<Triangle>().swap(tris);
    vertexTriangles(p, verts.size(), threads);
    std::vector<BuildNode> nodes;
    std::vector<uint32_t> level;
    Adjacency adjacency;
    buildLeaves(p, o, threads, metis, nodes, level, adjacency);
    r.leaves += nodes.size();
    r.seconds_partition += since(tb);
    const auto ts = Clock::now();
    buildLevels(p, o, threads, metis, nodes, level, adjacency, o.arity, quiet_progress);
    r.seconds_simplify += since(ts);
    const auto tw = Clock::now();
    std::vector<uint32_t> place_of;
    place(p, nodes, 0, place_of, placed, payloads, threads);
    for (uint32_t i : level) {
      Top t{place_of[i], {}, nodes[i].error, nodes[i].level, nodes[i].lo, nodes[i].hi};
      t.tris.reserve(nodes[i].tris.size());
      for (const Triangle& x : nodes[i].tris) t.tris.emplace_back(verts[x.x], verts[x.y], verts[x.z]);
      tops.push_back(std::move(t));
    }
    r.seconds_write += since(tw);
    progress.add(block_size[b]);
  }
  progress.finish();

  // The tops of every block, grouped up to the root; their shared edges are the blocks' borders.
  const auto ts = Clock::now();
  std::vector<Triangle> all;
  for (const Top& t : tops) all.insert(all.end(), t.tris.begin(), t.tris.end());
  std::vector<uint32_t> verts;
  const Prepared q = prepareSubset(src, f, all, local_id, verts, threads);
  std::vector<BuildNode> nodes(tops.size());
  std::unordered_map<uint64_t, uint32_t> edge_owner;  // an edge's first node
  Adjacency adjacency(tops.size());
  for (size_t i = 0, at = 0; i < tops.size(); ++i) {
    BuildNode& n = nodes[i];
    n.tris.assign(q.tris.begin() + std::ptrdiff_t(at),
                  q.tris.begin() + std::ptrdiff_t(at + tops[i].tris.size()));
    at += tops[i].tris.size();
    n.error = tops[i].error;
    n.level = tops[i].level;
    n.lo = tops[i].lo;
    n.hi = tops[i].hi;
    for (const Triangle& t : n.tris)
      for (int k = 0; k < 3; ++k) {
        const uint32_t a = std::min(t[k], t[(k + 1) % 3]), b = std::max(t[k], t[(k + 1) % 3]);
        const auto [it, fresh] = edge_owner.try_emplace(uint64_t(a) << 32 | b, uint32_t(i));
        if (!fresh && it->second != i) {
          ++adjacency[i][it->second];
          ++adjacency[it->second][i];
        }
      }
  }
  std::unordered_map<uint64_t, uint32_t>().swap(edge_owner);
  std::vector<uint32_t> level(tops.size());
  std::iota(level.begin(), level.end(), 0u);
  Progress top_progress("simplify", groupsUpToRoot(level.size(), o.arity), "patches", o.quiet);
  buildLevels(q, o, threads, metis, nodes, level, adjacency, 1, top_progress);
  top_progress.finish();
  r.seconds_simplify += since(ts);
  const auto tw = Clock::now();
  std::vector<uint32_t> place_of(tops.size());
  for (size_t i = 0; i < tops.size(); ++i) place_of[i] = tops[i].placed;
  place(q, nodes, tops.size(), place_of, placed, payloads, threads);
  const uint32_t root = place_of[level.front()];
  payloads.flush();

  // Ids breadth-first from the root, as the in-memory build numbers them.
  const std::vector<uint32_t> bfs = breadthFirst(
      root, [&](uint32_t i) -> const std::vector<uint32_t>& { return placed[i].children; });
  std::vector<uint32_t> id_of(placed.size());
  for (size_t i = 0; i < bfs.size(); ++i) id_of[bfs[i]] = uint32_t(i);
  std::vector<MeshNodeRecord> records(bfs.size());
  for (size_t id = 0; id < bfs.size(); ++id) {
    const Placed& n = placed[bfs[id]];
    records[id] = n.rec;
    records[id].first_child = n.children.empty() ? 0 : id_of[n.children.front()];
    for (size_t c = 0; c < n.children.size(); ++c)
      TESSERA_CHECK(id_of[n.children[c]] == records[id].first_child + c,
                    "lod::buildMeshStore(): children not contiguous");
  }
  MeshSummary s;
  s.origin = src.origin + f.lo;
  s.bbox_min = glm::dvec3(0.0);
  s.bbox_max = f.hi - f.lo;
  s.step = f.step;
  s.input_triangles = r.triangles;
  s.input_vertices = r.vertices;
  s.colors = src.colors != nullptr;
  writeStore(out, s, records, [&](uint32_t id, std::vector<uint8_t>& bytes) {
    bytes.resize(records[id].payload_bytes);
    payloads.readAt(bytes.data(), bytes.size(), placed[bfs[id]].temp_offset);
  });
  r.nodes = records.size();
  r.depth = s.depth;
  r.stored_triangles = s.stored_triangles;
  r.file_bytes = s.file_bytes;
  r.root_error = records[0].error;
  r.blocks = blocks;
  r.peak_bytes = vertex_bytes + cap * kBlockBytesPerTriangle;
  r.seconds_write += since(tw);
  r.seconds = seconds_read + since(t0);
  return r;
}

}  // namespace

MeshBuildReport buildInBlocks(const std::vector<std::filesystem::path>& inputs,
                              const std::filesystem::path& out, const MeshBuildOptions& o) {
  const auto t0 = Clock::now();
  const Spilled s = spill(inputs, out, o.temp_dir, o.quiet);
  return build(s.source, out, o, since(t0), t0, s.tris.get());
}

MeshBuildReport buildInBlocks(const Mesh& mesh, const std::filesystem::path& out,
                              const MeshBuildOptions& o) {
  Source src;
  src.origin = mesh.origin;
  src.positions = mesh.positions.data();
  src.vertices = mesh.positions.size();
  src.normals = mesh.normals.size() == mesh.positions.size() ? mesh.normals.data() : nullptr;
  src.colors = mesh.colors.size() == mesh.positions.size() ? mesh.colors.data() : nullptr;
  src.tris = mesh.triangles.data();
  src.triangles = mesh.triangles.size();
  if (src.vertices > 0xFFFFFFF0ull)
    throw ReadError("lod::buildMeshStore(): more than 2^32 vertices");
  return build(src, out, o, 0.0, Clock::now(), nullptr);
}

bool inMemoryBuildFits(const std::vector<std::filesystem::path>& inputs, uint64_t memory_mb) {
  uint64_t triangles = 0, vertices = 0;
  for (const auto& in : inputs) {
    const auto reader = openPointReader(in);
    const SourceInfo& info = reader->info();
    if (info.has_declared_points && info.declared_triangles > 0) {
      triangles += info.declared_triangles;
      vertices += info.declared_points;
    } else {  // no counts in the header (OBJ): a text triangle and its share of vertices
              // take at least 25 bytes
      std::error_code ec;
      const uint64_t bytes = std::filesystem::file_size(in, ec);
      triangles += ec ? 0 : bytes / 25;
      vertices += ec ? 0 : bytes / 50;
    }
  }
  return inMemoryBuildBytes(triangles, vertices) <= (memory_mb << 20);
}

}  // namespace tessera::lod::meshbuild
