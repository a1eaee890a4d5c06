#include <tessera/lod/store_cache.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <stdexcept>

#include <tessera/lod/mesh_samples.h>
#include <tessera/lod/point_writer.h>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

namespace tessera::lod {

namespace fs = std::filesystem;

fs::path cachedStorePath(const fs::path& input, const std::string& who) {
  if (input.extension() == ".tlod") return input;
  std::error_code ec;
  const auto size = fs::file_size(input, ec);
  if (ec) throw std::runtime_error(who + ": " + input.string() + ": " + ec.message());
  const auto mtime = fs::last_write_time(input, ec).time_since_epoch().count();
  // Without its time a changed input would be taken for the cached one.
  if (ec) throw std::runtime_error(who + ": " + input.string() + ": " + ec.message());
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

bool cachedStoreReady(const fs::path& input) {
  try {
    std::error_code ec;
    return fs::exists(cachedStorePath(input, "lod::cachedStoreReady"), ec);
  } catch (const std::runtime_error&) {
    return false;
  }
}

namespace {

/// An exclusive lock on a file beside a cache entry, held while the entry is checked and built:
/// processes sharing the cache (the nodes of one host, a master and its nodes) build an entry
/// once, the others wait for it. flock(2) locks go with the process, so a killed builder frees
/// its lock.
class EntryLock {
 public:
  EntryLock(const fs::path& lock_file, const std::string& who) {
    mFd = ::open(lock_file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (mFd < 0)
      throw std::runtime_error(who + ": cannot open the cache lock " + lock_file.string() + ": " +
                               std::strerror(errno));
    while (::flock(mFd, LOCK_EX) != 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(mFd);
      throw std::runtime_error(who + ": cannot lock " + lock_file.string() + ": " +
                               std::strerror(err));
    }
  }
  ~EntryLock() { ::close(mFd); }
  EntryLock(const EntryLock&) = delete;
  EntryLock& operator=(const EntryLock&) = delete;

 private:
  int mFd = -1;
};

/// A name beside `out` no other process or thread uses: the build's own output, its .partial
/// and its temporary folder (store_builder.h) all derive from it.
fs::path privateName(const fs::path& out, const char* suffix) {
  static std::atomic<uint64_t> counter{0};
  return out.parent_path() / (out.stem().string() + ".building-" + std::to_string(::getpid()) +
                              "-" + std::to_string(counter++) + suffix);
}

}  // namespace

fs::path cachedStoreFor(const fs::path& input, const std::string& who, bool quiet) {
  if (input.extension() == ".tlod") return input;
  const fs::path out = cachedStorePath(input, who);
  std::error_code ec;
  if (fs::exists(out)) return out;
  const EntryLock lock(out.string() + ".lock", who);
  if (fs::exists(out)) return out;  // another process built it while this one waited
  std::fprintf(stderr, "%s: converting %s into %s\n", who.c_str(), input.c_str(), out.c_str());
  BuildOptions o;
  o.quiet = quiet;
  const fs::path built = privateName(out, ".tlod");
  if (input.extension() == ".tmesh") {
    // A mesh store as points on its triangles (mesh_samples.h), for see-through drawing.
    const auto mesh = MeshStore::open(input);
    const fs::path ply = privateName(out, ".points.ply");
    writePly(ply, sampleMeshStore(*mesh), mesh->summary().origin);
    try {
      buildStore({ply}, built, o);
    } catch (...) {
      fs::remove(ply, ec);
      throw;
    }
    fs::remove(ply, ec);
  } else {
    buildStore({input}, built, o);
  }
  // The entry appears whole or not at all.
  fs::rename(built, out, ec);
  if (ec) {
    fs::remove(built, ec);
    throw std::runtime_error(who + ": cannot move " + built.string() + " to " + out.string() +
                             ": " + ec.message());
  }
  return out;
}

}  // namespace tessera::lod
