// Threads for the CPU-heavy loops (store builds, verification, virtual scans, lassos): one
// thread count rule and one way to run workers, so no loop starts its own pool.
#pragma once

#include <cstddef>
#include <functional>

namespace tessera {

/// Workers to use: `requested` when it is above 0, else the hardware's threads (at least 1).
unsigned threadCount(int requested = 0);

/// Runs `work(worker)` once on each of `workers` workers, worker 0 on the calling thread, and
/// returns when all have finished. When the system refuses to start a thread, the workers that
/// did start are all there is (so `work` must share its items through a counter, not assume
/// `workers` of them). The first exception a worker throws is rethrown here after every worker
/// has finished; the others are not interrupted (use parallelFor() to stop handing out items).
void runWorkers(unsigned workers, const std::function<void(unsigned worker)>& work);

/// Calls `f(i)` for every i in [0, n), each once, on up to `workers` workers taking items from
/// a shared counter. After the first exception no new item starts; it is rethrown here when
/// every worker has stopped.
void parallelFor(size_t n, unsigned workers, const std::function<void(size_t i)>& f);

}  // namespace tessera
