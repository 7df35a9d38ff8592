// The results file of a topology optimization, DIR/results.h5 (HDF5 1.10, plain C API to read it).
//
// Layout (every dataset below exists in every file; n = design variables, K = completed iterations):
//   /                      attributes: format = "hindsight-topology-results", format_version = 2,
//                          configuration (JSON string, the complete Config), completed_iterations = K,
//                          finished (0/1), nx, ny, updates (MMA updates made), objective_scale (psi(x0)),
//                          content_hash (the run state's hash, see Integrity), and in files written
//                          since the MPI configuration check: configuration_fingerprint (see
//                          problems/topopt/run_fingerprint.h; verify recomputes it from configuration)
//                          and ranks (the number of MPI ranks that agreed on it, 1 without MPI)
//   /history/<column>      1-D, K entries, one dataset per column of problems/topopt/history_schema.h
//                          (name, int32 or float64, unit, the checks below), written in its order;
//                          columns marked optional there are absent in older files, which are still read
//   /designs               K x ny x nx: the element densities the model saw in each iteration over ALL
//                          elements (solid end columns = 1); designs[k][row][column], row 0 at the
//                          bottom of the rod, column 0 at joint A
//   /state/design          n: the design variables of the next iteration (x_updates)
//   /state/mma_xold1, mma_xold2, mma_low, mma_upp   n each; attribute mma_iteration: the MMA state
//   /state/end_game        2: MMA's move limit and the objective at mma_xold1 (NaN when that design
//                          was infeasible); absent in older files (read as 0 and NaN)
//   /state/end_game_refining  1: 1 once the optimizer's end game refines (OptimizerState::refining), else
//                          0; absent in files written before the end game (read as 0)
//   /final/modes           modeCount x dofCount, row k = mode k on all DOFs (fe_model.h DOF order), and
//   /final/frequencies_hz  modeCount; both of the final design, empty (0 rows) until finished = 1
//   /scenarios/psi1, psi2  K x S: every scenario's psi per iteration (only in runs with scenarios,
//                          problems/rod/scenarios.h; the history's psi1/psi2 are then the worst one's)
//   /scenarios/objective_scale  S: psi_s(x0);  /scenarios/bound  4 (aggregate max: MMA's xold1,
//                          xold2, low, upp of the bound variable z) or 0
// Every dataset is float64 (int32 where said), chunked with an unlimited first dimension, and carries
// HDF5's Fletcher32 filter and an attribute content_hash.
//
// Integrity (format_version 2; docs/design.md §7). Two checksums, for two kinds of damage:
//   - Fletcher32 (HDF5's filter, per chunk) over the stored bytes: HDF5 refuses to read a chunk whose
//     bytes changed on disk (bit rot, a torn sector, a raw overwrite), naming the dataset.
//   - content_hash = "fnv1a64:<16 hex digits>", FNV-1a 64 (engine/hash.h) over the dataset's path, its
//     dimensions and its values as stored (little-endian float64 / int32), on every dataset; and on
//     the root the run state's hash: the attributes above (configuration, counters, mma_iteration)
//     and every dataset's hash. It catches what Fletcher32 cannot: values rewritten through HDF5
//     (h5py, the C API), which recomputes Fletcher32, and changed attributes, which have no filter.
//   It detects corruption, not tampering: anyone can recompute both. Reading recomputes every hash;
//   then the restored state is checked for plausibility: every history column as its schema says
//   (range, NaN allowed or not, iteration = row index), every other value finite, designs and design
//   variables in [rod.designLowerBound, 1], the MMA state as MMA leaves it (after an update mma_low <
//   mma_xold1 < mma_upp and mma_low < design < mma_upp), the counters consistent. Any failure names the
//   dataset.
// Format 1 files (before checksums) are still read: plausibility is checked, the hashes cannot be;
// ResultsData::checksummed says which, and the next write adds the checksums.
//
// Crash safety (the design this file is built on): writeResultsFile never modifies an existing file.
// It builds the file in memory (hdf5::createMemoryFile: a full disk is then an ordinary failed write,
// not a failed H5Fclose), writes the image to a temporary PATH.tmp-PID-N, fsyncs it, renames it onto
// PATH (atomic on POSIX) and fsyncs the directory (storage/atomic_file.h). So at every moment PATH is
// either absent or a complete file written by a finished call: a crash (kill -9, power loss after the
// rename) leaves the file of the last completed iteration, never a torn one; a leftover temporary is
// garbage and is removed by the next run (removeStaleTemporariesIn). Cost: the whole file is rewritten
// per iteration, O(K (nx ny + n)) bytes; for the 200 x 12 rod that is 20 kB per completed iteration,
// milliseconds next to a 2 s evaluation.
//
// Errors: StorageError (with the path) when the file cannot be written, read, is not such a file, or
// fails a check above (naming the dataset).
#pragma once

#include <hindsight/problems/topopt/topology_optimizer.h>

#include <string>
#include <vector>

namespace hindsight {

struct ResultsData {
  std::string configurationJson;
  /// configurationFingerprint(configurationJson) as the ranks agreed on it, and their number; empty
  /// and 0 in files written before they were stored (not written then, not checked when read).
  std::string configurationFingerprint;
  int ranks = 0;
  int nx = 0;
  int ny = 0;
  std::vector<IterationRecord> history;  ///< completed iterations, in order
  std::vector<Vector> densities;         ///< one nx * ny grid (row * nx + column) per history entry
  OptimizerState state;                  ///< the optimizer after the last completed iteration
  bool finished = false;                 ///< the last history entry is the final design's evaluation
  Matrix finalModes;                     ///< dofCount x modeCount when finished, else empty
  std::vector<double> finalFrequenciesHz;
  /// Set by readResultsFile: the file had checksums (format 2) and they matched; false for a format 1
  /// file, whose contents could only be checked for plausibility.
  bool checksummed = false;
};

/// The outcome of checking one object of a results file.
struct ResultsCheck {
  std::string object;   ///< "/state/mma_low", or "/" for the root attributes
  std::string problem;  ///< empty: sound
};

/// Every check of a results file, in file order.
struct ResultsVerification {
  int formatVersion = 0;
  bool checksummed = false;  ///< format 2: hashes and Fletcher32 were checked, not only plausibility
  int completedIterations = 0;
  bool finished = false;
  std::string configurationFingerprint;  ///< empty in older files
  int ranks = 0;
  std::vector<ResultsCheck> checks;
  /// The first failed check, or nullptr when the file is sound.
  const ResultsCheck* firstProblem() const;
};

/// Writes `data` atomically to `path` as described above. Throws std::invalid_argument when the
/// data are inconsistent (sizes), StorageError when the file cannot be written.
void writeResultsFile(const std::string& path, const ResultsData& data);

/// Reads a file written by writeResultsFile and checks it (Integrity above). Throws StorageError
/// naming the path when it cannot be opened, is not a hindsight results file, or fails a check (the
/// message names the dataset).
ResultsData readResultsFile(const std::string& path);

/// Runs every check of readResultsFile and reports each object instead of stopping at the first
/// problem. Throws StorageError only when the file cannot be opened or is not a results file.
ResultsVerification verifyResultsFile(const std::string& path);

/// The configuration JSON stored in a results file, after all checks (StorageError as
/// readResultsFile): a run resumed from it must not start from a corrupted configuration.
std::string readResultsConfiguration(const std::string& path);

}  // namespace hindsight
