// Export of scans and stores as LAS, LAZ or PLY (see point_export.h).
#include <tessera/lod/point_export.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtx/component_wise.hpp>

#include <tessera/core/progress.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_format.h>

#include "las_file.h"
#include "reader_util.h"

namespace tessera::lod {
namespace {

constexpr const char* kComponent = "lod::exportPoints()";
constexpr double kDefaultScale = 1e-4;  // 0.1 mm for inputs that declare no precision

enum class OutKind { kLas, kLaz, kPly };

OutKind outKind(const std::filesystem::path& out) {
  std::string ext = out.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".las") return OutKind::kLas;
  if (ext == ".laz") return OutKind::kLaz;
  if (ext == ".ply") return OutKind::kPly;
  throw WriteError(std::string(kComponent) + ": " + out.string() +
                   ": the output must end in .las, .laz or .ply");
}

bool hasMagic(const std::filesystem::path& p, const char* magic, size_t n) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(p, ec)) return false;
  std::ifstream in(p, std::ios::binary);
  std::string head(n, '\0');
  in.read(head.data(), std::streamsize(n));
  return in.gcount() == std::streamsize(n) && std::memcmp(head.data(), magic, n) == 0;
}

/// Whether a world position is kept.
struct Cut {
  const ExportOptions& o;
  bool keep(const glm::dvec3& p) const {
    if (o.box && (glm::any(glm::lessThan(p, o.box->first)) ||
                  glm::any(glm::greaterThan(p, o.box->second)))) {
      return false;
    }
    for (const glm::dvec4& pl : o.planes) {
      if (glm::dot(glm::dvec3(pl), p) + pl.w < 0.0) return false;
    }
    return true;
  }
};

/// LAS or LAZ in, LAS or LAZ out: records copied.
ExportReport copyRecords(const std::filesystem::path& in, const std::filesystem::path& out,
                         bool laz, const ExportOptions& o) {
  ByteSource src = ByteSource::openFile(in, kComponent);
  detail::LasParts parts = detail::readLasParts(src, kComponent);
  if (parts.format == 4 || parts.format == 5 || parts.format == 9 || parts.format == 10) {
    throw WriteError(std::string(kComponent) + ": " + in.string() + ": point format " +
                     std::to_string(parts.format) +
                     " refers to waveform packets, which export does not carry");
  }
  const glm::dvec3 scale = parts.scale, offset = parts.offset;
  const uint16_t rl = parts.record_length;
  ExportReport r;
  r.method = std::string("records copied (LAS 1.") + std::to_string(parts.minor) + " format " +
             std::to_string(parts.format) + ", every attribute)";
  detail::LasFileWriter writer(out, std::move(parts), laz, o.threads, kComponent);
  Progress progress("export", 0, "points", o.quiet);
  const Cut cut{o};
  const bool cutting = o.box || !o.planes.empty();
  std::vector<uint8_t> kept;
  detail::forEachRecordBlock(in, o.threads, [&](const uint8_t* records, uint64_t n) {
    r.read += n;
    progress.add(n);
    if (!cutting) {
      writer.add(records, n);
      return;
    }
    kept.clear();
    for (uint64_t i = 0; i < n; ++i) {
      const uint8_t* rec = records + i * rl;
      const glm::dvec3 p(double(detail::loadLE<int32_t>(rec)) * scale.x + offset.x,
                         double(detail::loadLE<int32_t>(rec + 4)) * scale.y + offset.y,
                         double(detail::loadLE<int32_t>(rec + 8)) * scale.z + offset.z);
      if (cut.keep(p)) kept.insert(kept.end(), rec, rec + rl);
    }
    writer.add(kept.data(), kept.size() / rl);
  });
  r.written = writer.points();
  writer.commit();
  return r;
}

/// The points of any source, in batches: (batch, origin) with world = origin + position.
using BatchSink = std::function<void(const PointBatch&, const glm::dvec3&)>;

struct SourceFacts {
  AttributeMask attributes = 0;      ///< what LAS output keeps
  AttributeMask ply_attributes = 0;  ///< what PLY output keeps
  glm::dvec3 origin{0.0};
  double precision = 0.0;
  uint64_t declared = 0;
  std::string what;
};

