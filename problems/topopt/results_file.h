// The results file of a topology optimization, DIR/results.h5 (HDF5 1.10, plain C API to read it).
//
// Layout (every dataset below exists in every file; n = design variables, K = completed iterations):
//   /                      attributes: format = "hindsight-topology-results", format_version = 1,
//                          configuration (JSON string, the complete Config), completed_iterations = K,
//                          finished (0/1), nx, ny, updates (MMA updates made), objective_scale (psi(x0))
//   /history/<column>      1-D, K entries, extendible (chunked, unlimited): iteration (int32), psi1, psi2,
//                          backtracks (int32), volume_fraction, max_design_change (NaN for the final
//                          evaluation),
//                          evaluation_seconds, mma_seconds, total_seconds
//   /designs               K x ny x nx, extendible in the first dimension: the element densities the model
//                          saw in each iteration over ALL elements (solid end columns = 1);
//                          designs[k][row][column], row 0 at the bottom of the rod, column 0 at joint A
//   /state/design          n: the design variables of the next iteration (x_updates)
//   /state/mma_xold1, mma_xold2, mma_low, mma_upp   n each; attribute mma_iteration: the MMA state
//   /final/modes           modeCount x dofCount, row k = mode k on all DOFs (fe_model.h DOF order), and
//   /final/frequencies_hz  modeCount; both of the final design, empty (0 rows) until finished = 1
//
// Crash safety (the design this file is built on): writeResultsFile never modifies an existing file.
// It writes the complete contents to a temporary PATH.tmp-PID-N, closes it, fsyncs it, renames it onto
// PATH (atomic on POSIX) and fsyncs the directory (storage/atomic_file.h). So at every moment PATH is
// either absent or a complete file written by a finished call: a crash (kill -9, power loss after the
// rename) leaves the file of the last completed iteration, never a torn one; a leftover temporary is
// garbage and is removed by the next run (removeStaleTemporaries). Cost: the whole file is rewritten
// per iteration, O(K (nx ny + n)) bytes; for the 200 x 12 rod that is 20 kB per completed iteration,
// milliseconds next to a 2 s evaluation.
//
// Errors: StorageError (with the path) when the file cannot be written, read, or is not such a file.
#pragma once

#include <hindsight/problems/topopt/topology_optimizer.h>

#include <string>
#include <vector>

namespace hindsight {

struct ResultsData {
  std::string configurationJson;
  int nx = 0;
  int ny = 0;
  std::vector<IterationRecord> history;  ///< completed iterations, in order
  std::vector<Vector> densities;         ///< one nx * ny grid (row * nx + column) per history entry
  OptimizerState state;                  ///< the optimizer after the last completed iteration
  bool finished = false;                 ///< the last history entry is the final design's evaluation
  Matrix finalModes;                     ///< dofCount x modeCount when finished, else empty
  std::vector<double> finalFrequenciesHz;
};

/// Writes `data` atomically to `path` as described above. Throws std::invalid_argument when the
/// data are inconsistent (sizes), StorageError when the file cannot be written.
void writeResultsFile(const std::string& path, const ResultsData& data);

/// Reads a file written by writeResultsFile. Throws StorageError naming the path when it cannot be
/// opened, is not a hindsight results file, or is inconsistent.
ResultsData readResultsFile(const std::string& path);

/// The configuration JSON stored in a results file (StorageError as readResultsFile).
std::string readResultsConfiguration(const std::string& path);

}  // namespace hindsight
