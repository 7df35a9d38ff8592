// The processes of one run: MPI ranks when the program was started by an MPI launcher
// (mpirun / mpiexec) and hindsight was built with HINDSIGHT_MPI, otherwise one process on its own.
// The optimizer uses only the two collective operations below; everything else (which rank owns a
// scenario, in which order results are combined) is fixed arithmetic on rank and size, so a run's
// numbers do not depend on the number of ranks (problems/topopt/scenario_objective.h).
//
// This file is the only one that includes <mpi.h>; without MPI it compiles to the one-process case.
#pragma once

#include <exception>
#include <string>
#include <vector>

namespace hindsight {

class Communicator {
 public:
  /// The processes of this run: MPI_COMM_WORLD when MPI is initialised (MpiSession), else one.
  static const Communicator& world();

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool isRoot() const { return rank_ == 0; }
  /// True when more than one process takes part.
  bool parallel() const { return size_ > 1; }

  /// Every rank contributes `mine` (counts may differ between ranks); every rank receives all
  /// contributions concatenated in rank order. One process: returns `mine`.
  std::vector<double> allGather(const std::vector<double>& mine) const;
  /// The largest of every rank's `value`.
  int maxOverRanks(int value) const;
  /// Collective agreement on a step that may fail on some ranks (input checks, writing results):
  /// every rank calls it with its own outcome. When any rank failed, every rank throws -- a failed
  /// rank its own exception, the others std::runtime_error saying which rank failed -- so no rank
  /// is left waiting in a later collective. One process: rethrows `error` if set.
  void agree(const std::exception_ptr& error) const;

  Communicator(int rank, int size) : rank_(rank), size_(size) {}

 private:
  int rank_ = 0;
  int size_ = 1;
};

/// Initialises MPI for the process's lifetime when it was started by an MPI launcher (the
/// launcher's environment, e.g. OMPI_COMM_WORLD_SIZE or PMI_RANK, is present) and hindsight was
/// built with MPI; otherwise does nothing, so the same binary runs alone without mpirun.
class MpiSession {
 public:
  MpiSession(int& argc, char**& argv);
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  /// Ends every rank at once with `code` (MPI_Abort) when MPI runs with several ranks; returns
  /// otherwise. For a rank that cannot continue while others wait in a collective.
  static void abortAll(int code);

 private:
  bool initialised_ = false;
};

/// True when hindsight was built with MPI (HINDSIGHT_MPI=ON and MPI found).
bool mpiSupported();

}  // namespace hindsight
