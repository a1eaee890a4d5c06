// Which node drives which tile as nodes join, die and come back (master/tile_table.h).
#include <gtest/gtest.h>

#include <tessera/master/tile_table.h>
#include <tessera/sync/config.h>

namespace {

using tessera::master::TileTable;

tessera::config::WallConfig wall() {
  return tessera::sync::parseWallConfig(
      R"({"tiles": [
        {"name": "left", "width": 1, "height": 1, "pixelWidth": 8, "pixelHeight": 8},
        {"name": "right", "x": 1.1, "width": 1, "height": 1, "pixelWidth": 8, "pixelHeight": 8},
        {"name": "top", "y": 1.1, "width": 1, "height": 1, "pixelWidth": 8, "pixelHeight": 8,
         "host": "pc3.lab"}], "eye": {"z": 2}})",
      "w.json");
}

tessera::cluster::Hello hello(const std::string& tile, const std::string& host = "pc1") {
  tessera::cluster::Hello h;
  h.set_tile(tile);
  h.set_host(host);
  h.set_pid(77);
  return h;
}

uint32_t claimed(const TileTable& t, const tessera::cluster::Hello& h) {
  const auto c = t.claim(h);
  EXPECT_TRUE(std::holds_alternative<uint32_t>(c)) << std::get<std::string>(c);
  return std::holds_alternative<uint32_t>(c) ? std::get<uint32_t>(c) : 999;
}

std::string refusal(const TileTable& t, const tessera::cluster::Hello& h) {
  const auto c = t.claim(h);
  return std::holds_alternative<std::string>(c) ? std::get<std::string>(c) : "(granted)";
}

TEST(TileTable, UnnamedJoinsTakeTheFirstFreeTileAndHostTilesGoToTheirHost) {
  TileTable t(wall(), "w.json");
  EXPECT_EQ(claimed(t, hello("")), 0u);
  t.assign(0, 1, hello(""), 0);
  EXPECT_EQ(claimed(t, hello("")), 1u);
  t.assign(1, 2, hello(""), 0);
  // "top" names host pc3.lab: a node on pc1 gets nothing, one on pc3 (short name) gets it.
  EXPECT_NE(refusal(t, hello("", "pc1")).find("may drive has a node"), std::string::npos);
  EXPECT_EQ(claimed(t, hello("", "pc3")), 2u);
}

TEST(TileTable, NamedTilesDuplicatesAndUnknownNames) {
  TileTable t(wall(), "w.json");
  EXPECT_EQ(claimed(t, hello("right")), 1u);
  t.assign(1, 5, hello("right", "pc9"), 3);
  EXPECT_EQ(t.tileOf(5), std::optional<uint32_t>(1));
  EXPECT_EQ(t.slot(1).state, TileTable::State::kJoining);
  EXPECT_EQ(t.slot(1).welcome_frame, 3u);
  EXPECT_EQ(refusal(t, hello("right")),
            "tile 'right' is already driven by the node on pc9 (pid 77)");
  EXPECT_EQ(refusal(t, hello("middle")),
            "w.json has no tile 'middle' (its tiles: left, right, top)");
  // Lost: free again, for the same name.
  t.lose(1, "dead");
  EXPECT_FALSE(t.tileOf(5));
  EXPECT_EQ(claimed(t, hello("right")), 1u);
  EXPECT_EQ(t.count(TileTable::State::kLost), 1u);
  EXPECT_EQ(t.driven(), 0u);
}

TEST(TileTable, LiveAndDescribe) {
  TileTable t(wall(), "w.json");
  t.assign(2, 9, hello("top", "pc3.lab"), 0);
  t.setLive(2);
  EXPECT_EQ(t.slot(2).state, TileTable::State::kLive);
  EXPECT_EQ(t.driven(), 1u);
  EXPECT_EQ(t.describe(2), "tile top (host pc3.lab, pid 77)");
  EXPECT_EQ(t.describe(0), "tile left");
}

}  // namespace
