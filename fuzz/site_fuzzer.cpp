// libFuzzer target: what a remote site sends (collab/site_messages.h, site.proto) as the master
// takes it. The bytes are a sequence of messages, each with a 2-byte little-endian length; each
// one is parsed and checked (parseToMaster), and the ones that pass are applied to a master's
// scene by the site roster (collab/site_roster.h) for two participants, with frames taken in
// between; notes (SiteNote) go to an annotation database in memory (collab/site_notes.h), which
// stores the scene's measurements and selections before every frame. A refusal is the only
// failure allowed: no crash, no exception, no precondition of the
// scene graph broken by anything a site can send.
#include <google/protobuf/stubs/logging.h>

#include <cstdint>
#include <string_view>

#include <tessera/collab/site_messages.h>
#include <tessera/collab/site_notes.h>
#include <tessera/collab/site_roster.h>
#include <tessera/sync/scene_graph.h>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  google::protobuf::LogSilencer quiet;
  tessera::sync::SceneGraph graph;
  tessera::collab::SiteRoster roster;
  tessera::annotate::AnnotationScene notes(":memory:");
  const uint32_t a = roster.join(graph, "fuzz", "key-a");
  const uint32_t b = roster.join(graph, "fuzz", "key-b");
  double now = 0;
  uint64_t frame = 0;
  for (size_t at = 0; at + 2 <= size && frame < 64;) {
    const size_t n = std::min<size_t>(size - at - 2, data[at] | (size_t(data[at + 1]) << 8));
    const std::string_view bytes(reinterpret_cast<const char*>(data + at + 2), n);
    at += 2 + n;
    tessera::site::ToMaster m;
    if (!tessera::collab::parseToMaster(bytes, m)) {
      if (m.kind_case() == tessera::site::ToMaster::kBye) {
        roster.leave(graph, (frame & 1) ? a : b);
      } else if (m.kind_case() == tessera::site::ToMaster::kNote) {
        (void)tessera::collab::applySiteNote(&notes, graph, "fuzz", m.note());
      } else if (m.kind_case() != tessera::site::ToMaster::kHello) {
        roster.apply(graph, (frame & 1) ? a : b, m, now);
      }
    }
    now += 0.01;
    roster.animate(graph, now);
    notes.sync(graph);
    (void)graph.takeFrame(++frame, uint64_t(now * 1e6));
  }
  return 0;
}
