// A complete, restartable topology-optimization run of the piston rod in an output directory: the
// TopologyOptimizer loop, DIR/results.h5 after every iteration (problems/topopt/results_file.h, crash-safe),
// a progress line per iteration, and pictures (DIR/design_iter_K.png/.vtk every
// optimization.pictureEvery iterations, DIR/design_final.png/.vtk at the end) and the final design's
// geometry (DIR/design_final.svg/.dxf/.stl, the contour at density 0.5; problems/topopt/geometry_export.h).
//
// Every input check happens in the constructor, before any evaluation: the configuration (field named),
// --resume together with --force, an output directory that cannot be created or written (probed by
// writing a file), existing results without resume or force, and on resume a stored configuration
// that differs from the requested one in anything but optimization.iterations and
// optimization.pictureEvery, or fewer iterations than already completed. Those throw
// std::invalid_argument; an unreadable results file on resume throws StorageError.
//
// The output directory is locked for the run's lifetime (storage/directory_lock.h): a second run into
// the same directory is refused at once with std::invalid_argument naming the directory and the
// holder's PID. With the lock taken, temporary files of dead processes' atomic writes there (results
// file and pictures, NAME.tmp-PID-N) are removed.
//
// Resume: the results file is read with all its checks (problems/topopt/results_file.h: checksums,
// plausibility of the restored design and MMA state); a file that fails one throws StorageError
// naming the dataset, and nothing runs. A format 1 file (no checksums) is resumed after the
// plausibility checks with a warning in the progress output that it could not be verified.
// The optimizer continues from the stored state after the last completed iteration, so the
// history and designs of a resumed run equal those of an uninterrupted run bit for bit (the seconds
// columns excepted). A finished run resumed with more iterations drops its final evaluation (which
// made no update) and continues from there, exactly as a run started with the larger count.
#pragma once

#include <hindsight/problems/topopt/results_file.h>
#include <hindsight/problems/topopt/topology_optimizer.h>
#include <hindsight/storage/directory_lock.h>

#include <functional>
#include <iosfwd>
#include <memory>
#include <string>

namespace hindsight {

struct OptimizationRunOptions {
  std::string outputDirectory = "results";
  bool resume = false;  ///< continue DIR/results.h5 (a fresh run when there is none)
  bool force = false;   ///< overwrite DIR/results.h5
  int pixelsPerElement = 4;
  /// Called after every iteration once its results are safely on disk (tests use it to crash).
  std::function<void(const IterationRecord&)> afterCommit;
};

struct OptimizationRunSummary {
  std::vector<IterationRecord> history;  ///< the whole history, stored and new
  int resumedFrom = 0;                   ///< iterations taken over from the results file
  bool finished = false;
  double wallSeconds = 0.0;  ///< of this invocation
  std::string resultsPath;
};

class OptimizationRun {
 public:
  /// Checks all inputs (see above) and prepares the output directory; makes no evaluation.
  OptimizationRun(const Config& config, const OptimizationRunOptions& options);

  const std::string& resultsPath() const { return resultsPath_; }
  const TopologyOptimizer& optimizer() const { return optimizer_; }
  /// Number of iterations found in the results file (0 for a fresh run).
  int resumedIterations() const { return static_cast<int>(data_.history.size()); }

  /// Runs to the end, writing one progress line per iteration to `progress`.
  OptimizationRunSummary run(std::ostream& progress);

 private:
  void writePictures(const std::string& stem, const Vector& grid) const;

  Config config_;
  OptimizationRunOptions options_;
  std::unique_ptr<DirectoryLock> lock_;     // held from the constructor until the run is destroyed
  bool resumedUnverified_ = false;          // resumed from a format 1 file (no checksums)
  bool root_ = true;                        // rank 0 (or the only process): writes the directory
  std::vector<std::string> scenarioNames_;  // empty without scenarios
  std::string resultsPath_;
  ResultsData data_;
  TopologyOptimizer optimizer_;
};

/// Index in `history` of the best feasible design: the lowest optimized objective (psi1 or psi2 per
/// optimization.objective; with scenarios the aggregate of w_s psi_s / psi_s(x0), psi_s(x0) from the
/// first record) among the feasible records (TopologyOptimizer::feasible of the record's constraints:
/// the volume bound and, when on, the frequency guard, within TopologyOptimizer::kFeasibilitySlack, the
/// stopping rule's test). -1 when no record is feasible.
int bestFeasibleIndex(const std::vector<IterationRecord>& history, const Config& config);

/// The progress line of one iteration, e.g.
/// "iter  12  psi1 0.0812  psi2 0.0795  V/V0 0.5000  max|dx| 0.113  2.4 s". With scenarios, psi1 and
/// psi2 are the worst scenario's, named at the end ("worst: fast").
std::string progressLine(const IterationRecord& record, const std::vector<std::string>& scenarioNames = {});

}  // namespace hindsight
