// Which node drives which tile of the wall, as nodes join, die and come back (cluster link,
// sync/cluster_link.h). A node is known by its tile's name, not by its connection or MPI rank:
// it names the tile it wants (tessera-node --tile NAME) or is given the first free one; a second
// node claiming a driven tile is refused with a message naming who drives it. A wall's foveal
// insets are slots too, after its tiles (render::wallSlots(): "<inset>", "<inset>/left", ...).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <tessera/cluster.pb.h>
#include <tessera/render/inset.h>
#include <tessera/sync/cluster_link.h>

namespace tessera::master {

class TileTable {
 public:
  enum class State {
    kEmpty,    ///< no node has driven it yet
    kJoining,  ///< welcomed; not in the swap barrier until it reports a rendered frame
    kLive,     ///< in the barrier: every frame waits for it (up to the node timeout)
    kLost,     ///< its node died, hung, failed or spoke garbage; free for a new node
  };

  struct Slot {
    State state = State::kEmpty;
    sync::PeerId peer = 0;
    std::string host;  ///< of the node driving it (Hello)
    uint32_t pid = 0;
    uint64_t welcome_frame = 0;  ///< the snapshot's frame its node started from
    bool started = false;        ///< its startup report said it can render
    bool reported = false;       ///< reported at least one rendered frame since its welcome
    std::string lost_reason;     ///< kLost: why
  };

  /// `wall_name` is used in messages.
  TileTable(const config::WallConfig& wall, std::string wall_name);

  /// The tile a join gets, or why it is refused: a named tile that does not exist or is driven
  /// by a live or joining node; no free tile. Unnamed joins take the first free tile whose host
  /// matches the node's (config::Tile::host, short names match), else the first free tile that
  /// names no host.
  std::variant<uint32_t, std::string> claim(const cluster::Hello& hello) const;

  /// `tile` is driven by `peer` from now on (state kJoining).
  void assign(uint32_t tile, sync::PeerId peer, const cluster::Hello& hello, uint64_t frame);
  void setLive(uint32_t tile);
  void lose(uint32_t tile, const std::string& reason);

  std::optional<uint32_t> tileOf(sync::PeerId peer) const;
  const Slot& slot(uint32_t tile) const { return mSlots[tile]; }
  Slot& slot(uint32_t tile) { return mSlots[tile]; }
  size_t size() const { return mSlots.size(); }
  size_t count(State state) const;
  /// Tiles whose node is joining or live.
  size_t driven() const { return count(State::kJoining) + count(State::kLive); }

  /// "tile left (host h, pid 12)".
  std::string describe(uint32_t tile) const;
  const std::string& name(uint32_t tile) const { return mWallSlots[tile].tile.name(); }
  /// The tile of slot `tile` (an inset's: render::WallSlot::tile).
  const config::Tile& tile(uint32_t tile) const { return mWallSlots[tile].tile; }

 private:
  config::WallConfig mWall;
  std::string mWallName;
  std::vector<render::WallSlot> mWallSlots;
  std::vector<Slot> mSlots;
};

}  // namespace tessera::master
