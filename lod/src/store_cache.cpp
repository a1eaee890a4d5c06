#include <tessera/lod/store_cache.h>

#include <cstdio>
#include <cstdlib>
#include <functional>
#include <stdexcept>

#include <tessera/lod/mesh_samples.h>
#include <tessera/lod/point_writer.h>

namespace tessera::lod {

namespace fs = std::filesystem;

fs::path cachedStorePath(const fs::path& input, const std::string& who) {
  if (input.extension() == ".tlod") return input;
  std::error_code ec;
  const auto size = fs::file_size(input, ec);
  if (ec) throw std::runtime_error(who + ": " + input.string() + ": " + ec.message());
  const auto mtime = fs::last_write_time(input, ec).time_since_epoch().count();
  const char* cache_env = std::getenv("XDG_CACHE_HOME");
  const char* home = std::getenv("HOME");
  fs::path cache = cache_env && *cache_env ? fs::path(cache_env)
                                           : fs::path(home && *home ? home : "/tmp") / ".cache";
  cache /= "tessera";
  fs::create_directories(cache, ec);
  if (ec)
    throw std::runtime_error(who + ": cannot create the store cache " + cache.string() + ": " +
                             ec.message());
  const size_t key = std::hash<std::string>{}(fs::absolute(input).string() + ":" +
                                              std::to_string(size) + ":" + std::to_string(mtime));
  return cache / (input.stem().string() + "-" + std::to_string(key) + ".tlod");
}

fs::path cachedStoreFor(const fs::path& input, const std::string& who, bool quiet) {
  if (input.extension() == ".tlod") return input;
  const fs::path out = cachedStorePath(input, who);
  std::error_code ec;
  if (!fs::exists(out)) {
    std::fprintf(stderr, "%s: converting %s into %s\n", who.c_str(), input.c_str(), out.c_str());
    BuildOptions o;
    o.quiet = quiet;
    if (input.extension() == ".tmesh") {
      // A mesh store as points on its triangles (mesh_samples.h), for see-through drawing.
      const auto mesh = MeshStore::open(input);
      const fs::path ply = out.string() + ".points.ply";
      writePly(ply, sampleMeshStore(*mesh), mesh->summary().origin);
      try {
        buildStore({ply}, out, o);
      } catch (...) {
        fs::remove(ply, ec);
        throw;
      }
      fs::remove(ply, ec);
    } else {
      buildStore({input}, out, o);
    }
  }
  return out;
}

}  // namespace tessera::lod