/// A .tlod store's leaves: every input point once. Their positions are whole steps from each
/// leaf's own corner, so no one LAS grid holds them all exactly: the scale is 1/256 of the finest
/// leaf step (the stored positions kept within 1/512 of a step), as long as the store's extent
/// fits the LAS range at it.
SourceFacts storeFacts(PointStore& store) {
  SourceFacts f;
  const StoreSummary& sum = store.summary();
  f.attributes = sum.attributes & (kColor | kIntensity | kClassification);
  f.ply_attributes = f.attributes & (kColor | kIntensity);
  f.origin = sum.origin;
  f.declared = sum.points;
  f.what = "store leaves";
  double finest = std::numeric_limits<double>::max();
  std::vector<NodeId> stack{store.root()};
  while (!stack.empty()) {
    const NodeId id = stack.back();
    stack.pop_back();
    const NodeInfo n = store.node(id);
    if (n.leaf()) {
      if (n.points) finest = std::min(finest, double(n.error_bound) * 2.0 / std::sqrt(3.0));
    } else {
      for (NodeId c : store.children(id)) stack.push_back(c);
    }
  }
  const double extent = glm::compMax(glm::abs(sum.bbox_max) + glm::abs(sum.bbox_min));
  f.precision = std::max(finest < std::numeric_limits<double>::max() ? finest / 256.0 : kDefaultScale,
                         extent / 2e9);
  return f;
}

/// Every leaf of a store, in depth-first order.
std::vector<NodeId> allLeaves(PointStore& store) {
  std::vector<NodeId> leaves, stack{store.root()};
  while (!stack.empty()) {
    const NodeId id = stack.back();
    stack.pop_back();
    if (store.node(id).leaf()) {
      leaves.push_back(id);
    } else {
      for (NodeId c : store.children(id)) stack.push_back(c);
    }
  }
  return leaves;
}

void readStore(PointStore& store, const ExportOptions& o, const BatchSink& sink) {
  const std::vector<NodeId> all = allLeaves(store);
  std::vector<NodeId> leaves = o.leaves ? *o.leaves : all;
  if (o.leaves) {  // a selection's nodes must be leaves of this store
    const std::vector<NodeId> sorted = [&] {
      auto v = all;
      std::sort(v.begin(), v.end());
      return v;
    }();
    for (NodeId id : leaves) {
      if (!std::binary_search(sorted.begin(), sorted.end(), id)) {
        throw ReadError(std::string(kComponent) + ": " + store.path().string() +
                        ": the selection names node " + std::to_string(id) +
                        ", which is not a leaf of this store (it was made on another store)");
      }
    }
  }
  PointBatch batch;
  const glm::dvec3 origin = store.summary().origin;
  for (NodeId id : leaves) {
    // The cells too: in double, offset + grid + cell * step is the stored point exactly (the
    // input's own integers in an exact store), where the float positions round.
    const auto chunk = store.decodeChunk(id, {}, true);
    if (o.leaf_size && o.leaf_size(id) != chunk->size()) {
      throw ReadError(std::string(kComponent) + ": " + store.path().string() +
                      ": the selection counts " + std::to_string(o.leaf_size(id)) +
                      " points in node " + std::to_string(id) + ", which holds " +
                      std::to_string(chunk->size()) + " (it was made on another store)");
    }
    batch.reset(chunk->attributes & (kColor | kIntensity | kClassification));
    batch.resize(chunk->size());
    size_t kept = 0;
    for (size_t i = 0; i < chunk->size(); ++i) {
      if (o.keep_element && !o.keep_element(id, uint32_t(i))) continue;
      batch.positions[kept] =
          chunk->offset + chunk->grid + glm::dvec3(chunk->cells[i]) * chunk->step;
      if (batch.attributes & kColor) batch.colors[kept] = chunk->colors[i];
      if (batch.attributes & kIntensity) batch.intensities[kept] = float(chunk->intensities[i]);
      if (batch.attributes & kClassification) batch.classifications[kept] = chunk->classifications[i];
      ++kept;
    }
    batch.resize(kept);
    sink(batch, origin);
  }
}

