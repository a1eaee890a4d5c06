// Raw scans as stores without a build step: any file a reader takes (PLY, LAS, .conf, XYZ, OBJ)
// is built once into a .tlod in a cache folder and reused while the file is unchanged. The cache
// is $XDG_CACHE_HOME/tessera (else ~/.cache/tessera); entries are keyed by the input's absolute
// path, size and modification time. Several processes may share the cache: an entry is built by
// one process under a lock beside it (the others wait, then open it), under names of its own,
// and renamed into place whole, so a killed build never leaves an entry that opens.
// tessera-render --model and the master's scenes use it; the master converts before any node
// sees the scene, so the nodes of its host share the entry.
#pragma once

#include <filesystem>
#include <string>

#include <tessera/lod/store_builder.h>

namespace tessera::lod {

/// `input` itself when it is a .tlod; else the cached store built from it (a .tmesh mesh store:
/// from points sampled on its triangles, mesh_samples.h, for see-through drawing) (building it
/// first when missing: progress on stderr unless `quiet`, a line "WHO: converting INPUT into
/// STORE"). Throws std::runtime_error (lod::StoreError, ReadError ...) naming the file when the
/// input cannot be read or the store not written.
std::filesystem::path cachedStoreFor(const std::filesystem::path& input, const std::string& who,
                                     bool quiet = false);

/// Where cachedStoreFor() keeps (or will keep) the store of `input`, without building it:
/// `input` itself for a .tlod. Throws std::runtime_error naming the input when it cannot be
/// stat'ed or the cache folder not made.
std::filesystem::path cachedStorePath(const std::filesystem::path& input, const std::string& who);

/// Whether cachedStoreFor(`input`) would return at once: a .tlod, or a cache entry made before.
/// False too when `input` cannot be stat'ed (cachedStoreFor() then says why).
bool cachedStoreReady(const std::filesystem::path& input);

}  // namespace tessera::lod
