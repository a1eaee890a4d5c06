// Which render node drives which tile of the wall. Nodes are MPI ranks 1..K; by default rank
// r drives the wall's tile r - 1 in config order. Tiles that name a host (config::Tile::host) go
// to the ranks running on that host, in rank order; the other tiles to the remaining ranks in
// order.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <tessera/sync/config.h>

namespace tessera::master {

/// The node count or the hosts do not fit the wall. The message names the wall file, the tile
/// or rank and the hosts.
class AssignmentError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// `hosts[i]` is the host of rank i + 1. Returns the tile index of each node (rank i + 1 at
/// [i]). A host matches a tile's host when equal, or equal up to the first '.' (short names).
/// Throws AssignmentError when the node count differs from the tile count, or a tile's host runs
/// no free node. `wall_name` is used in messages.
std::vector<uint32_t> assignTiles(const config::WallConfig& wall,
                                  const std::vector<std::string>& hosts,
                                  const std::string& wall_name);

}  // namespace tessera::master
