#include <tessera/master/tile_assignment.h>

#include <gtest/gtest.h>

namespace {

using namespace tessera;

config::WallConfig wall(const std::vector<std::string>& hosts) {
  config::WallConfig w;
  for (size_t i = 0; i < hosts.size(); ++i) {
    config::Tile* t = w.add_tiles();
    t->set_name("t" + std::to_string(i));
    t->set_host(hosts[i]);
  }
  return w;
}

TEST(TileAssignment, ConfigOrderWithoutHosts) {
  EXPECT_EQ(master::assignTiles(wall({"", "", ""}), {"a", "a", "b"}, "w.json"),
            (std::vector<uint32_t>{0, 1, 2}));
}

TEST(TileAssignment, TilesNamingHostsGoToRanksOnThem) {
  // Tiles 0 and 2 on host b (full and short name), tile 1 anywhere.
  EXPECT_EQ(master::assignTiles(wall({"b", "", "b.lab"}), {"a.lab", "b.lab", "b"}, "w.json"),
            (std::vector<uint32_t>{1, 0, 2}));
}

TEST(TileAssignment, WrongCountAndUnknownHostAreErrors) {
  try {
    master::assignTiles(wall({"", ""}), {"a"}, "w.json");
    FAIL();
  } catch (const master::AssignmentError& e) {
    EXPECT_NE(std::string(e.what()).find("w.json has 2 tiles but 1 render nodes"),
              std::string::npos);
  }
  try {
    master::assignTiles(wall({"c", ""}), {"a", "b"}, "w.json");
    FAIL();
  } catch (const master::AssignmentError& e) {
    EXPECT_NE(std::string(e.what()).find("tiles[0] 't0' names host 'c'"), std::string::npos)
        << e.what();
  }
}

}  // namespace
