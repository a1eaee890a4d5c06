// Worker threads (core/parallel.h) and JSON string literals (core/json_string.h).
#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include <tessera/core/json_string.h>
#include <tessera/core/parallel.h>

namespace tessera {
namespace {

TEST(Parallel, ThreadCountIsTheRequestOrTheHardwares) {
  EXPECT_EQ(threadCount(3), 3u);
  EXPECT_EQ(threadCount(0), std::max(1u, std::thread::hardware_concurrency()));
  EXPECT_EQ(threadCount(-2), std::max(1u, std::thread::hardware_concurrency()));
}

TEST(Parallel, EveryItemRunsOnceOnAnyNumberOfWorkers) {
  for (unsigned workers : {1u, 2u, 7u, 64u}) {
    for (size_t n : {size_t(0), size_t(1), size_t(5), size_t(10000)}) {
      std::vector<std::atomic<int>> seen(n);
      parallelFor(n, workers, [&](size_t i) { ++seen[i]; });
      for (size_t i = 0; i < n; ++i) ASSERT_EQ(seen[i].load(), 1) << workers << " " << n << " " << i;
    }
  }
}

TEST(Parallel, EachWorkerRunsOnceWithItsOwnIndex) {
  std::vector<std::atomic<int>> ran(5);
  runWorkers(5, [&](unsigned w) { ++ran.at(w); });
  for (auto& r : ran) EXPECT_EQ(r.load(), 1);
}

TEST(Parallel, TheFirstFailureStopsNewItemsAndReachesTheCaller) {
  std::atomic<size_t> ran{0};
  try {
    parallelFor(100000, 4, [&](size_t i) {
      ++ran;
      if (i == 10) throw std::runtime_error("item 10 failed");
    });
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "item 10 failed");
  }
  EXPECT_LT(ran.load(), size_t(100000));  // the rest was not handed out
  // A worker's exception in runWorkers waits for the others, then reaches the caller.
  std::atomic<int> finished{0};
  EXPECT_THROW(runWorkers(3,
                          [&](unsigned w) {
                            if (w == 1) throw std::logic_error("worker 1");
                            ++finished;
                          }),
               std::logic_error);
  EXPECT_EQ(finished.load(), 2);
}

TEST(JsonString, EscapesQuotesBackslashesAndControlsAndKeepsUtf8) {
  EXPECT_EQ(jsonString(""), "\"\"");
  EXPECT_EQ(jsonString("a\"b\\c"), "\"a\\\"b\\\\c\"");
  EXPECT_EQ(jsonString("l1\nl2\r\t"), "\"l1\\nl2\\r\\t\"");
  EXPECT_EQ(jsonString(std::string("\x01\x1f\x7f", 3)), "\"\\u0001\\u001f\\u007f\"");
  EXPECT_EQ(jsonString("東京 🐇"), "\"東京 🐇\"");
  std::string out = "[";
  appendJsonString(out, "x");
  EXPECT_EQ(out, "[\"x\"");
}

}  // namespace
}  // namespace tessera
