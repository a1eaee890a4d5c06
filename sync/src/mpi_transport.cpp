#include <tessera/sync/mpi_transport.h>

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <thread>

#include <tessera/core/check.h>
#include <tessera/core/stopwatch.h>

namespace tessera::sync {

namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

MpiTransport::MpiTransport(int* argc, char*** argv, std::string who, double timeout_s)
    : mWho(std::move(who)) {
  setTimeout(timeout_s);
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (!initialized && MPI_Init(argc, argv) != MPI_SUCCESS)
    throw TransportError(mWho + ": MPI_Init failed (start it with mpirun)");
  // Errors come back as codes; a broken communicator then aborts through abort() with a message.
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  MPI_Comm_rank(MPI_COMM_WORLD, &mRank);
  MPI_Comm_size(MPI_COMM_WORLD, &mSize);
  char name[MPI_MAX_PROCESSOR_NAME] = {};
  int len = 0;
  MPI_Get_processor_name(name, &len);
  mHost.assign(name, size_t(len));
}

void MpiTransport::setTimeout(double seconds) {
  TESSERA_CHECK(std::isfinite(seconds) && seconds > 0.0,
                "sync::MpiTransport: the timeout must be a finite number of seconds > 0");
  mTimeoutS = seconds;
}

MpiTransport::~MpiTransport() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

void MpiTransport::abort(int code, const std::string& why) const {
  std::fprintf(stderr, "%s (rank %d on %s): %s\n", mWho.c_str(), mRank, mHost.c_str(), why.c_str());
  std::fflush(stderr);
  MPI_Abort(MPI_COMM_WORLD, code);
  std::_Exit(code);  // MPI_Abort does not return; this keeps [[noreturn]] honest
}

void MpiTransport::wait(void* request_ptr, const char* what) {
  auto* request = static_cast<MPI_Request*>(request_ptr);
  const auto start = Clock::now();
  // Poll, then sleep a little between polls: MPI's own blocking waits spin, which on an
  // oversubscribed machine takes the core from the rank being waited for.
  for (int polls = 0;; ++polls) {
    int done = 0;
    if (MPI_Test(request, &done, MPI_STATUS_IGNORE) != MPI_SUCCESS)
      abort(3, std::string("MPI failed while waiting for ") + what);
    if (done) return;
    const double ms = msSince(start);
    if (!(ms <= mTimeoutS * 1000.0)) {  // written so that a NaN timeout aborts, never waits
      char why[256];
      std::snprintf(why, sizeof why, "no %s after %.0f s (a rank hung or died); aborting the job",
                    what, mTimeoutS);
      abort(4, why);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(ms < 1.0 ? 20 : 200));
  }
}

uint64_t MpiTransport::broadcast(std::string& bytes, const char* what) {
  uint64_t size = mRank == 0 ? bytes.size() : 0;
  MPI_Request request;
  MPI_Ibcast(&size, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD, &request);
  wait(&request, what);
  if (size > uint64_t(INT32_MAX))
    abort(5, std::string("a broadcast of ") + std::to_string(size) +
                 " bytes is over MPI's 2 GiB count limit");
  if (mRank != 0) bytes.resize(size);
  if (size == 0) return sizeof size;
  MPI_Ibcast(bytes.data(), int(size), MPI_BYTE, 0, MPI_COMM_WORLD, &request);
  wait(&request, what);
  return sizeof size + size;
}

double MpiTransport::swapBarrier() {
  const auto start = Clock::now();
  MPI_Request request;
  MPI_Ibarrier(MPI_COMM_WORLD, &request);
  wait(&request, "swap barrier (a rank did not finish its frame)");
  return msSince(start);
}

std::vector<std::string> MpiTransport::gatherBytes(std::string_view mine, const char* what) {
  if (mine.size() > size_t(INT32_MAX))
    abort(5, std::string(what) + ": " + std::to_string(mine.size()) +
                 " bytes are over MPI's 2 GiB limit");
  const int my_count = int(mine.size());
  std::vector<int> counts(mRank == 0 ? size_t(mSize) : 0);
  MPI_Request request;
  MPI_Igather(&my_count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD, &request);
  wait(&request, what);
  std::vector<int> displs(counts.size(), 0);
  std::vector<char> all;
  if (mRank == 0) {
    int64_t total = 0;
    for (size_t i = 0; i < counts.size(); ++i) {
      displs[i] = int(total);
      total += counts[i];
      if (total > int64_t(INT32_MAX)) abort(5, std::string(what) + ": over MPI's 2 GiB limit");
    }
    all.resize(size_t(total));
  }
  MPI_Igatherv(mine.data(), my_count, MPI_BYTE, all.data(), counts.data(), displs.data(), MPI_BYTE,
               0, MPI_COMM_WORLD, &request);
  wait(&request, what);
  std::vector<std::string> parts;
  for (size_t i = 0; i < counts.size(); ++i)
    parts.emplace_back(all.data() + displs[i], size_t(counts[i]));
  return parts;
}

std::string MpiTransport::scatterBytes(const std::vector<std::string>& parts, const char* what) {
  std::vector<int> counts, displs;
  std::string all;
  if (mRank == 0) {
    TESSERA_CHECK(parts.size() == size_t(mSize), "one part per rank");
    for (const std::string& p : parts) {
      if (all.size() + p.size() > size_t(INT32_MAX))
        abort(5, std::string(what) + ": over MPI's 2 GiB limit");
      counts.push_back(int(p.size()));
      displs.push_back(int(all.size()));
      all += p;
    }
  }
  int my_count = 0;
  MPI_Request request;
  MPI_Iscatter(counts.data(), 1, MPI_INT, &my_count, 1, MPI_INT, 0, MPI_COMM_WORLD, &request);
  wait(&request, what);
  std::string mine(size_t(my_count), '\0');
  MPI_Iscatterv(all.data(), counts.data(), displs.data(), MPI_BYTE, mine.data(), my_count, MPI_BYTE,
                0, MPI_COMM_WORLD, &request);
  wait(&request, what);
  return mine;
}

}  // namespace tessera::sync
