// Streaming of point chunks to the GPU (Bettio et al. 2009, section 4.1: the renderer never
// waits for data; it draws what is resident and refines as chunks arrive). A pool of loader
// threads reads and decodes chunks (and hierarchy pages) in priority order, coarse and near
// first: each worker takes the highest-priority item queued. The GL thread uploads finished
// chunks into buffers kept under a byte budget with LRU eviction.
//
// Per frame, on the GL thread: beginFrame() uploads what the loader finished and evicts; the
// renderer asks find() for each chunk it wants and request()s the missing ones; endFrame() hands
// this frame's requests to the loader, replacing the previous frame's (a camera that moved on
// does not keep stale work queued; work in flight that frames stopped wanting is given up,
// StreamerOptions::cancel_after_frames). Chunks used in the previous frame are never evicted, so a
// resting view settles even when its cut is larger than the budget (the budget is then exceeded
// and says so in the stats).
//
// What see-through rendering needs of a chunk besides its points (density, and normals, density
// ratios and surface cells as StreamerOptions asks) is measured only for chunks requested for
// see-through drawing (ChunkUse::kSeeThrough), since they cost the loader more than decoding. A
// chunk resident without them counts as missing for a see-through view and is loaded again with
// them, so a model that turns see-through later gets its measurements.
#pragma once

#include <cstdint>
#include <memory>

#include <tessera/lod/mesh_store.h>
#include <tessera/lod/point_store.h>
#include <tessera/render/gl_buffer.h>

namespace tessera::render {

/// A chunk resident on the GPU: GpuPoint records (point_pass.h) relative to `offset`; for a mesh
/// patch (lod/mesh_store.h), GpuMeshVertex records (mesh_pass.h) and `indices`.
struct GpuChunk {
  GlBuffer buffer;
  uint32_t count = 0;  ///< points, or a patch's vertices
  GlBuffer indices;    ///< a mesh patch's triangles: uint32, 3 a triangle
  uint32_t index_count = 0;
  glm::dvec3 offset{0.0};   ///< store-local position of the points' frame
  uint64_t last_used = 0;   ///< frame number
  uint32_t disk_bytes = 0;  ///< the chunk's compressed size in the store
  double spacing = 0.0;     ///< the node's mean sample spacing, store units
  /// Whether the measurements below were taken (the chunk was loaded for see-through drawing,
  /// ChunkUse::kSeeThrough); without them the chunk can only be drawn opaque.
  bool measured = false;
  /// Whether its points' own splat sizes were asked for (StreamerOptions::point_splat_sizes;
  /// on leaves they are in the points' top bytes).
  bool splat_sized = false;
  /// The largest of its points' own splat scales (pointSplatScale(), splat_sizes.h); 1 when
  /// none was measured.
  float max_splat_scale = 1.0f;
  /// Points per unit area (store units) by sphere counts on the chunk's own points (spbr.h),
  /// for see-through rendering; 0 when too few points or not `measured`.
  double density = 0.0;
  GlBuffer normals;         ///< 10:10:10 normals, when `measured` and StreamerOptions::normals
  GlBuffer density_ratios;  ///< float per point (spbr.h densityRatios()), when asked for
  /// Per point, 16 bytes: spbr.h SurfaceCell, its axes in units of `spacing` as half floats,
  /// weight and centroid (chunk_streamer.cpp packCell()); when `measured` and
  /// StreamerOptions::surface_cells.
  GlBuffer cells;
};

/// Counters of the last frame (requested..evicted, pages_*) and the state after it.
struct StreamStats {
  uint64_t requested = 0;  ///< chunks this frame wanted but were not resident
  uint64_t uploaded = 0;   ///< chunks that became resident at the start of this frame
  uint64_t evicted = 0;
  uint64_t failed = 0;  ///< chunks refused by the store (corrupt): never drawn, never retried
  uint64_t pages_requested = 0;
  uint64_t resident_chunks = 0;
  uint64_t resident_bytes = 0;
  uint64_t resident_disk_bytes = 0;  ///< the resident chunks' compressed size in their stores
  uint64_t budget_bytes = 0;
  uint64_t queued = 0;  ///< handed to the loader and not done
  /// Chunks the loader gave up in flight since the previous frame: no frame wanted them any
  /// more (StreamerOptions::cancel_after_frames) or their store was forgotten.
  uint64_t cancelled = 0;
  double upload_ms = 0.0;
};

/// How points of stores carrying ambient occlusion (lod::kAmbientOcclusion: multi-view AO from
/// the range scans, `tessera-lod ao`) are coloured when their chunks are loaded.
enum class StoredAo : uint8_t {
  kModulate,  ///< the point's colour times its visibility
  kOff,       ///< the point's colour
  kAlone,     ///< white times its visibility (the AO by itself, as grey)
};

struct StreamerOptions {
  uint64_t budget_bytes = 1ull << 30;        ///< GPU bytes for resident chunks
  glm::u8vec3 default_color{200, 200, 200};  ///< for stores without colour
  /// Estimate a normal per point on loading (see-through rendering without slant shading).
  /// Costs about as much as decoding again.
  bool normals = false;
  /// Measure each point's density against its node's on loading (see-through rendering evens
  /// out density jumps inside a node with it, e.g. overlapping scans). About as costly as
  /// decoding; render nodes and see-through views turn it on.
  bool density_ratios = false;
  /// Each point's surface cell on loading (spbr.h surfaceCells(): area, centroid and extent),
  /// for see-through chunks only: what lets see-through rendering of sparse scans cover their
  /// surfaces evenly (SpbrCopies::kInCell, the default, and kGaussian with cell_weights). About
  /// twice the cost of decoding, 16 GPU bytes a point; without it copies stay on their points.
  bool surface_cells = true;
  /// Each leaf point's own splat size (splat_sizes.h: the disc that closes the surface around
  /// it, in the GPU point's top byte), for the chunks request() asks them for (leaves seen
  /// close): closes the gaps between scan lines. Several times the cost of decoding, so only
  /// where discs are large; no GPU bytes.
  bool point_splat_sizes = true;
  /// Loader threads decoding (and measuring) in parallel; 0: std::thread::hardware_concurrency().
  uint32_t loader_threads = 0;
  /// Measure every chunk as if it were drawn see-through (the baseline of bench/loader_pool):
  /// benchmarks compare against it; views that may turn see-through at any moment need not, a
  /// chunk is measured again when first wanted see-through.
  bool measure_every_chunk = false;
  /// A chunk in flight that this many frames in a row did not want (the view moved on) is
  /// given up: a slow source's read is withdrawn (lod::RangeSource's cancel token: a remote
  /// site's request leaves the chunk server's queue), its measuring skipped, and the loader
  /// thread takes what the present view needs. 0: never.
  uint32_t cancel_after_frames = 2;
};

/// What a view draws a chunk for (request(), find()).
enum class ChunkUse : uint8_t {
  kOpaque,      ///< its points only
  kSeeThrough,  ///< its points and the measurements see-through rendering takes
                ///< (GpuChunk::measured)
};

class ChunkStreamer {
 public:
  /// Starts the loader threads. A GL context must be current on the constructing thread, which
  /// is the only thread that may call the methods below.
  explicit ChunkStreamer(const StreamerOptions& options = {});
  /// Stops the loader (finishing the items in flight) and frees every buffer.
  ~ChunkStreamer();
  ChunkStreamer(const ChunkStreamer&) = delete;
  ChunkStreamer& operator=(const ChunkStreamer&) = delete;

