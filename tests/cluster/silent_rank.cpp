// A rank of an MPI job that starts MPI and then says nothing, as a render node stuck before its
// join would (tests/cluster/mpi_failure_test.cpp): the master must name it and end the job.
// Bounded: if nobody ends the job, it leaves by itself after argv[1] seconds (default 60), with
// exit code 99, never hanging a test run.
#include <mpi.h>

#include <chrono>
#include <cstdlib>
#include <thread>

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  const double limit_s = argc > 1 ? std::atof(argv[1]) : 60.0;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(limit_s);
  while (std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::_Exit(99);  // no MPI_Finalize: the master never got a word from this rank
}
