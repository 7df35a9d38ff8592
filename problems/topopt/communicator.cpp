#include <hindsight/problems/topopt/communicator.h>

#include <cstdlib>
#include <stdexcept>
#include <string>

#ifdef HINDSIGHT_HAVE_MPI
// The C API only: OpenMPI would otherwise pull in its deprecated C++ bindings.
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#endif

namespace hindsight {
namespace {

#ifdef HINDSIGHT_HAVE_MPI
bool mpiRunning() {
  int initialised = 0;
  int finalised = 0;
  MPI_Initialized(&initialised);
  MPI_Finalized(&finalised);
  return initialised != 0 && finalised == 0;
}

void check(int code, const char* what) {
  if (code != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}
#endif

[[maybe_unused]] bool startedByLauncher() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_RANK", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS"}) {
    if (std::getenv(name) != nullptr) return true;
  }
  return false;
}

}  // namespace

bool mpiSupported() {
#ifdef HINDSIGHT_HAVE_MPI
  return true;
#else
  return false;
#endif
}

const Communicator& Communicator::world() {
#ifdef HINDSIGHT_HAVE_MPI
  if (mpiRunning()) {
    static const Communicator world = [] {
      int rank = 0;
      int size = 1;
      MPI_Comm_rank(MPI_COMM_WORLD, &rank);
      MPI_Comm_size(MPI_COMM_WORLD, &size);
      return Communicator(rank, size);
    }();
    return world;
  }
#endif
  static const Communicator alone(0, 1);
  return alone;
}

std::vector<double> Communicator::allGather(const std::vector<double>& mine) const {
  if (size_ == 1) return mine;
#ifdef HINDSIGHT_HAVE_MPI
  std::vector<int> counts(static_cast<std::size_t>(size_));
  const int count = static_cast<int>(mine.size());
  check(MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD), "MPI_Allgather");
  std::vector<int> offsets(static_cast<std::size_t>(size_), 0);
  for (int r = 1; r < size_; ++r) offsets[r] = offsets[r - 1] + counts[r - 1];
  std::vector<double> all(static_cast<std::size_t>(offsets.back() + counts.back()));
  check(MPI_Allgatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), offsets.data(), MPI_DOUBLE,
                       MPI_COMM_WORLD),
        "MPI_Allgatherv");
  return all;
#else
  return mine;
#endif
}

int Communicator::maxOverRanks(int value) const {
  if (size_ == 1) return value;
#ifdef HINDSIGHT_HAVE_MPI
  int result = value;
  check(MPI_Allreduce(&value, &result, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD), "MPI_Allreduce");
  return result;
#else
  return value;
#endif
}

void Communicator::agree(const std::exception_ptr& error) const {
  // The lowest failed rank is named: each rank proposes (size - rank) when it failed.
  const int proposal = error ? size_ - rank_ : 0;
  const int agreed = maxOverRanks(proposal);
  if (error) std::rethrow_exception(error);
  if (agreed > 0) {
    throw std::runtime_error("stopped because rank " + std::to_string(size_ - agreed) +
                             " failed (that rank reports the error)");
  }
}

MpiSession::MpiSession(int& argc, char**& argv) {
#ifdef HINDSIGHT_HAVE_MPI
  if (startedByLauncher() && !mpiRunning()) {
    int provided = 0;
    // Only the main thread calls MPI; TBB's worker threads never do.
    if (MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided) == MPI_SUCCESS) initialised_ = true;
  }
#else
  (void)argc;
  (void)argv;
#endif
}

MpiSession::~MpiSession() {
#ifdef HINDSIGHT_HAVE_MPI
  if (initialised_ && mpiRunning()) MPI_Finalize();
#endif
}

void MpiSession::abortAll(int code) {
#ifdef HINDSIGHT_HAVE_MPI
  if (mpiRunning() && Communicator::world().parallel()) MPI_Abort(MPI_COMM_WORLD, code);
#else
  (void)code;
#endif
}

}  // namespace hindsight