  /// Starts the next frame: uploads the loader's finished chunks, evicts beyond the budget,
  /// resets the per-frame counters.
  void beginFrame();
  /// The resident chunk of a node, marked used this frame; null when not resident, or, for
  /// ChunkUse::kSeeThrough, resident without its measurements (request() it again).
  const GpuChunk* find(const lod::LodHierarchy& store, lod::NodeId node,
                       ChunkUse use = ChunkUse::kOpaque);
  /// Asks for a missing chunk. Priority: lower levels first, then nearer (`distance`).
  /// Ignored for chunks already resident (for kSeeThrough: resident with measurements), failed,
  /// or finished or in flight with what `use` needs. `splat_sizes`: with the points' own splat
  /// sizes (StreamerOptions::point_splat_sizes); a resident chunk without is decoded again
  /// and replaced when the new copy arrives.
  void request(lod::PointStore& store, lod::NodeId node, uint8_t level, double distance,
               ChunkUse use = ChunkUse::kOpaque, bool splat_sizes = false);
  /// Asks for a missing mesh patch (lod::MeshStore::readPatch, then the GPU layout of
  /// mesh_pass.h). Priority as for points; ignored when resident, failed, done or in flight.
  void request(lod::MeshStore& store, lod::NodeId node, uint8_t level, double distance);
  /// Asks the loader to read the hierarchy page holding `node`'s children (ahead of chunks).
  void requestChildren(lod::LodHierarchy& store, lod::NodeId node);
  /// Whether a chunk failed to load (corrupt): the renderer draws an ancestor instead.
  bool failed(const lod::LodHierarchy& store, lod::NodeId node) const;
  /// Hands this frame's requests to the loader, replacing earlier ones.
  void endFrame();

  /// Blocks until the loader has nothing queued or in flight, or is paused (tools, tests,
  /// screenshots).
  void waitForLoader();
  /// Holds (true) or releases every loader thread before its next item (items in flight are
  /// finished): lets tests observe frames drawn while data is missing.
  void pauseLoader(bool paused);
  /// Drops every chunk of a store (before it is closed): removes its queued items, gives up its
  /// items in flight (a remote read is withdrawn, not waited for) and waits for the loader
  /// threads to leave them, discards what they produced and frees its resident chunks. After
  /// it returns no loader thread touches the store.
  void forget(const lod::LodHierarchy& store);
  /// How chunks loaded from here on colour stored ambient occlusion. The caller forgets the
  /// stores carrying it when the mode changes (ViewRenderer does), so none stays in the old one.
  void setStoredAo(StoredAo mode);
  StoredAo storedAo() const;
  /// Loader threads (StreamerOptions::loader_threads resolved).
  uint32_t loaderThreads() const;
  /// Items the loader threads are working on at this moment (tests, tools).
  uint32_t inFlight() const;

  const StreamStats& stats() const { return mStats; }

 private:
  struct Impl;
  std::unique_ptr<Impl> mImpl;
  StreamStats mStats;
};

}  // namespace tessera::render
