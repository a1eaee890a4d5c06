// The small 2x2 wall the process tests run (tests/cluster, tests/collab): 320x180 tiles, 2 cm
// bezels, so that a master, four nodes and a few sites share two cores.
#pragma once

#include <string>

namespace tessera::test {

/// The wall's JSON; `extra_tile_1_1` is added to tile-1-1's fields, `extra` to the wall's.
inline std::string smallWallJson(const std::string& extra_tile_1_1 = "",
                                 const std::string& extra = "") {
  auto tile = [](const std::string& name, double x, double y, const std::string& more) {
    return R"({"name": ")" + name + R"(", "x": )" + std::to_string(x) + R"(, "y": )" +
           std::to_string(y) +
           R"(, "width": 0.48, "height": 0.27, "pixelWidth": 320, "pixelHeight": 180)" + more + "}";
  };
  return R"({"name": "small 2x2", "tiles": [)" + tile("tile-0-0", 0, 0.29, "") + "," +
         tile("tile-1-0", 0.5, 0.29, "") + "," + tile("tile-0-1", 0, 0, "") + "," +
         tile("tile-1-1", 0.5, 0, extra_tile_1_1) +
         R"(], "eye": {"x": 0.49, "y": 0.28, "z": 1.5})" + extra + "}";
}

}  // namespace tessera::test
