// The METIS worker pool (lod/src/metis_pool.h): the same parts as METIS in this process, from
// any number of threads at once; a dead worker is an exception, never a hang; no zombies left.
#include <gtest/gtest.h>

#include <signal.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <functional>
#include <future>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "../../lod/src/metis_pool.h"

namespace tessera::lod {
namespace {

/// A side x side grid graph in CSR (4-neighbours), with vertex and edge weights that vary, so a
/// partition of it has choices to make and the seed matters.
struct Grid {
  std::vector<idx_t> xadj{0}, adjncy, vwgt, adjwgt;
  explicit Grid(int side) {
    for (int y = 0; y < side; ++y)
      for (int x = 0; x < side; ++x) {
        const int v = y * side + x;
        for (const auto& [dx, dy] : {std::pair{-1, 0}, {1, 0}, {0, -1}, {0, 1}}) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= side || ny >= side) continue;
          const int u = ny * side + nx;
          adjncy.push_back(u);
          adjwgt.push_back(1 + (std::min(u, v) * 7 + std::max(u, v)) % 5);  // symmetric
        }
        xadj.push_back(idx_t(adjncy.size()));
        vwgt.push_back(1 + v % 3);
      }
  }
};

constexpr int kSide = 64;  // 4096 vertices: beyond MetisPool::kInProcessBelow
static_assert(kSide * kSide >= MetisPool::kInProcessBelow);

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(no exception)";
}

/// Reaped: no such process (a zombie would still answer kill(pid, 0)).
bool reaped(pid_t pid) {
  return ::kill(pid, 0) != 0 && errno == ESRCH;
}

TEST(MetisPool, WorkersPartitionAsThisProcessDoesFromManyThreads) {
  const Grid g(kSide);
  MetisPool local(0);
  std::vector<std::vector<idx_t>> want(4);
  for (int k = 0; k < 4; ++k) {  // plain and weighted, two seeds
    const bool weights = k % 2;
    ASSERT_EQ(local.partGraphKway(g.xadj, g.adjncy, weights ? &g.vwgt : nullptr,
                                  weights ? &g.adjwgt : nullptr, 16, 42 + k / 2, want[size_t(k)]),
              METIS_OK);
  }
  EXPECT_NE(want[0], want[2]) << "the seed should matter on this graph";

  std::vector<pid_t> pids;
  {
    MetisPool pool(2);
    pids = pool.pids();
    ASSERT_EQ(pids.size(), 2u);
    std::vector<std::thread> threads;
    std::vector<int> mismatches(6, 0);
    for (size_t t = 0; t < mismatches.size(); ++t)  // more callers than workers: they wait
      threads.emplace_back([&, t] {
        for (int round = 0; round < 3; ++round)
          for (int k = 0; k < 4; ++k) {
            const bool weights = k % 2;
            std::vector<idx_t> part;
            const int rc = pool.partGraphKway(g.xadj, g.adjncy, weights ? &g.vwgt : nullptr,
                                              weights ? &g.adjwgt : nullptr, 16, 42 + k / 2, part);
            mismatches[t] += rc != METIS_OK || part != want[size_t(k)];
          }
      });
    for (std::thread& t : threads) t.join();
    for (size_t t = 0; t < mismatches.size(); ++t) EXPECT_EQ(mismatches[t], 0) << "thread " << t;
  }
  for (pid_t pid : pids) EXPECT_TRUE(reaped(pid)) << "worker " << pid << " left behind";
}

TEST(MetisPool, AKilledWorkerIsAnErrorNotAHang) {
  const Grid g(kSide);
  std::vector<idx_t> part;
  std::vector<pid_t> pids;
  {
    MetisPool pool(2);
    pids = pool.pids();
    // Killed between calls: the next call to it finds its socket closed.
    ASSERT_EQ(::kill(pids[0], SIGKILL), 0);
    const std::string first =
        errorOf([&] { pool.partGraphKway(g.xadj, g.adjncy, nullptr, nullptr, 8, 42, part); });
    EXPECT_NE(first.find("partition worker 0 (pid " + std::to_string(pids[0]) + ")"),
              std::string::npos)
        << first;
    EXPECT_NE(first.find("killed by signal 9"), std::string::npos) << first;
    // The other worker still serves.
    EXPECT_EQ(pool.partGraphKway(g.xadj, g.adjncy, nullptr, nullptr, 8, 42, part), METIS_OK);
    // Killed during a call: stopped first, so the call is under way when it dies.
    ASSERT_EQ(::kill(pids[1], SIGSTOP), 0);
    auto call = std::async(std::launch::async, [&] {
      return errorOf([&] { pool.partGraphKway(g.xadj, g.adjncy, nullptr, nullptr, 8, 42, part); });
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ASSERT_EQ(::kill(pids[1], SIGKILL), 0);
    ASSERT_EQ(call.wait_for(std::chrono::seconds(30)), std::future_status::ready) << "hung";
    const std::string second = call.get();
    EXPECT_NE(second.find("partition worker 1"), std::string::npos) << second;
    EXPECT_NE(second.find("died during a call"), std::string::npos) << second;
    // None left: every call throws at once.
    EXPECT_NE(errorOf([&] {
                pool.partGraphKway(g.xadj, g.adjncy, nullptr, nullptr, 8, 42, part);
              }).find("every partition worker died"),
              std::string::npos);
    // Small graphs still run in this process.
    const Grid small(8);
    EXPECT_EQ(pool.partGraphKway(small.xadj, small.adjncy, nullptr, nullptr, 4, 42, part),
              METIS_OK);
  }
  for (pid_t pid : pids) EXPECT_TRUE(reaped(pid)) << "worker " << pid << " left behind";
}

}  // namespace
}  // namespace tessera::lod
