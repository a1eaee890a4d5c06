// libFuzzer target: the cluster link's messages (sync/cluster_link.h, cluster.proto) as each side
// takes them from outside. The bytes are parsed as a FromNode (what the master receives: a join
// goes through the master's tile claim, a report through its size check) and as a ToNode (what a
// node receives: a welcome's snapshot and a frame are applied to a replica). Refusals and
// SyncError are the only failures allowed; no crash, no exception of another type.
#include <google/protobuf/stubs/logging.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <variant>

#include <tessera/master/tile_table.h>
#include <tessera/sync/cluster_link.h>
#include <tessera/sync/config.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/wire.h>

namespace {

const tessera::config::WallConfig& wall() {
  static const tessera::config::WallConfig w = tessera::sync::parseWallConfig(
      R"({"tiles": [{"name": "a", "width": 1, "height": 1, "pixelWidth": 4, "pixelHeight": 4},
                    {"name": "b", "x": 1.1, "width": 1, "height": 1, "pixelWidth": 4,
                     "pixelHeight": 4, "host": "h1"}], "eye": {"z": 2}})",
      "fuzz-wall");
  return w;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  google::protobuf::LogSilencer quiet;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  std::string why;

  tessera::cluster::FromNode from;
  if (tessera::sync::parseFromNode(bytes, from, why)) {
    tessera::master::TileTable tiles(wall(), "fuzz-wall");
    if (from.has_hello()) {
      const auto claim = tiles.claim(from.hello());
      if (const auto* t = std::get_if<uint32_t>(&claim)) {
        tiles.assign(*t, 1, from.hello(), 0);
        (void)tiles.describe(*t);
        (void)tiles.claim(from.hello());  // the same tile again: refused or another one
      }
    } else if (from.has_report()) {
      (void)(from.report().rgba().size() == 4 * 4 * 4);
      (void)from.report().status().message().size();
    }
  } else if (why.empty()) {
    std::fprintf(stderr, "link fuzz: a refusal without a reason\n");
    __builtin_trap();
  }

  tessera::cluster::ToNode to;
  if (tessera::sync::parseToNode(bytes, to, why)) {
    tessera::sync::SceneGraph replica;
    try {
      if (to.has_welcome()) replica.apply(to.welcome().snapshot());
      if (to.has_frame()) replica.apply(tessera::sync::parseFrame(to.frame().frame()));
    } catch (const tessera::sync::SyncError&) {
      // refused with a message: what a node reports as NODE_BAD_FRAME
    }
  }
  return 0;
}
