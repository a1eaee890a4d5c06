#include <tessera/core/parallel.h>

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace tessera {

unsigned threadCount(int requested) {
  if (requested > 0) return unsigned(requested);
  return std::max(1u, std::thread::hardware_concurrency());
}

void runWorkers(unsigned workers, const std::function<void(unsigned worker)>& work) {
  workers = std::max(1u, workers);
  std::mutex failure_mutex;
  std::exception_ptr failure;
  auto guarded = [&](unsigned worker) {
    try {
      work(worker);
    } catch (...) {
      std::lock_guard lock(failure_mutex);
      if (!failure) failure = std::current_exception();
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(workers - 1);
  try {
    for (unsigned w = 1; w < workers; ++w) pool.emplace_back(guarded, w);
  } catch (const std::system_error&) {
    // No more threads: the ones started share the work. (A joinable std::thread destroyed
    // during unwinding would call std::terminate.)
  }
  guarded(0);
  for (std::thread& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
}

void parallelFor(size_t n, unsigned workers, const std::function<void(size_t i)>& f) {
  if (n == 0) return;
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  runWorkers(unsigned(std::min<size_t>(std::max(1u, workers), n)), [&](unsigned) {
    try {
      for (size_t i; !failed.load(std::memory_order_relaxed) && (i = next++) < n;) f(i);
    } catch (...) {
      failed = true;
      throw;
    }
  });
}

}  // namespace tessera
