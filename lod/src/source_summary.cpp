#include <tessera/lod/source_summary.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include <tessera/core/file_checks.h>
#include <tessera/core/json_string.h>
#include <tessera/core/progress.h>

namespace tessera::lod {

namespace {

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

std::string vec(const glm::dvec3& v, bool json) {
  if (json) return "[" + num(v.x) + ", " + num(v.y) + ", " + num(v.z) + "]";
  return num(v.x) + " " + num(v.y) + " " + num(v.z);
}

}  // namespace

namespace {

bool isPointStore(const std::filesystem::path& path) {
  if (path.extension() == ".tlod") return true;
  if (notRegularFile(path)) return false;  // the reader says why; an ifstream would block on a FIFO
  std::ifstream in(path, std::ios::binary);
  char magic[4] = {};
  in.read(magic, 4);
  return in && std::memcmp(magic, "TLOD", 4) == 0;
}

void summarizeMeshStore(const std::filesystem::path& path, SourceSummary& s) {
  try {
    const auto store = MeshStore::open(path);
    const MeshSummary& m = store->summary();
    s.mesh_store = m;
    s.opened = true;
    s.stats.points = m.input_vertices;
    s.stats.triangles = m.input_triangles;
    s.bbox_min = m.origin + m.bbox_min;
    s.bbox_max = m.origin + m.bbox_max;
    s.info.attributes = m.colors ? AttributeMask(kColor) : AttributeMask(0);
    s.info.origin = m.origin;
    // Children come after their parents in the table (open() checks it): a node's depth is
    // known when it is met.
    std::vector<uint32_t> depth(store->nodeCount(), 0);
    for (NodeId id = 0; id < store->nodeCount(); ++id) {
      const MeshNodeRecord& r = store->record(id);
      for (uint32_t c = 0; c < r.child_count; ++c) depth[r.first_child + c] = depth[id] + 1;
      if (depth[id] >= s.mesh_levels.size()) s.mesh_levels.resize(depth[id] + 1);
      SourceSummary::MeshLevel& level = s.mesh_levels[depth[id]];
      ++level.patches;
      level.triangles += r.triangles;
      level.max_error = std::max(level.max_error, double(r.error));
    }
  } catch (const StoreError& e) {
    s.error = e.what();
  }
}

}  // namespace

SourceSummary summarizeSource(const std::filesystem::path& path, bool quiet) {
  SourceSummary s;
  s.path = path.string();
  if (path.extension() == ".tmesh" || isMeshStore(path)) {
    summarizeMeshStore(path, s);
    return s;
  }
  if (isPointStore(path)) {
    try {
      auto store = PointStore::open(path);
      s.store = store->summary();
      s.store_sources = store->sources();
      s.opened = true;
      s.stats.points = s.store->points;
      s.bbox_min = s.store->origin + s.store->bbox_min;
      s.bbox_max = s.store->origin + s.store->bbox_max;
      s.info.attributes = s.store->attributes;
      s.info.origin = s.store->origin;
    } catch (const StoreError& e) {
      s.error = e.what();
    }
    return s;
  }
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  try {
    auto reader = openPointReader(path);
    s.info = reader->info();
    s.opened = true;
    // Only worth a bar for big inputs.
    bool show = !quiet && s.info.declared_points > 20'000'000;
    Progress progress("info " + path.filename().string(), s.info.declared_points, " points", !show);
    PointBatch batch;
    try {
      while (reader->next(batch)) {
        for (const auto& p : batch.positions) {
          lo = glm::min(lo, p);
          hi = glm::max(hi, p);
        }
        progress.add(batch.size());
      }
    } catch (const ReadError& e) {
      s.error = e.what();
    }
    s.stats = reader->stats();
  } catch (const ReadError& e) {
    s.error = e.what();
  }
  if (s.stats.points > 0) {
    s.bbox_min = s.info.origin + lo;
    s.bbox_max = s.info.origin + hi;
  }
  return s;
}

namespace {

std::string meshStoreText(const SourceSummary& s) {
  const MeshSummary& m = *s.mesh_store;
  const double per_triangle = double(std::max<uint64_t>(1, m.input_triangles));
  const glm::dvec3 size = m.bbox_max - m.bbox_min;
  std::string o =
      s.path + ": Tessera mesh store (.tmesh) version " + std::to_string(m.version) + "\n";
  char line[256];
  std::snprintf(line, sizeof line,
                "  %llu input triangles, %llu vertices%s; %llu nodes, depth %u, %llu stored "
                "triangles (%.2fx)\n",
                (unsigned long long)m.input_triangles, (unsigned long long)m.input_vertices,
                m.colors ? ", colour" : "", (unsigned long long)m.nodes, m.depth,
                (unsigned long long)m.stored_triangles, double(m.stored_triangles) / per_triangle);
  o += line;
  std::snprintf(line, sizeof line,
                "  origin %.9g %.9g %.9g, size %.6g x %.6g x %.6g, grid step %.3g\n", m.origin.x,
                m.origin.y, m.origin.z, size.x, size.y, size.z, m.step);
  o += line;
  std::snprintf(line, sizeof line, "  %llu bytes: %.2f bytes per input triangle\n",
                (unsigned long long)m.file_bytes, double(m.file_bytes) / per_triangle);
  o += line;
  for (size_t d = 0; d < s.mesh_levels.size(); ++d) {
    const SourceSummary::MeshLevel& l = s.mesh_levels[d];
    std::snprintf(line, sizeof line,
                  "  depth %zu: %llu patches, %llu triangles, error up to %.3g\n", d,
                  (unsigned long long)l.patches, (unsigned long long)l.triangles, l.max_error);
    o += line;
  }
  return o;
}

std::string meshStoreJson(const SourceSummary& s) {
  const MeshSummary& m = *s.mesh_store;
  const double per_triangle = double(std::max<uint64_t>(1, m.input_triangles));
  std::ostringstream o;
  o << ", \"format\": \"tmesh\", \"version\": " << m.version << ", \"points\": " << m.input_vertices
    << ", \"vertices\": " << m.input_vertices << ", \"triangles\": " << m.input_triangles
    << ", \"bbox_min\": " << vec(s.bbox_min, true) << ", \"bbox_max\": " << vec(s.bbox_max, true)
    << ", \"origin\": " << vec(m.origin, true)
    << ", \"size\": " << vec(m.bbox_max - m.bbox_min, true) << ", \"attributes\": ["
    << (m.colors ? "\"color\"" : "") << "], \"skipped\": {}, \"scans\": []"
    << ", \"nodes\": " << m.nodes << ", \"depth\": " << m.depth
    << ", \"stored_triangles\": " << m.stored_triangles
    << ", \"overhead\": " << num(double(m.stored_triangles) / per_triangle)
    << ", \"grid_step\": " << num(m.step) << ", \"file_bytes\": " << m.file_bytes
    << ", \"bytes_per_triangle\": " << num(double(m.file_bytes) / per_triangle)
    << ", \"levels\": [";
  for (size_t d = 0; d < s.mesh_levels.size(); ++d) {
    const SourceSummary::MeshLevel& l = s.mesh_levels[d];
    o << (d ? ", " : "") << "{\"depth\": " << d << ", \"patches\": " << l.patches
      << ", \"triangles\": " << l.triangles << ", \"max_error\": " << num(l.max_error) << "}";
  }
  o << "]";
  return o.str();
}

}  // namespace

std::string summaryText(const SourceSummary& s) {
  if (s.mesh_store) return meshStoreText(s);
  std::ostringstream o;
  o << s.path << "\n";
  if (s.store) {
    const StoreSummary& t = *s.store;
    o << "  format: tlod (Tessera point store, version " << t.version << ")\n";
    o << "  points: " << t.points << "\n  triangles: 0\n";
    o << "  bbox_min: " << vec(s.bbox_min, false) << "\n  bbox_max: " << vec(s.bbox_max, false)
      << "\n";
    o << "  origin: " << vec(t.origin, false) << "\n  attributes:";
    for (const char* a : attributeNames(t.attributes))
      o << " " << (std::strcmp(a, "scan_index") ? a : "source");
    o << "\n  nodes: " << t.nodes << "\n  depth: " << t.depth << "\n";
    o << "  stored_points: " << t.stored_points << " (overhead "
      << num(double(t.stored_points) / double(t.points)) << "x)\n";
    o << "  bytes_per_point: " << num(double(t.file_bytes) / double(t.points))
      << " (position + colour " << num(double(t.position_color_bytes) / double(t.points)) << ")\n";
    o << "  spacing_root: " << num(t.spacing_root)
      << "\n  spacing_finest: " << num(t.spacing_finest) << "\n";
    o << "  leaves: "
      << (t.exact_leaves ? "exact (the input's integers at " + num(t.input_precision) + ")"
                         : std::string("within their stated error bounds"))
      << "\n";
    o << "  sources: " << s.store_sources.size() << "\n";
    for (size_t i = 0; i < s.store_sources.size(); ++i)
      o << "    [" << i << "] " << s.store_sources[i] << "\n";
  }
  if (s.opened && !s.store) {
    o << "  format: " << formatName(s.info.format) << " (" << s.info.format_detail << ")\n";
    o << "  points: " << s.stats.points;
    if (s.info.has_declared_points && s.info.declared_points != s.stats.points) {
      o << " (header declares " << s.info.declared_points << ")";
    }
    o << "\n  triangles: " << s.stats.triangles << "\n";
    if (s.stats.points > 0) {
      o << "  bbox_min: " << vec(s.bbox_min, false) << "\n";
      o << "  bbox_max: " << vec(s.bbox_max, false) << "\n";
    }
    if (s.info.header_bbox) {
      o << "  header_bbox: " << vec(s.info.header_bbox->first, false) << " .. "
        << vec(s.info.header_bbox->second, false) << "\n";
    }
    o << "  origin: " << vec(s.info.origin, false) << "\n";
    o << "  attributes:";
    for (const char* a : attributeNames(s.info.attributes)) o << " " << a;
    if (s.info.attributes == 0) o << " none";
    o << "\n  skipped: " << s.stats.skippedTotal();
    for (auto& [reason, count] : s.stats.skipped) {
      o << "\n    " << reason << ": " << count << " (first at " << s.stats.first_skip_at.at(reason)
        << ")";
    }
    o << "\n";
    if (!s.info.scans.empty()) {
      o << "  scans: " << s.info.scans.size() << "\n";
      for (size_t i = 0; i < s.info.scans.size(); ++i) {
        const ScanInfo& sc = s.info.scans[i];
        const glm::dquat q = confQuaternion(sc.pose);
        o << "    [" << i << "] " << sc.name << ": " << sc.points << " points, grid "
          << sc.grid_columns << "x" << sc.grid_rows << ", t = " << vec(sc.pose.translation, false)
          << ", conf q(i j k r) = " << num(q.x) << " " << num(q.y) << " " << num(q.z) << " "
          << num(q.w) << "\n";
      }
    }
  }
  if (!s.error.empty()) o << "  error: " << s.error << "\n";
  return o.str();
}

std::string summaryJson(const SourceSummary& s) {
  std::ostringstream o;
  o << "{\"file\": " << jsonString(s.path);
  if (s.mesh_store) o << meshStoreJson(s);
  if (s.store) {
    const StoreSummary& t = *s.store;
    o << ", \"format\": \"tlod\", \"version\": " << t.version << ", \"points\": " << t.points
      << ", \"triangles\": 0, \"bbox_min\": " << vec(s.bbox_min, true)
      << ", \"bbox_max\": " << vec(s.bbox_max, true) << ", \"origin\": " << vec(t.origin, true)
      << ", \"attributes\": [";
    bool first = true;
    for (const char* a : attributeNames(t.attributes)) {
      o << (first ? "" : ", ") << jsonString(std::strcmp(a, "scan_index") ? a : "source");
      first = false;
    }
    o << "], \"skipped\": {}, \"scans\": [], \"nodes\": " << t.nodes << ", \"depth\": " << t.depth
      << ", \"bytes_per_point\": " << num(double(t.file_bytes) / double(t.points))
      << ", \"position_color_bytes_per_point\": "
      << num(double(t.position_color_bytes) / double(t.points))
      << ", \"stored_points\": " << t.stored_points
      << ", \"overhead\": " << num(double(t.stored_points) / double(t.points))
      << ", \"spacing_root\": " << num(t.spacing_root)
      << ", \"spacing_finest\": " << num(t.spacing_finest)
      << ", \"exact_leaves\": " << (t.exact_leaves ? "true" : "false")
      << ", \"input_precision\": " << num(t.input_precision) << ", \"sources\": [";
    for (size_t i = 0; i < s.store_sources.size(); ++i)
      o << (i ? ", " : "") << jsonString(s.store_sources[i]);
    o << "]";
  }
  if (s.opened && !s.store && !s.mesh_store) {
    o << ", \"format\": " << jsonString(formatName(s.info.format))
      << ", \"format_detail\": " << jsonString(s.info.format_detail)
      << ", \"points\": " << s.stats.points;
    if (s.info.has_declared_points) o << ", \"declared_points\": " << s.info.declared_points;
    o << ", \"triangles\": " << s.stats.triangles;
    if (s.stats.points > 0) {
      o << ", \"bbox_min\": " << vec(s.bbox_min, true)
        << ", \"bbox_max\": " << vec(s.bbox_max, true);
    } else {
      o << ", \"bbox_min\": null, \"bbox_max\": null";
    }
    o << ", \"origin\": " << vec(s.info.origin, true) << ", \"attributes\": [";
    bool first = true;
    for (const char* a : attributeNames(s.info.attributes)) {
      o << (first ? "" : ", ") << jsonString(a);
      first = false;
    }
    o << "], \"skipped\": {";
    first = true;
    for (auto& [reason, count] : s.stats.skipped) {
      o << (first ? "" : ", ") << jsonString(reason) << ": " << count;
      first = false;
    }
    o << "}, \"scans\": [";
    for (size_t i = 0; i < s.info.scans.size(); ++i) {
      const ScanInfo& sc = s.info.scans[i];
      const glm::dquat q = confQuaternion(sc.pose);
      o << (i ? ", " : "") << "{\"name\": " << jsonString(sc.name) << ", \"points\": " << sc.points
        << ", \"grid\": [" << sc.grid_columns << ", " << sc.grid_rows
        << "], \"translation\": " << vec(sc.pose.translation, true) << ", \"quaternion_ijkr\": ["
        << num(q.x) << ", " << num(q.y) << ", " << num(q.z) << ", " << num(q.w) << "]}";
    }
    o << "]";
  }
  if (!s.error.empty()) o << ", \"error\": " << jsonString(s.error);
  o << "}";
  return o.str();
}

}  // namespace tessera::lod