/// Points of anything but LAS-to-LAS, written as LAS 1.4 (format 7, or 6 without colour).
void writeConverted(const SourceFacts& f, const std::function<void(const BatchSink&)>& source,
                    const std::filesystem::path& out, bool laz, const ExportOptions& o,
                    ExportReport& r) {
  const int format = f.attributes & kColor ? 7 : 6;
  const double s = o.scale > 0 ? o.scale : f.precision > 0 ? f.precision : kDefaultScale;
  const glm::dvec3 scale(s), offset = f.origin;
  detail::LasFileWriter writer(out, detail::newLasParts(format, 0, scale, offset), laz, o.threads,
                               kComponent);
  const uint16_t rl = writer.recordLength();
  r.method = "points converted to LAS 1.4 format " + std::to_string(format) + " at a scale of " +
             std::to_string(s) + " (from " + f.what + ")";
  Progress progress("export", f.declared, "points", o.quiet);
  const Cut cut{o};
  std::vector<uint8_t> records;
  source([&](const PointBatch& b, const glm::dvec3& origin) {
    records.clear();
    for (size_t i = 0; i < b.size(); ++i) {
      const glm::dvec3 p = origin + b.positions[i];
      if (!cut.keep(p)) continue;
      const glm::dvec3 q = glm::round((p - offset) / scale);
      if (glm::any(glm::greaterThan(glm::abs(q), glm::dvec3(2147483647.0))) ||
          !std::isfinite(q.x + q.y + q.z)) {
        throw WriteError(std::string(kComponent) + ": " + out.string() + ": a point at (" +
                         std::to_string(p.x) + ", " + std::to_string(p.y) + ", " +
                         std::to_string(p.z) + ") lies beyond the LAS coordinate range at a "
                         "scale of " + std::to_string(s) + "; export with a coarser --scale");
      }
      uint8_t rec[36] = {};
      for (int c = 0; c < 3; ++c) {
        const int32_t v = int32_t(q[c]);
        std::memcpy(rec + 4 * c, &v, 4);
      }
      const uint16_t intensity =
          b.attributes & kIntensity
              ? uint16_t(std::clamp(std::round(b.intensities[i]), 0.f, 65535.f))
              : 0;
      std::memcpy(rec + 12, &intensity, 2);
      rec[14] = 0x11;  // return 1 of 1
      rec[16] = b.attributes & kClassification ? b.classifications[i] : 1;
      if (format == 7) {
        for (int c = 0; c < 3; ++c) {
          const uint16_t v = uint16_t(b.colors[i][c] * 257);
          std::memcpy(rec + 30 + 2 * c, &v, 2);
        }
      }
      records.insert(records.end(), rec, rec + rl);
    }
    writer.add(records.data(), records.size() / rl);
    r.read += b.size();
    progress.add(b.size());
  });
  r.written = writer.points();
  writer.commit();
}

void writePlyOut(const SourceFacts& f, const std::function<void(const BatchSink&)>& source,
                 const std::filesystem::path& out, const ExportOptions& o, ExportReport& r) {
  PointBatch all;
  all.reset(f.ply_attributes);
  const Cut cut{o};
  Progress progress("export", f.declared, "points", o.quiet);
  source([&](const PointBatch& b, const glm::dvec3& origin) {
    for (size_t i = 0; i < b.size(); ++i) {
      const glm::dvec3 p = origin + b.positions[i];
      if (!cut.keep(p)) continue;
      all.appendFrom(b, i);
      all.positions.back() = p - f.origin;
    }
    r.read += b.size();
    progress.add(b.size());
  });
  PlyWriteOptions po;
  po.double_positions = true;
  writePly(out, all, f.origin, po);
  r.written = all.size();
  r.method = "points written as binary PLY with double positions (from " + f.what + ")";
}

}  // namespace

ExportReport exportPoints(const std::filesystem::path& input, const std::filesystem::path& output,
                          const ExportOptions& o) {
  const OutKind kind = outKind(output);
  if (kind != OutKind::kPly && hasMagic(input, "LASF", 4) && !o.leaves && !o.keep_element) {
    return copyRecords(input, output, kind == OutKind::kLaz, o);
  }
  ExportReport r;
  SourceFacts facts;
  std::function<void(const BatchSink&)> source;
  std::unique_ptr<PointStore> store;
  if (hasMagic(input, store::kMagic, 4)) {
    store = PointStore::open(input, 64ull << 20);
    facts = storeFacts(*store);
    source = [&](const BatchSink& sink) { readStore(*store, o, sink); };
  } else {
    if (o.leaves || o.keep_element || o.leaf_size) {
      throw ReadError(std::string(kComponent) + ": " + input.string() +
                      ": a selection picks points of the .tlod store it was made on, not of a scan");
    }
    ReaderOptions ro;
    ro.decode_threads = o.threads;
    auto probe = openPointReader(input, ro);
    const SourceInfo& info = probe->info();
    facts.attributes = info.attributes & (kColor | kIntensity | kClassification);
    facts.ply_attributes = info.attributes & (kNormal | kColor | kAlpha | kIntensity | kConfidence);
    facts.origin = info.origin;
    facts.precision = info.precision;
    facts.declared = info.declared_points;
    facts.what = std::string(formatName(info.format)) + " points";
    source = [&input, ro](const BatchSink& sink) {
      auto reader = openPointReader(input, ro);
      PointBatch b;
      while (reader->next(b)) {
        if (b.size()) sink(b, reader->info().origin);
      }
    };
  }
  if (kind == OutKind::kPly) {
    writePlyOut(facts, source, output, o, r);
  } else {
    writeConverted(facts, source, output, kind == OutKind::kLaz, o, r);
  }
  return r;
}

}  // namespace tessera::lod
