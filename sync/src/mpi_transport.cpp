#include <tessera/sync/mpi_transport.h>

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <thread>

#include <tessera/core/check.h>
#include <tessera/core/stopwatch.h>

namespace tessera::sync {

namespace {

using Clock = std::chrono::steady_clock;

/// A wait's time limit that does not count time this process did not run: a rank stopped
/// (SIGSTOP, a debugger) and continued must not blame the others for its own pause.
class Budget {
 public:
  explicit Budget(double timeout_s) : mTimeoutS(timeout_s) {}

  /// Written so that a NaN timeout ends the wait, never waits forever.
  bool expired() {
    const auto now = Clock::now();
    const double gap_s = std::chrono::duration<double>(now - mLast).count();
    if (gap_s > kPauseS) mPausedS += gap_s;  // polls are 0.2 ms apart: this process was stopped
    mLast = now;
    return !(std::chrono::duration<double>(now - mStart).count() - mPausedS <= mTimeoutS);
  }

  /// Between polls: MPI's own blocking waits spin, which on an oversubscribed machine takes the
  /// core from the rank being waited for.
  void pause() const {
    std::this_thread::sleep_for(std::chrono::microseconds(msSince(mStart) < 1.0 ? 20 : 200));
  }

 private:
  static constexpr double kPauseS = 1.0;
  const Clock::time_point mStart = Clock::now();
  Clock::time_point mLast = mStart;
  double mTimeoutS = 0, mPausedS = 0;
};

}  // namespace

struct MpiTransport::Send {
  std::shared_ptr<const std::string> bytes;
  int to = 0;
  MPI_Request request = MPI_REQUEST_NULL;
};

// Held by unique_ptr from MPI_Imrecv to its end: the string MPI writes into never moves.
struct MpiTransport::Buffer {
  std::string bytes;
  MPI_Request request = MPI_REQUEST_NULL;
};

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

void MpiTransport::check(int mpi_result, const char* doing, const char* what) const {
  if (mpi_result == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING] = {};
  int len = 0;
  MPI_Error_string(mpi_result, text, &len);
  abort(kExitMpiFailed, std::string("MPI failed ") + doing + " (" + what + "): " + text);
}

void MpiTransport::post(int to, int tag, std::shared_ptr<const std::string> bytes,
                        const char* what) {
  TESSERA_CHECK(to >= 0 && to < mSize && to != mRank && bytes, "post() to another rank");
  if (bytes->size() > size_t(INT_MAX))
    abort(1, std::string(what) + ": " + std::to_string(bytes->size()) +
                 " bytes are over MPI's 2 GiB count limit");
  auto send = std::make_unique<Send>();
  send->bytes = std::move(bytes);
  send->to = to;
  check(MPI_Isend(send->bytes->data(), int(send->bytes->size()), MPI_BYTE, to, tag, MPI_COMM_WORLD,
                  &send->request),
        "sending", what);
  mSends.push_back(std::move(send));
}

bool MpiTransport::progressSends(const char* what) {
  for (size_t i = 0; i < mSends.size();) {
    int done = 0;
    check(MPI_Test(&mSends[i]->request, &done, MPI_STATUS_IGNORE), "sending", what);
    if (done) {
      mSends.erase(mSends.begin() + std::ptrdiff_t(i));
    } else {
      ++i;
    }
  }
  return mSends.empty();
}

std::vector<int> MpiTransport::flush(double timeout_s, const char* what) {
  Budget budget(timeout_s);
  while (!progressSends(what) && !budget.expired()) budget.pause();
  std::vector<int> late;
  for (const auto& s : mSends) late.push_back(s->to);
  std::sort(late.begin(), late.end());
  late.erase(std::unique(late.begin(), late.end()), late.end());
  return late;
}

std::vector<std::optional<std::string>> MpiTransport::receiveEach(const std::vector<int>& from,
                                                                  int tag, double timeout_s,
                                                                  const char* what) {
  std::vector<std::optional<std::string>> out(from.size());
  // A message is matched (MPI_Improbe, which tells its size), then received into a buffer of
  // that size (MPI_Imrecv): no rank's message can be taken by another's receive.
  std::vector<std::unique_ptr<Buffer>> incoming(from.size());
  size_t left = from.size();
  Budget budget(timeout_s);
  while (true) {
    for (size_t i = 0; i < from.size(); ++i) {
      if (out[i]) continue;
      if (!incoming[i]) {
        int found = 0;
        MPI_Message message;
        MPI_Status status;
        check(MPI_Improbe(from[i], tag, MPI_COMM_WORLD, &found, &message, &status), "receiving",
              what);
        if (!found) continue;
        int count = 0;
        MPI_Get_count(&status, MPI_BYTE, &count);
        incoming[i] = std::make_unique<Buffer>();
        incoming[i]->bytes.resize(size_t(std::max(count, 0)));
        check(
            MPI_Imrecv(incoming[i]->bytes.data(), count, MPI_BYTE, &message, &incoming[i]->request),
            "receiving", what);
      }
      int done = 0;
      check(MPI_Test(&incoming[i]->request, &done, MPI_STATUS_IGNORE), "receiving", what);
      if (!done) continue;
      out[i] = std::move(incoming[i]->bytes);
      incoming[i].reset();
      --left;
    }
    progressSends(what);
    if (left == 0 || budget.expired()) break;
    budget.pause();
  }
  for (auto& b : incoming)
    if (b) mAbandoned.push_back(std::move(b));
  return out;
}

}  // namespace tessera::sync
