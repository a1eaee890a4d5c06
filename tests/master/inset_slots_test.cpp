// A wall's foveal insets are slots after its tiles: named joins, unnamed joins and MPI rank
// assignment give nodes to them as to tiles (master/tile_table.h, master/tile_assignment.h).
#include <gtest/gtest.h>

#include <tessera/master/tile_assignment.h>
#include <tessera/master/tile_table.h>
#include <tessera/sync/config.h>

namespace {

using tessera::master::TileTable;

tessera::config::WallConfig wall() {
  return tessera::sync::parseWallConfig(
      R"({"tiles": [
        {"name": "left", "width": 1, "height": 1, "pixelWidth": 8, "pixelHeight": 8},
        {"name": "right", "x": 1.1, "width": 1, "height": 1, "pixelWidth": 8, "pixelHeight": 8}],
        "insets": [{"name": "fovea", "x": 0.8, "y": 0.2, "width": 0.5, "height": 0.5,
                    "pixelWidth": 16, "pixelHeight": 16, "stereo": true},
                   {"name": "detail", "x": 0.1, "y": 0.1, "width": 0.2, "height": 0.2,
                    "pixelWidth": 12, "pixelHeight": 12}],
        "eye": {"z": 2}})",
      "w.json");
}

tessera::cluster::Hello hello(const std::string& tile) {
  tessera::cluster::Hello h;
  h.set_tile(tile);
  h.set_host("pc1");
  h.set_pid(77);
  return h;
}

TEST(InsetSlots, NamedJoinsClaimAnInsetsEyeAndUnnamedJoinsFillInsetsAfterTiles) {
  TileTable t(wall(), "w.json");
  ASSERT_EQ(t.size(), 5u);  // left, right, fovea/left, fovea/right, detail
  EXPECT_EQ(t.name(2), "fovea/left");
  EXPECT_EQ(t.name(3), "fovea/right");
  EXPECT_EQ(t.name(4), "detail");
  EXPECT_EQ(t.tile(3).pixel_width(), 16u);
  const auto right_eye = t.claim(hello("fovea/right"));
  ASSERT_TRUE(std::holds_alternative<uint32_t>(right_eye));
  EXPECT_EQ(std::get<uint32_t>(right_eye), 3u);
  t.assign(3, 9, hello("fovea/right"), 0);
  const auto again = t.claim(hello("fovea/right"));
  ASSERT_TRUE(std::holds_alternative<std::string>(again));
  EXPECT_NE(std::get<std::string>(again).find("tile 'fovea/right' is already driven"),
            std::string::npos);
  // A stereo inset has no mono slot.
  const auto mono = t.claim(hello("fovea"));
  ASSERT_TRUE(std::holds_alternative<std::string>(mono));
  EXPECT_NE(std::get<std::string>(mono).find("fovea/left, fovea/right, detail"), std::string::npos)
      << std::get<std::string>(mono);
  for (uint32_t i = 0; i < 2; ++i) t.assign(i, 10 + i, hello(""), 0);
  const auto next = t.claim(hello(""));
  ASSERT_TRUE(std::holds_alternative<uint32_t>(next));
  EXPECT_EQ(std::get<uint32_t>(next), 2u);
}

TEST(InsetSlots, MpiRanksCoverTilesAndInsetSlots) {
  const std::vector<std::string> five(5, "pc1");
  const std::vector<uint32_t> tiles = tessera::master::assignTiles(wall(), five, "w.json");
  EXPECT_EQ(tiles, (std::vector<uint32_t>{0, 1, 2, 3, 4}));
  try {
    (void)tessera::master::assignTiles(wall(), {"pc1", "pc1"}, "w.json");
    ADD_FAILURE() << "two nodes for five slots";
  } catch (const tessera::master::AssignmentError& e) {
    EXPECT_NE(std::string(e.what()).find("has 5 tiles but 2 render nodes"), std::string::npos)
        << e.what();
  }
}

}  // namespace
