#include <tessera/master/tile_assignment.h>

#include <tessera/render/inset.h>

namespace tessera::master {

namespace {

bool sameHost(const std::string& a, const std::string& b) {
  auto shortName = [](const std::string& s) { return s.substr(0, s.find('.')); };
  return a == b || shortName(a) == shortName(b);
}

}  // namespace

std::vector<uint32_t> assignTiles(const config::WallConfig& wall,
                                  const std::vector<std::string>& hosts,
                                  const std::string& wall_name) {
  // A wall's foveal insets are slots after its tiles.
  const std::vector<render::WallSlot> slots = render::wallSlots(wall);
  const size_t tiles = slots.size();
  if (hosts.size() != tiles) {
    throw AssignmentError("master::assignTiles(): " + wall_name + " has " + std::to_string(tiles) +
                          " tiles but " + std::to_string(hosts.size()) +
                          " render nodes were started; start one tessera-node per tile (mpirun "
                          "-np 1 tessera-master ... : -np " +
                          std::to_string(tiles) + " tessera-node)");
  }
  constexpr uint32_t kFree = ~0u;
  std::vector<uint32_t> tile_of(hosts.size(), kFree);
  // Tiles bound to a host first, so unbound tiles do not take their ranks.
  for (size_t t = 0; t < tiles; ++t) {
    const std::string& host = slots[t].tile.host();
    if (host.empty()) continue;
    size_t r = 0;
    while (r < hosts.size() && !(tile_of[r] == kFree && sameHost(hosts[r], host))) ++r;
    if (r == hosts.size()) {
      std::string started;
      for (size_t i = 0; i < hosts.size(); ++i)
        started +=
            (i ? ", " : "") + std::string("rank ") + std::to_string(i + 1) + " on " + hosts[i];
      throw AssignmentError("master::assignTiles(): " + wall_name + ": tiles[" + std::to_string(t) +
                            "] '" + slots[t].tile.name() + "' names host '" + host +
                            "', which runs no free render node (" + started + ")");
    }
    tile_of[r] = uint32_t(t);
  }
  size_t r = 0;
  for (size_t t = 0; t < tiles; ++t) {
    if (!slots[t].tile.host().empty()) continue;
    while (tile_of[r] != kFree) ++r;  // counts are equal, so a free rank remains
    tile_of[r] = uint32_t(t);
  }
  return tile_of;
}

}  // namespace tessera::master
