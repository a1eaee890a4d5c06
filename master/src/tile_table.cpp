#include <tessera/master/tile_table.h>

#include <algorithm>

namespace tessera::master {

namespace {

bool sameHost(const std::string& a, const std::string& b) {
  auto shortName = [](const std::string& s) { return s.substr(0, s.find('.')); };
  return a == b || shortName(a) == shortName(b);
}

bool free(const TileTable::Slot& s) {
  return s.state == TileTable::State::kEmpty || s.state == TileTable::State::kLost;
}

}  // namespace

TileTable::TileTable(const config::WallConfig& wall, std::string wall_name)
    : mWall(wall),
      mWallName(std::move(wall_name)),
      mWallSlots(render::wallSlots(wall)),
      mSlots(mWallSlots.size()) {}

std::variant<uint32_t, std::string> TileTable::claim(const cluster::Hello& hello) const {
  if (!hello.tile().empty()) {
    for (uint32_t t = 0; t < mSlots.size(); ++t) {
      if (name(t) != hello.tile()) continue;
      if (!free(mSlots[t]))
        return "tile '" + hello.tile() + "' is already driven by the node on " + mSlots[t].host +
               " (pid " + std::to_string(mSlots[t].pid) + ")";
      return t;
    }
    std::string names;
    for (uint32_t t = 0; t < mSlots.size(); ++t) names += (t ? ", " : "") + name(t);
    return mWallName + " has no tile '" + hello.tile().substr(0, 64) + "' (its tiles: " + names +
           ")";
  }
  for (uint32_t t = 0; t < mSlots.size(); ++t) {
    const std::string& host = tile(t).host();
    if (free(mSlots[t]) && !host.empty() && sameHost(host, hello.host())) return t;
  }
  for (uint32_t t = 0; t < mSlots.size(); ++t)
    if (free(mSlots[t]) && tile(t).host().empty()) return t;
  return "every tile of " + mWallName + " that this host (" + hello.host().substr(0, 64) +
         ") may drive has a node; name one with --tile, or stop the node driving it";
}

void TileTable::assign(uint32_t tile, sync::PeerId peer, const cluster::Hello& hello,
                       uint64_t frame) {
  Slot& s = mSlots[tile];
  s = Slot();
  s.state = State::kJoining;
  s.peer = peer;
  s.host = hello.host().substr(0, 256);
  s.pid = hello.pid();
  s.welcome_frame = frame;
}

void TileTable::setLive(uint32_t tile) {
  mSlots[tile].state = State::kLive;
  mSlots[tile].reported = true;
}

void TileTable::lose(uint32_t tile, const std::string& reason) {
  mSlots[tile].state = State::kLost;
  mSlots[tile].lost_reason = reason;
}

std::optional<uint32_t> TileTable::tileOf(sync::PeerId peer) const {
  for (uint32_t t = 0; t < mSlots.size(); ++t)
    if (!free(mSlots[t]) && mSlots[t].peer == peer) return t;
  return std::nullopt;
}

size_t TileTable::count(State state) const {
  return size_t(
      std::count_if(mSlots.begin(), mSlots.end(), [&](const Slot& s) { return s.state == state; }));
}

std::string TileTable::describe(uint32_t tile) const {
  const Slot& s = mSlots[tile];
  std::string d = "tile " + name(tile);
  if (!s.host.empty()) d += " (host " + s.host + ", pid " + std::to_string(s.pid) + ")";
  return d;
}

}  // namespace tessera::master
