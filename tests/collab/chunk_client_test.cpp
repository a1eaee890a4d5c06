// A site's disk cache of chunk server ranges (collab/chunk_client.h) when several loader threads
// meet one broken cached copy at once, as a mesh patch and its child's morph targets do: each
// thread ends with the server's bytes, and the broken copy is dropped and counted once. A real
// chunk server and client over CURVE on 127.0.0.1, in this process.
#include <tessera/collab/chunk_client.h>
#include <tessera/collab/chunk_server.h>
#include <tessera/collab/curve.h>

#include <sys/stat.h>

#include <barrier>
#include <filesystem>
#include <memory>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <zmq.hpp>

#include "../support/temp_dir.h"

namespace tessera::collab {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kOffset = 4096;
constexpr size_t kLength = 8192;
constexpr int kThreads = 4;

/// A chunk server for one store of known bytes, and a site's client with a disk cache.
struct Link {
  test::TempDir dir;
  fs::path store = dir.path() / "store.bin", cache = dir.path() / "cache";
  std::vector<uint8_t> bytes = std::vector<uint8_t>(65536);
  KeyPair master = generateKeyPair(), site = generateKeyPair();
  zmq::context_t context{1};
  std::unique_ptr<ZapHandler> zap;
  std::unique_ptr<ChunkServer> server;
  std::unique_ptr<ChunkClient> client;
  std::unique_ptr<lod::RangeSource> source;

  Link() {
    for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = uint8_t(i * 31 + i / 256 + 7);
    test::writeBytes(store, bytes);
    const fs::path allow = dir.path() / "allow.txt";
    test::writeText(allow, site.public_key + " loaders\n");
    ::chmod(allow.c_str(), 0644);
    zap = std::make_unique<ZapHandler>(context, std::make_shared<AllowList>(allow));
    ChunkServerOptions so;
    so.endpoint = "tcp://127.0.0.1:*";
    server = std::make_unique<ChunkServer>(context, master, so);
    server->setStores({store.string()});
    ChunkClientOptions co;
    co.endpoint = server->endpoint();
    co.master_key = master.public_key;
    co.keys = site;
    co.cache_dir = cache.string();
    co.timeout_s = 10;
    client = std::make_unique<ChunkClient>(co);
    source = client->open(store.string());
  }
  ~Link() {  // the client and the server before the context
    source.reset();
    client.reset();
    server.reset();
    zap.reset();
  }

  std::vector<uint8_t> expected() const {
    return {bytes.begin() + kOffset, bytes.begin() + kOffset + kLength};
  }
  /// The cached copy of the range, after a first read put it there.
  fs::path cachedCopy() const {
    for (const auto& e : fs::recursive_directory_iterator(cache))
      if (e.path().filename() == std::to_string(kOffset) + "+" + std::to_string(kLength))
        return e.path();
    return {};
  }
};

TEST(ChunkClientCache, LoadersReadingOneBrokenCopyAtOnceAllGetTheServersBytesAndItCountsOnce) {
  Link link;
  std::vector<uint8_t> first(kLength);
  link.source->read(kOffset, first.data(), kLength);
  ASSERT_EQ(first, link.expected());
  const fs::path copy = link.cachedCopy();
  ASSERT_FALSE(copy.empty()) << "the first read is kept in the cache";
  std::vector<uint8_t> broken = test::readBytes(copy);
  broken[kLength / 2] ^= 0x5A;  // as a disk would: same size, other bytes
  test::writeBytes(copy, broken);

  // Each thread reads, then (as PointStore and MeshStore do on a failed checksum) asks for the
  // range again and reads once more. All read the broken copy before any asks again.
  std::barrier all_read(kThreads);
  std::vector<std::vector<uint8_t>> got(kThreads, std::vector<uint8_t>(kLength));
  std::vector<int> saw_broken(kThreads), read_again(kThreads);
  std::vector<std::jthread> loaders;
  for (int t = 0; t < kThreads; ++t)
    loaders.emplace_back([&, t] {
      link.source->read(kOffset, got[t].data(), kLength);
      saw_broken[t] = got[t] != link.expected();
      all_read.arrive_and_wait();
      if (saw_broken[t] && link.source->refetch(kOffset, kLength)) {
        read_again[t] = 1;
        link.source->read(kOffset, got[t].data(), kLength);
      }
    });
  loaders.clear();
  for (int t = 0; t < kThreads; ++t) {
    EXPECT_TRUE(saw_broken[t]) << "thread " << t;
    EXPECT_TRUE(read_again[t]) << "thread " << t << ": the source lets every reader read again";
    EXPECT_EQ(got[t], link.expected()) << "thread " << t;
  }
  EXPECT_EQ(link.client->counters().refetched, 1u) << "one broken copy";
  EXPECT_EQ(test::readBytes(copy), link.expected()) << "the cache holds the good bytes again";

  // Bytes that came from the server and not from the cache: nothing to drop, read as they are.
  std::vector<uint8_t> direct(16);
  link.source->read(0, direct.data(), direct.size());
  EXPECT_FALSE(link.source->refetch(0, direct.size()));
}

TEST(ChunkClientCache, LoadersMeetingOneCopyOfTheWrongSizeAllGetTheServersBytesAndItCountsOnce) {
  Link link;
  std::vector<uint8_t> first(kLength);
  link.source->read(kOffset, first.data(), kLength);
  const fs::path copy = link.cachedCopy();
  ASSERT_FALSE(copy.empty());
  fs::resize_file(copy, kLength / 2);  // cut short, as a full disk or a crash leaves it

  std::barrier start(kThreads);
  std::vector<std::vector<uint8_t>> got(kThreads, std::vector<uint8_t>(kLength));
  std::vector<std::jthread> loaders;
  for (int t = 0; t < kThreads; ++t)
    loaders.emplace_back([&, t] {
      start.arrive_and_wait();
      link.source->read(kOffset, got[t].data(), kLength);
    });
  loaders.clear();
  for (int t = 0; t < kThreads; ++t) EXPECT_EQ(got[t], link.expected()) << "thread " << t;
  EXPECT_EQ(link.client->counters().refetched, 1u) << "one copy of the wrong size";
  EXPECT_EQ(fs::file_size(copy), kLength);
}

}  // namespace
}  // namespace tessera::collab
