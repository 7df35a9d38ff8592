// Topology optimization of the piston rod on a coarse mesh: the loop decreases psi1 and ends feasible,
// both routes record psi1, a run killed at any moment leaves a readable results file and resumes bit
// for bit, the --resume / --force rules and the bad-input errors (library and CLI exit codes).
#include <hindsight/problems/topopt/geometry_export.h>
#include <hindsight/problems/topopt/optimization_run.h>
#include <hindsight/problems/topopt/results_file.h>
#include <hindsight/problems/topopt/topology_optimizer.h>

#include "support/run_cli.h"

#include "support/file_checks.h"
#include "support/fresh_directory.h"
#include "support/same_bits.h"

#include <gtest/gtest.h>
#include <hdf5.h>

#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <thread>

namespace hindsight {
namespace {

using testing::sameBits;

namespace fs = std::filesystem;

// 20 x 4 elements, 4 modes, 0.5 s: an evaluation takes about 0.1 s. Move limit 0.1: with the standard
// value 0.5 the first MMA steps overshoot into soft designs (see the divergence test below).
Config coarseConfig(const std::string& objective = "psi1", int iterations = 8) {
  Config config;
  config.rod.elementsAlongLength = 20;
  config.rod.elementsThroughHeight = 4;
  config.rod.modeCount = 4;
  config.rod.endTime = 0.5;
  config.rod.rampTime = 0.5;
  config.simulation.step = 2e-4;
  config.optimization.objective = parseObjective(objective);
  config.optimization.iterations = iterations;
  config.optimization.moveLimit = 0.1;
  return config;
}

using testing::freshDirectory;

// Whether a temporary file of the atomic write of `path` (PATH.tmp-PID-N) is left in its directory.
bool hasTemporaries(const std::string& path) {
  const std::string prefix = fs::path(path).filename().string() + ".tmp-";
  for (const auto& entry : fs::directory_iterator(fs::path(path).parent_path())) {
    if (entry.path().filename().string().rfind(prefix, 0) == 0) return true;
  }
  return false;
}

// Everything but the wall-clock seconds must agree bit for bit.
void expectSameResults(const ResultsData& a, const ResultsData& b) {
  ASSERT_EQ(a.history.size(), b.history.size());
  for (std::size_t k = 0; k < a.history.size(); ++k) {
    SCOPED_TRACE("iteration " + std::to_string(k));
    EXPECT_EQ(a.history[k].iteration, b.history[k].iteration);
    EXPECT_EQ(a.history[k].backtracks, b.history[k].backtracks);
    EXPECT_TRUE(sameBits(a.history[k].psi1, b.history[k].psi1))
        << a.history[k].psi1 << " vs " << b.history[k].psi1;
    EXPECT_TRUE(sameBits(a.history[k].psi2, b.history[k].psi2));
    EXPECT_TRUE(sameBits(a.history[k].volumeFraction, b.history[k].volumeFraction));
    EXPECT_TRUE(sameBits(a.history[k].maxDesignChange, b.history[k].maxDesignChange));
    EXPECT_TRUE(sameBits(a.densities[k], b.densities[k]));
  }
  EXPECT_EQ(a.finished, b.finished);
  EXPECT_EQ(a.state.iteration, b.state.iteration);
  EXPECT_TRUE(sameBits(a.state.design, b.state.design));
  EXPECT_TRUE(sameBits(a.state.mma.xold1, b.state.mma.xold1));
  EXPECT_TRUE(sameBits(a.state.mma.xold2, b.state.mma.xold2));
  EXPECT_TRUE(sameBits(a.state.mma.low, b.state.mma.low));
  EXPECT_TRUE(sameBits(a.state.mma.upp, b.state.mma.upp));
  EXPECT_TRUE(sameBits(a.state.objectiveScale, b.state.objectiveScale));
  EXPECT_TRUE(sameBits(a.state.mma.moveLimit, b.state.mma.moveLimit));
  EXPECT_TRUE(sameBits(a.state.mma.objective, b.state.mma.objective));
  EXPECT_TRUE(sameBits(a.state.bestObjective, b.state.bestObjective));
  EXPECT_EQ(a.state.recentObjectives, b.state.recentObjectives);
  EXPECT_TRUE(sameBits(a.state.bestDesign, b.state.bestDesign));
  EXPECT_EQ(a.state.refining, b.state.refining);
  EXPECT_EQ(a.finalModes.rows(), b.finalModes.rows());
  EXPECT_EQ(a.finalModes.cols(), b.finalModes.cols());
  EXPECT_TRUE(sameBits(a.finalModes, b.finalModes));
  EXPECT_EQ(a.configurationJson, b.configurationJson);
}

OptimizationRunSummary runQuietly(const Config& config, OptimizationRunOptions options) {
  std::ostringstream progress;
  OptimizationRun run(config, options);
  return run.run(progress);
}

// ---- corrupting a results file the way a disk, a tool or a person would ----

std::vector<double> readDoublesWithPlainHdf5(const std::string& path, const std::string& name) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t dataset = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  const hid_t space = H5Dget_space(dataset);
  std::vector<double> values(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
  EXPECT_GE(H5Dread(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  H5Sclose(space);
  H5Dclose(dataset);
  H5Fclose(file);
  return values;
}

// Sets entry `index` of a dataset through HDF5, as h5py or the C API would: HDF5 recomputes its
// Fletcher32 checksums, so only the content hash can notice. Returns the old value.
double setValueWithPlainHdf5(const std::string& path, const std::string& name, std::size_t index,
                             double value) {
  std::vector<double> values = readDoublesWithPlainHdf5(path, name);
  const double old = values.at(index);
  values[index] = value;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  const hid_t dataset = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  EXPECT_GE(H5Dwrite(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  H5Dclose(dataset);
  EXPECT_GE(H5Fclose(file), 0);
  return old;
}

// The byte offset in the file of the chunk of `name` that holds the element at `coordinates`.
std::uint64_t chunkOffset(const std::string& path, const std::string& name,
                          const std::vector<hsize_t>& coordinates) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t dataset = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  unsigned filterMask = 0;
  haddr_t address = HADDR_UNDEF;
  hsize_t size = 0;
  EXPECT_GE(H5Dget_chunk_info_by_coord(dataset, coordinates.data(), &filterMask, &address, &size), 0);
  H5Dclose(dataset);
  H5Fclose(file);
  EXPECT_NE(address, HADDR_UNDEF);
  return static_cast<std::uint64_t>(address);
}

// Changes bytes of the file itself, below HDF5: what bit rot or a raw overwrite does.
void overwriteFileBytes(const std::string& path, std::uint64_t offset, const void* bytes, std::size_t count) {
  std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
  file.seekp(static_cast<std::streamoff>(offset));
  file.write(static_cast<const char*>(bytes), static_cast<std::streamsize>(count));
  ASSERT_TRUE(static_cast<bool>(file)) << path;
}

// Turns a results file into one as written before checksums (format_version 1, no content_hash
// attributes); the chunked layout and its filters stay, which format 1 readers never looked at.
void stripChecksums(const std::string& path) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  EXPECT_GE(H5Adelete(file, "content_hash"), 0);
  for (const std::string& name : testing::resultsDatasets())
    EXPECT_GE(H5Adelete_by_name(file, name.c_str(), "content_hash", H5P_DEFAULT), 0);
  const hid_t attribute = H5Aopen(file, "format_version", H5P_DEFAULT);
  const int version = 1;
  EXPECT_GE(H5Awrite(attribute, H5T_NATIVE_INT, &version), 0);
  H5Aclose(attribute);
  EXPECT_GE(H5Fclose(file), 0);
}

// The message of the StorageError that reading `path` throws; empty when it reads.
std::string readError(const std::string& path) {
  try {
    readResultsFile(path);
  } catch (const StorageError& e) {
    return e.what();
  }
  return {};
}

// The uninterrupted reference run of a configuration, computed once per configuration.
const ResultsData& referenceResults(const Config& config, const std::string& name) {
  static std::map<std::string, ResultsData> cache;
  auto found = cache.find(name);
  if (found == cache.end()) {
    OptimizationRunOptions options;
    options.outputDirectory = freshDirectory("reference_" + name);
    runQuietly(config, options);
    found = cache.emplace(name, readResultsFile(options.outputDirectory + "/results.h5")).first;
  }
  return found->second;
}

TEST(TopologyOptimizer, CoarseOptimizationDecreasesPsi1AndEndsFeasible) {
  const Config config = coarseConfig("psi1", 15);
  TopologyOptimizer optimizer(config);
  std::vector<IterationRecord> history;
  while (!optimizer.finished()) history.push_back(optimizer.step());
  ASSERT_EQ(history.size(), 16u);
  EXPECT_TRUE(std::isnan(history.back().maxDesignChange));  // the final evaluation makes no update
  int increases = 0;
  for (std::size_t k = 1; k < history.size(); ++k) {
    std::cout << progressLine(history[k]) << '\n';
    if (history[k].psi1 > history[k - 1].psi1) ++increases;
    // "Monotonically-ish": MMA may overshoot a little while it pulls the volume onto the bound.
    EXPECT_LT(history[k].psi1, 1.02 * history[k - 1].psi1) << "iteration " << k;
  }
  EXPECT_LE(increases, 3);
  EXPECT_LT(history.back().psi1, 0.8 * history.front().psi1);
  EXPECT_LE(history.back().volumeFraction, 0.5 + 1e-6);
  // x0 = 0.5 with solid end columns starts slightly infeasible (V/V0 = 0.55 on 20 columns).
  EXPECT_GT(history.front().volumeFraction, 0.5);
  EXPECT_EQ(optimizer.state().iteration, 15);
  EXPECT_THROW(optimizer.step(), std::logic_error);
}

// With the paper's time span and the standard MMA move limit 0.5 the coarse rod reaches, in its fourth
// update, a near-mechanism design whose response diverges (checked directly below); the optimizer
// halves the step back toward the previous design and carries on.
TEST(TopologyOptimizer, DivergedSimulationIsBacktrackedTowardThePreviousDesign) {
  Config config;
  config.rod.elementsAlongLength = 20;
  config.rod.elementsThroughHeight = 4;
  config.rod.modeCount = 4;
  config.simulation.step = 2e-4;
  config.optimization.iterations = 5;
  // The paper's MMA with its move limit 0.5 overshoots into a soft design in the first steps (the
  // default adaptive move limit halves after such a step and may never reach one).
  config.optimization.method = "mma";
  config.optimization.moveLimit = 0.5;
  TopologyOptimizer optimizer(config);
  std::vector<IterationRecord> history;
  Vector failing;
  while (!optimizer.finished()) {
    const Vector proposed = optimizer.state().design;
    history.push_back(optimizer.step());
    if (history.back().backtracks > 0 && failing.size() == 0) failing = proposed;
    EXPECT_TRUE(std::isfinite(history.back().psi1));
  }
  ASSERT_GT(failing.size(), 0) << "no simulation diverged; the test no longer exercises the guard";
  // The rejected design really diverges: its simulation fails or psi1 grew more than tenfold.
  bool diverged = false;
  try {
    diverged = optimizer.rod().evaluate(failing, {false, false, false}).psi1 >
               TopologyOptimizer::maxObjectiveGrowth * history.front().psi1;
  } catch (const NumericalError&) {
    diverged = true;
  }
  EXPECT_TRUE(diverged);
  EXPECT_LT(history.back().psi1, TopologyOptimizer::maxObjectiveGrowth * history.front().psi1);
}

TEST(TopologyOptimizer, EslRouteRecordsPsi1OfEveryDesignAndDecreasesPsi2) {
  const Config config = coarseConfig("psi2", 10);
  TopologyOptimizer optimizer(config);
  std::vector<IterationRecord> history;
  while (!optimizer.finished()) history.push_back(optimizer.step());
  for (const IterationRecord& record : history) {
    EXPECT_TRUE(std::isfinite(record.psi1) && record.psi1 > 0.0);
    EXPECT_TRUE(std::isfinite(record.psi2) && record.psi2 > 0.0);
  }
  EXPECT_LT(history.back().psi2, 0.8 * history.front().psi2);
  EXPECT_LE(history.back().volumeFraction, 0.5 + 1e-6);
}

TEST(TopologyOptimizer, FilteredDensityIsWhatTheModelSeesAndKeepsSolidColumns) {
  Config config = coarseConfig("psi1", 3);
  config.optimization.filterRadius = 1.5;
  TopologyOptimizer optimizer(config);
  Vector x = optimizer.state().design;
  x(0) = 1.0;  // column 1, row 0: its neighbours pick up density through the filter
  const Vector grid = optimizer.densityGrid(x);
  const int nx = config.rod.elementsAlongLength;
  const int ny = config.rod.elementsThroughHeight;
  for (int row = 0; row < ny; ++row) {
    EXPECT_EQ(grid(row * nx), 1.0);
    EXPECT_EQ(grid(row * nx + nx - 1), 1.0);
  }
  EXPECT_LT(grid(0 * nx + 1), 1.0);          // smeared out
  EXPECT_GT(grid(0 * nx + 2), 0.5);          // its right neighbour gained
  EXPECT_GT(grid(1 * nx + 1), 0.5);          // and the one above
  EXPECT_DOUBLE_EQ(grid(3 * nx + 10), 0.5);  // far away nothing changes
  std::vector<IterationRecord> history;
  while (!optimizer.finished()) history.push_back(optimizer.step());
  EXPECT_LT(history.back().psi1, history.front().psi1);
}

TEST(ResultsFile, RoundTripsEveryField) {
  const Config config = coarseConfig("psi1", 2);
  const ResultsData& data = referenceResults(config, "psi1_2");
  EXPECT_EQ(data.history.size(), 3u);
  EXPECT_TRUE(data.finished);
  EXPECT_EQ(data.finalModes.cols(), 4);
  EXPECT_EQ(data.finalFrequenciesHz.size(), 4u);
  const std::string path = freshDirectory("roundtrip") + ".h5";
  writeResultsFile(path, data);
  expectSameResults(readResultsFile(path), data);
  for (std::size_t k = 0; k < data.history.size(); ++k) {
    EXPECT_TRUE(sameBits(readResultsFile(path).history[k].totalSeconds, data.history[k].totalSeconds));
  }
  EXPECT_FALSE(hasTemporaries(path));
}

TEST(ResultsFile, UnreadableOrForeignFilesThrowStorageError) {
  const std::string dir = freshDirectory("foreign");
  fs::create_directories(dir);
  EXPECT_THROW(readResultsFile(dir + "/missing.h5"), StorageError);
  std::ofstream(dir + "/garbage.h5") << "not hdf5";
  EXPECT_THROW(readResultsFile(dir + "/garbage.h5"), StorageError);
  const hid_t file = H5Fcreate((dir + "/empty.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  H5Fclose(file);
  EXPECT_THROW(readResultsFile(dir + "/empty.h5"), StorageError);
}

// Reads the file with nothing but the HDF5 C API and returns the number of completed iterations,
// after checking that the history columns and the designs have that many rows.
int completedIterationsWithPlainHdf5(const std::string& path, int nx, int ny) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(file, 0) << path;
  if (file < 0) return -1;
  int completed = -1;
  const hid_t attribute = H5Aopen(file, "completed_iterations", H5P_DEFAULT);
  EXPECT_GE(H5Aread(attribute, H5T_NATIVE_INT, &completed), 0);
  H5Aclose(attribute);
  const hid_t psi1 = H5Dopen2(file, "history/psi1", H5P_DEFAULT);
  const hid_t space = H5Dget_space(psi1);
  hsize_t rows = 0;
  H5Sget_simple_extent_dims(space, &rows, nullptr);
  std::vector<double> values(rows);
  if (rows > 0) EXPECT_GE(H5Dread(psi1, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  for (double v : values) EXPECT_TRUE(std::isfinite(v) && v > 0.0);
  H5Sclose(space);
  H5Dclose(psi1);
  EXPECT_EQ(static_cast<int>(rows), completed);
  const hid_t designs = H5Dopen2(file, "designs", H5P_DEFAULT);
  const hid_t designSpace = H5Dget_space(designs);
  hsize_t dims[3] = {0, 0, 0};
  EXPECT_EQ(H5Sget_simple_extent_dims(designSpace, dims, nullptr), 3);
  EXPECT_EQ(dims[0], rows);
  EXPECT_EQ(dims[1], static_cast<hsize_t>(ny));
  EXPECT_EQ(dims[2], static_cast<hsize_t>(nx));
  H5Sclose(designSpace);
  H5Dclose(designs);
  H5Fclose(file);
  return completed;
}

// Runs `config` in a child process; the child dies by std::_Exit right after iteration `exitAfter`
// was committed (exitAfter < 0: it runs to the end), or by SIGKILL from the parent after `killAfter`.
// Returns true when the child died by the signal.
bool runInChild(const Config& config, const std::string& directory, int exitAfter,
                std::chrono::microseconds killAfter = std::chrono::microseconds::zero()) {
  std::cout.flush();
  const pid_t child = fork();
  EXPECT_GE(child, 0);
  if (child < 0) return false;
  if (child == 0) {
    OptimizationRunOptions options;
    options.outputDirectory = directory;
    options.resume = true;  // the first attempt starts fresh, the next ones continue
    if (exitAfter >= 0) {
      options.afterCommit = [exitAfter](const IterationRecord& record) {
        if (record.iteration == exitAfter) std::_Exit(0);
      };
    }
    try {
      runQuietly(config, options);
    } catch (...) {
      std::_Exit(1);
    }
    std::_Exit(0);
  }
  if (killAfter.count() > 0) {
    std::this_thread::sleep_for(killAfter);
    kill(child, SIGKILL);
  }
  int status = 0;
  EXPECT_EQ(waitpid(child, &status, 0), child);
  if (killAfter.count() == 0) {
    EXPECT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
  }
  return WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
}

// `config` run into the fresh directory `name` in a child that stops right after iteration `exitAfter`,
// then resumed here to its end: the resumed run's results file.
ResultsData interruptedAndResumed(const Config& config, const std::string& name, int exitAfter) {
  const std::string dir = freshDirectory(name);
  EXPECT_FALSE(runInChild(config, dir, exitAfter));
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  options.resume = true;
  runQuietly(config, options);
  return readResultsFile(dir + "/results.h5");
}

TEST(OptimizationRun, ExitAfterAnIterationThenResumeIsBitIdentical) {
  for (const std::string objective : {"psi1", "psi2"}) {
    SCOPED_TRACE(objective);
    const Config config = coarseConfig(objective, 6);
    const ResultsData& reference = referenceResults(config, objective + "_6");
    const std::string dir = freshDirectory("exit_" + objective);
    EXPECT_FALSE(runInChild(config, dir, 2));
    EXPECT_EQ(completedIterationsWithPlainHdf5(dir + "/results.h5", 20, 4), 3);
    OptimizationRunOptions options;
    options.outputDirectory = dir;
    options.resume = true;
    const OptimizationRunSummary summary = runQuietly(config, options);
    EXPECT_EQ(summary.resumedFrom, 3);
    expectSameResults(readResultsFile(dir + "/results.h5"), reference);
    EXPECT_TRUE(fs::exists(dir + "/design_final.png"));
    EXPECT_TRUE(fs::exists(dir + "/design_final.vtk"));
  }
}

TEST(OptimizationRun, KillNineAtRandomMomentsLeavesAReadableFileAndResumesBitIdentically) {
  const Config config = coarseConfig("psi1", 6);
  const ResultsData& reference = referenceResults(config, "psi1_6");
  double runSeconds = 0.0;
  for (const IterationRecord& record : reference.history) runSeconds += record.totalSeconds;
  std::mt19937 rng(20261122);
  std::uniform_real_distribution<double> moment(0.05, 0.95);
  const std::string dir = freshDirectory("kill9");
  // Several kills into the same directory: each resumes the previous attempt's file, so a kill can
  // also land in a resumed run, while it reads the file or writes a picture.
  int killedMidRun = 0;
  int lastCompleted = 0;
  for (int attempt = 0; attempt < 4; ++attempt) {
    const auto delay = std::chrono::microseconds(static_cast<long>(1e6 * runSeconds * moment(rng)));
    const bool killed = runInChild(config, dir, -1, delay);
    const std::string path = dir + "/results.h5";
    if (fs::exists(path)) {
      const int completed = completedIterationsWithPlainHdf5(path, 20, 4);
      EXPECT_GE(completed, lastCompleted);  // never loses a completed iteration
      lastCompleted = completed;
      const ResultsData partial = readResultsFile(path);
      // What is there equals the uninterrupted run's first iterations.
      for (std::size_t k = 0; k < partial.history.size(); ++k) {
        EXPECT_TRUE(sameBits(partial.history[k].psi1, reference.history[k].psi1));
        EXPECT_TRUE(sameBits(partial.densities[k], reference.densities[k]));
      }
      if (killed && !partial.finished) ++killedMidRun;
    }
  }
  // Otherwise the test proved nothing: at least one kill must have hit a run in progress.
  EXPECT_GE(killedMidRun, 1);
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  options.resume = true;
  runQuietly(config, options);
  expectSameResults(readResultsFile(dir + "/results.h5"), reference);
  EXPECT_FALSE(hasTemporaries(dir + "/results.h5"));
}

TEST(OptimizationRun, ResumingAFinishedRunWithMoreIterationsEqualsTheLongerRun) {
  const std::string dir = freshDirectory("extend");
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  runQuietly(coarseConfig("psi1", 3), options);
  options.resume = true;
  // Same count: nothing to do, the file is unchanged.
  EXPECT_EQ(runQuietly(coarseConfig("psi1", 3), options).history.size(), 4u);
  runQuietly(coarseConfig("psi1", 6), options);
  expectSameResults(readResultsFile(dir + "/results.h5"),
                    referenceResults(coarseConfig("psi1", 6), "psi1_6"));
}

// The stopping rule on the coarse rod (smooth there: 0.5 s, no resonance in reach) ends the run at a
// KKT point long before the iteration limit: residual and step below the tolerances at the last
// record, which is marked converged in memory and in the file; a run interrupted before and resumed
// stops at the same iteration with the same bits, and so does a finished one asked for more.
TEST(OptimizationRun, StoppingRuleEndsTheRunAtAKktPointAndAResumeStopsThere) {
  Config config = coarseConfig("psi1", 200);
  ASSERT_EQ(config.optimization.method, "mma-adaptive");  // the defaults under test
  ASSERT_GT(config.optimization.kktTolerance, 0.0);
  const ResultsData& reference = referenceResults(config, "psi1_converging");
  ASSERT_TRUE(reference.finished);
  ASSERT_LT(reference.history.size(), 201u);
  const IterationRecord& last = reference.history.back();
  EXPECT_TRUE(last.converged);
  EXPECT_LE(last.kktResidual, config.optimization.kktTolerance);
  EXPECT_LE(last.maxDesignChange, config.optimization.changeTolerance);
  EXPECT_LE(last.volumeFraction, config.optimization.volumeFraction * (1.0 + 1e-6));
  for (std::size_t k = 0; k + 1 < reference.history.size(); ++k) {
    EXPECT_FALSE(reference.history[k].converged) << k;
    EXPECT_TRUE(std::isfinite(reference.history[k].kktResidual)) << k;
  }
  EXPECT_EQ(reference.state.iteration + 1, static_cast<int>(reference.history.size()));
  EXPECT_EQ(bestFeasibleIndex(reference.history, config), static_cast<int>(reference.history.size()) - 1);

  const std::string dir = freshDirectory("converging_exit");
  EXPECT_FALSE(runInChild(config, dir, 3));
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  options.resume = true;
  runQuietly(config, options);
  const ResultsData resumed = readResultsFile(dir + "/results.h5");
  expectSameResults(resumed, reference);
  EXPECT_TRUE(resumed.history.back().converged);
  config.optimization.iterations = 250;  // a finished run asked for more converges at the same place
  runQuietly(config, options);
  expectSameResults(readResultsFile(dir + "/results.h5"), referenceResults(config, "psi1_converging_250"));

  // Either tolerance 0: the rule is off and the run makes every update.
  Config off = coarseConfig("psi1", 20);
  off.optimization.kktTolerance = 0.0;
  const ResultsData& full = referenceResults(off, "psi1_rule_off");
  EXPECT_EQ(full.history.size(), 21u);
  EXPECT_FALSE(full.history.back().converged);
  // With the rule on, a run that reaches the cap ends with an evaluation of its best feasible design:
  // the same bits as that design's own record (x_N itself is not evaluated). With the rule off (the
  // paper's setting, above) the final record is x_N's, unlike every earlier one.
  const Config capped = coarseConfig("psi1", 6);
  const ResultsData& short_ = referenceResults(capped, "psi1_capped");
  ASSERT_EQ(short_.history.size(), 7u);
  ASSERT_FALSE(short_.history.back().converged);
  const std::vector<IterationRecord> updates(short_.history.begin(), short_.history.end() - 1);
  const int best = bestFeasibleIndex(updates, capped);
  ASSERT_GE(best, 0);
  EXPECT_TRUE(sameBits(short_.history.back().psi1, short_.history[best].psi1));
  EXPECT_TRUE(sameBits(short_.history.back().volumeFraction, short_.history[best].volumeFraction));
  EXPECT_TRUE(sameBits(short_.densities.back(), short_.densities[best]));
  EXPECT_EQ(bestFeasibleIndex(short_.history, capped), 6);  // the tie goes to the final record
  for (std::size_t k = 0; k + 1 < full.history.size(); ++k)
    EXPECT_FALSE(sameBits(full.history.back().psi1, full.history[k].psi1)) << k;
}

// Stagnation replaces the change test: with a change tolerance no update meets, the run still ends once
// the residual test holds and the objective of the last five designs varies by at most
// objectiveTolerance; the window is part of the stored state, so a run interrupted inside the window
// and resumed stops at the same record with the same bits. Without stagnation the same run goes on.
TEST(OptimizationRun, StagnationEndsTheRunAndAResumeStopsThere) {
  Config config = coarseConfig("psi1", 200);
  config.optimization.changeTolerance = 1e-12;
  config.optimization.objectiveTolerance = 1e-3;
  const ResultsData& reference = referenceResults(config, "psi1_stagnating");
  ASSERT_TRUE(reference.finished);
  const std::vector<IterationRecord>& h = reference.history;
  ASSERT_GE(h.size(), 6u);
  ASSERT_LT(h.size(), 201u);
  EXPECT_TRUE(h.back().converged);
  EXPECT_LE(h.back().kktResidual, config.optimization.kktTolerance);
  EXPECT_GT(h.back().maxDesignChange, config.optimization.changeTolerance);  // not the change test
  // The window: the relative objectives psi / psi(x0) of the last five designs, this one's last.
  double smallest = h.back().psi1, largest = h.back().psi1;
  for (std::size_t k = h.size() - 5; k < h.size(); ++k) {
    smallest = std::min(smallest, h[k].psi1);
    largest = std::max(largest, h[k].psi1);
  }
  EXPECT_LE(largest - smallest, 1e-3 * smallest * (1.0 + 1e-12));
  for (std::size_t k = 0; k + 1 < h.size(); ++k) EXPECT_FALSE(h[k].converged) << k;

  // Interrupted inside the final window.
  expectSameResults(interruptedAndResumed(config, "stagnating_exit", static_cast<int>(h.size()) - 3),
                    reference);

  Config off = config;
  off.optimization.objectiveTolerance = 0.0;
  off.optimization.iterations = static_cast<int>(h.size()) + 2;
  const ResultsData& longer = referenceResults(off, "psi1_stagnation_off");
  EXPECT_FALSE(longer.history[h.size() - 1].converged);
}

// The end game: a run whose residual never meets kktTolerance (here 1e-12) would go on to the cap; when
// only the end game's updates remain it returns to its best feasible design, refines it with a move limit
// that halves at every update, and ends there by the rule's trust-region test, before the cap, at the
// lowest objective of its history. The refinement is part of
// the stored state: a run interrupted inside it and resumed ends with the same bits. With the end game
// off the same run does not stop there.
TEST(OptimizationRun, EndGameRefinesTheBestDesignAndEndsByTheRuleBeforeTheCap) {
  Config config = coarseConfig("psi1", 60);
  config.optimization.kktTolerance = 1e-12;
  const ResultsData& reference = referenceResults(config, "psi1_end_game");
  ASSERT_TRUE(reference.finished);
  const std::vector<IterationRecord>& h = reference.history;
  ASSERT_LT(h.size(), 61u) << "the end game did not end the run before the cap";
  EXPECT_TRUE(h.back().converged);
  EXPECT_TRUE(reference.state.refining);
  // The stored limit is that of the update that led to the final design: one halving above the limit
  // the rule found at or below changeTolerance.
  EXPECT_LE(reference.state.mma.moveLimit, 2.0 * config.optimization.changeTolerance);
  for (std::size_t k = 0; k + 1 < h.size(); ++k) {
    EXPECT_FALSE(h[k].converged) << k;
    if (h[k].volumeFraction <= config.optimization.volumeFraction * (1.0 + 1e-6))
      EXPECT_LE(h.back().psi1, h[k].psi1) << k;
  }

  // Interrupted inside the refinement.
  expectSameResults(interruptedAndResumed(config, "end_game_exit", static_cast<int>(h.size()) - 3),
                    reference);

  Config off = config;
  off.optimization.endGame = false;
  off.optimization.iterations = static_cast<int>(h.size()) + 2;
  const ResultsData& longer = referenceResults(off, "psi1_end_game_off");
  EXPECT_FALSE(longer.history[h.size() - 1].converged);
}

// The best feasible design: the lowest objective among records within the volume bound (1e-6 relative
// slack), with scenarios the aggregate of the relative objectives; -1 when none is feasible.
TEST(OptimizationRun, BestFeasibleIndexPicksTheLowestObjectiveWithinTheVolumeBound) {
  Config config;
  std::vector<IterationRecord> history(4);
  const double psi[] = {1.0, 0.2, 0.3, 0.25};
  const double volume[] = {0.6, 0.51, 0.5 * (1.0 + 5e-7), 0.45};
  for (int k = 0; k < 4; ++k) {
    history[k].iteration = k;
    history[k].psi1 = psi[k];
    history[k].psi2 = 2.0 * psi[k];
    history[k].volumeFraction = volume[k];
  }
  EXPECT_EQ(bestFeasibleIndex(history, config), 3);  // 0.2 is infeasible, 0.25 < 0.3
  history[3].volumeFraction = 0.7;
  EXPECT_EQ(bestFeasibleIndex(history, config), 2);  // within the slack
  for (IterationRecord& r : history) r.volumeFraction = 0.9;
  EXPECT_EQ(bestFeasibleIndex(history, config), -1);
  // The frequency guard counts as the stopping rule counts it: a record below the bound (or without a
  // frequency) is not feasible.
  for (IterationRecord& r : history) r.volumeFraction = 0.4;
  config.optimization.minFirstFrequency = 50.0;
  const double frequency[] = {60.0, 49.0, 50.0, std::numeric_limits<double>::quiet_NaN()};
  for (int k = 0; k < 4; ++k) history[k].firstFrequencyHz = frequency[k];
  EXPECT_EQ(bestFeasibleIndex(history, config), 2);  // 0.2 is below 50 Hz, 0.25 has no frequency
  config.optimization.minFirstFrequency = 0.0;
  // Two scenarios, aggregate max of w_s psi_s / psi_s(x0).
  config.scenarios = {Scenario{"a", {}, {}, {}, {}, 1.0}, Scenario{"b", {}, {}, {}, {}, 2.0}};
  config.optimization.aggregate = Aggregate::Max;
  for (IterationRecord& r : history) r.volumeFraction = 0.4;
  history[0].scenarioPsi1 = {1.0, 1.0};
  history[1].scenarioPsi1 = {0.1, 0.5};  // max(0.1, 1.0) = 1.0
  history[2].scenarioPsi1 = {0.6, 0.2};  // max(0.6, 0.4) = 0.6
  history[3].scenarioPsi1 = {0.3, 0.4};  // max(0.3, 0.8) = 0.8
  EXPECT_EQ(bestFeasibleIndex(history, config), 2);
  config.optimization.aggregate = Aggregate::Sum;  // sums 3.0, 1.1, 1.0, 1.1
  EXPECT_EQ(bestFeasibleIndex(history, config), 2);
}

TEST(OptimizationRun, ExistingResultsNeedResumeOrForce) {
  const std::string dir = freshDirectory("rules");
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  runQuietly(coarseConfig("psi1", 1), options);
  const auto before = fs::last_write_time(dir + "/results.h5");
  // Without a flag: refused before any work, the file untouched.
  try {
    OptimizationRun run(coarseConfig("psi1", 1), options);
    FAIL() << "an existing results file was accepted without --resume or --force";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--force"), std::string::npos) << e.what();
  }
  EXPECT_EQ(fs::last_write_time(dir + "/results.h5"), before);
  // Both flags: refused.
  OptimizationRunOptions both = options;
  both.resume = both.force = true;
  EXPECT_THROW(OptimizationRun(coarseConfig("psi1", 1), both), std::invalid_argument);
  // --resume with a different problem: refused, naming the field.
  OptimizationRunOptions resume = options;
  resume.resume = true;
  Config other = coarseConfig("psi1", 1);
  other.rod.modeCount = 3;
  try {
    OptimizationRun run(other, resume);
    FAIL() << "a resume with a different configuration was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rod.modeCount"), std::string::npos) << e.what();
  }
  // --resume with fewer iterations than done: refused.
  EXPECT_THROW(OptimizationRun(coarseConfig("psi1", 0), resume), std::invalid_argument);
  // --force: a fresh run replaces the file.
  OptimizationRunOptions force = options;
  force.force = true;
  const OptimizationRunSummary summary = runQuietly(coarseConfig("psi2", 1), force);
  EXPECT_EQ(summary.resumedFrom, 0);
  EXPECT_NE(readResultsFile(dir + "/results.h5").configurationJson.find("\"psi2\""), std::string::npos);
}

TEST(OptimizationRun, BadInputIsRefusedBeforeAnyWork) {
  const std::string dir = freshDirectory("bad");
  fs::create_directories(dir);
  std::ofstream(dir + "/a_file") << "x";
  OptimizationRunOptions options;
  // An output directory below a regular file cannot be created (also as root).
  options.outputDirectory = dir + "/a_file/results";
  EXPECT_THROW(OptimizationRun(coarseConfig(), options), std::invalid_argument);
  options.outputDirectory = dir + "/a_file";
  EXPECT_THROW(OptimizationRun(coarseConfig(), options), std::invalid_argument);
  options.outputDirectory = dir + "/out";
  Config config = coarseConfig();
  config.optimization.volumeFraction = 1.5;
  try {
    OptimizationRun run(config, options);
    FAIL() << "volume fraction 1.5 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("optimization.volumeFraction"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir + "/out/results.h5"));
}

// ---- integrity of the results file ----

// An interrupted run (3 of 7 evaluations committed) in `name`; returns the results file.
std::string interruptedRun(const std::string& name) {
  const std::string dir = freshDirectory(name);
  EXPECT_FALSE(runInChild(coarseConfig("psi1", 6), dir, 2));
  return dir + "/results.h5";
}

TEST(ResultsFile, EveryDatasetIsChecksummedAndASoundFileVerifies) {
  const std::string path = interruptedRun("sound");
  const ResultsVerification verification = verifyResultsFile(path);
  EXPECT_EQ(verification.formatVersion, 2);
  EXPECT_TRUE(verification.checksummed);
  EXPECT_EQ(verification.completedIterations, 3);
  EXPECT_EQ(verification.firstProblem(), nullptr);
  ASSERT_EQ(verification.checks.size(), testing::resultsDatasets().size() + 1);  // and the root
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GT(H5Aexists(file, "content_hash"), 0);
  for (const std::string& name : testing::resultsDatasets()) {
    SCOPED_TRACE(name);
    const hid_t dataset = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
    const hid_t creation = H5Dget_create_plist(dataset);
    EXPECT_EQ(H5Pget_layout(creation), H5D_CHUNKED);
    EXPECT_GE(
        H5Pget_filter_by_id2(creation, H5Z_FILTER_FLETCHER32, nullptr, nullptr, nullptr, 0, nullptr, nullptr),
        0);
    EXPECT_GT(H5Aexists(dataset, "content_hash"), 0);
    H5Pclose(creation);
    H5Dclose(dataset);
  }
  H5Fclose(file);
  EXPECT_TRUE(readResultsFile(path).checksummed);
}

// The finding: a NaN written into state/mma_low of an interrupted run was carried on unnoticed.
// Rewritten through HDF5 (Fletcher32 recomputed), the content hash names it.
TEST(ResultsFile, ANanWrittenThroughHdf5IntoMmaLowIsNamed) {
  const std::string path = interruptedRun("nan_hdf5");
  setValueWithPlainHdf5(path, "state/mma_low", 5, std::numeric_limits<double>::quiet_NaN());
  const std::string error = readError(path);
  EXPECT_NE(error.find("'/state/mma_low' is corrupted"), std::string::npos) << error;
  EXPECT_NE(error.find("content hash"), std::string::npos) << error;
  EXPECT_THROW(readResultsConfiguration(path), StorageError);  // a resume without --config too
}

// Below HDF5 (the raw bytes of the chunk): Fletcher32 refuses the read.
TEST(ResultsFile, ANanWrittenIntoTheRawBytesOfMmaLowIsNamed) {
  const std::string path = interruptedRun("nan_raw");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  overwriteFileBytes(path, chunkOffset(path, "state/mma_low", {0}) + 5 * sizeof(double), &nan, sizeof nan);
  const std::string error = readError(path);
  EXPECT_NE(error.find("'/state/mma_low' is corrupted"), std::string::npos) << error;
  EXPECT_NE(error.find("Fletcher32"), std::string::npos) << error;
}

TEST(ResultsFile, FlippedBitsInADesignRowAreNamed) {
  const std::string path = interruptedRun("flip");
  // Row 1, element 30: one bit of the mantissa, one of the exponent.
  const std::uint64_t offset = chunkOffset(path, "designs", {1, 0, 0}) + 30 * sizeof(double);
  unsigned char bytes[8];
  std::ifstream(path, std::ios::binary)
      .seekg(static_cast<std::streamoff>(offset))
      .read(reinterpret_cast<char*>(bytes), 8);
  bytes[0] ^= 0x01;
  bytes[6] ^= 0x10;
  overwriteFileBytes(path, offset, bytes, sizeof bytes);
  const ResultsVerification verification = verifyResultsFile(path);
  const ResultsCheck* bad = verification.firstProblem();
  ASSERT_NE(bad, nullptr);
  EXPECT_EQ(bad->object, "/designs");
  // Only that dataset: the others are still reported sound.
  int problems = 0;
  for (const ResultsCheck& check : verification.checks) problems += check.problem.empty() ? 0 : 1;
  EXPECT_EQ(problems, 1);
  EXPECT_NE(readError(path).find("'/designs' is corrupted"), std::string::npos);
}

// A plausible change (a density 0.5 -> 0.7, in bounds) rewritten through HDF5: neither Fletcher32
// nor the bounds can see it; the content hash does.
TEST(ResultsFile, APlausibleRewriteOfADesignRowIsCaughtByTheContentHash) {
  const std::string path = interruptedRun("plausible");
  // Row 1, element 30 (20 x 4 elements per row).
  if (setValueWithPlainHdf5(path, "designs", 80 + 30, 0.7) == 0.7)
    setValueWithPlainHdf5(path, "designs", 110, 0.6);
  const std::string error = readError(path);
  EXPECT_NE(error.find("'/designs' is corrupted"), std::string::npos) << error;
  EXPECT_NE(error.find("content hash"), std::string::npos) << error;
}

TEST(ResultsFile, AChangedAttributeIsCaughtByTheRunStatesHash) {
  const std::string path = interruptedRun("attribute");
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  const hid_t attribute = H5Aopen(file, "objective_scale", H5P_DEFAULT);
  double scale = 0.0;
  H5Aread(attribute, H5T_NATIVE_DOUBLE, &scale);
  scale *= 1.01;
  H5Awrite(attribute, H5T_NATIVE_DOUBLE, &scale);
  H5Aclose(attribute);
  H5Fclose(file);
  const std::string error = readError(path);
  EXPECT_NE(error.find("the attributes of '/' are corrupted"), std::string::npos) << error;
}

// Values that pass every checksum (written by writeResultsFile itself) but that no run leaves
// behind are refused too, naming the dataset.
TEST(ResultsFile, ImplausibleStateIsRefusedEvenWithMatchingChecksums) {
  const ResultsData& reference = referenceResults(coarseConfig("psi1", 6), "psi1_6");
  const std::string path = freshDirectory("implausible") + ".h5";
  const auto expectRefused = [&](const ResultsData& data, const std::string& object,
                                 const std::string& what) {
    writeResultsFile(path, data);
    const std::string error = readError(path);
    EXPECT_NE(error.find(object == "/" ? "'/' are corrupted" : "'" + object + "' is corrupted"),
              std::string::npos)
        << error;
    EXPECT_NE(error.find(what), std::string::npos) << error;
  };
  ResultsData data = reference;
  data.state.mma.low(3) = std::numeric_limits<double>::quiet_NaN();
  expectRefused(data, "/state/mma_low", "not finite");
  data = reference;
  data.state.mma.low(3) = data.state.mma.xold1(3);  // MMA needs low < x
  expectRefused(data, "/state/mma_low", "is not below /state/mma_xold1");
  data = reference;
  data.state.mma.upp(7) = data.state.design(7);
  expectRefused(data, "/state/mma_upp", "is not above /state/");
  data = reference;
  data.state.design(2) = 1.5;
  expectRefused(data, "/state/design", "outside");
  data = reference;
  data.densities[2](11) = 1e-9;  // below rod.designLowerBound
  expectRefused(data, "/designs", "row 2, element 11");
  data = reference;
  data.history[3].psi1 = -1.0;
  expectRefused(data, "/history/psi1", "entry 3");
  data = reference;
  data.state.mma.iteration = 4;
  expectRefused(data, "/", "inconsistent counters");
  writeResultsFile(path, reference);
  EXPECT_EQ(readError(path), "");
}

// Format 1 files (no checksums) are resumed after the plausibility checks, with a warning, and the
// resumed run still equals the uninterrupted one; the rewritten file has checksums.
TEST(OptimizationRun, AFileWithoutChecksumsIsResumedWithAWarning) {
  const std::string path = interruptedRun("format1");
  stripChecksums(path);
  const ResultsVerification verification = verifyResultsFile(path);
  EXPECT_EQ(verification.formatVersion, 1);
  EXPECT_FALSE(verification.checksummed);
  EXPECT_EQ(verification.firstProblem(), nullptr);
  OptimizationRunOptions options;
  options.outputDirectory = fs::path(path).parent_path().string();
  options.resume = true;
  std::ostringstream progress;
  OptimizationRun(coarseConfig("psi1", 6), options).run(progress);
  EXPECT_NE(progress.str().find("warning: " + path + " has no checksums"), std::string::npos)
      << progress.str();
  const ResultsData resumed = readResultsFile(path);
  EXPECT_TRUE(resumed.checksummed);
  expectSameResults(resumed, referenceResults(coarseConfig("psi1", 6), "psi1_6"));
}

TEST(OptimizationRun, AFileWithoutChecksumsIsStillCheckedForPlausibility) {
  const std::string path = interruptedRun("format1_nan");
  stripChecksums(path);
  setValueWithPlainHdf5(path, "state/mma_low", 5, std::numeric_limits<double>::quiet_NaN());
  OptimizationRunOptions options;
  options.outputDirectory = fs::path(path).parent_path().string();
  options.resume = true;
  try {
    OptimizationRun run(coarseConfig("psi1", 6), options);
    FAIL() << "a NaN in the stored MMA state was resumed";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("'/state/mma_low' is corrupted: entry 5 is nan"), std::string::npos)
        << e.what();
  }
}

TEST(OptimizationRun, ASecondRunIntoTheSameDirectoryIsRefusedAtOnce) {
  const std::string dir = freshDirectory("locked");
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  {
    OptimizationRun first(coarseConfig("psi1", 1), options);
    try {
      OptimizationRun second(coarseConfig("psi1", 1), options);
      FAIL() << "a second run into a locked directory was accepted";
    } catch (const std::invalid_argument& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("'" + dir + "' is in use"), std::string::npos) << message;
      EXPECT_NE(message.find("pid " + std::to_string(::getpid())), std::string::npos) << message;
    }
  }
  // Released with the run: the next one proceeds.
  EXPECT_EQ(runQuietly(coarseConfig("psi1", 1), options).history.size(), 2u);
}

TEST(OptimizationRun, StaleTemporariesOfResultsAndPicturesAreRemovedOnStart) {
  const std::string path = interruptedRun("stale");
  const std::string dir = fs::path(path).parent_path().string();
  const pid_t child = ::fork();  // a pid that no process has any more
  ASSERT_GE(child, 0);
  if (child == 0) std::_Exit(0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  const std::string dead = std::to_string(child);
  const std::vector<std::string> stale = {
      "design_final.vtk.tmp-" + dead + "-0", "design_final.png.tmp-" + dead + "-1",
      "design_iter_2.png.tmp-" + dead + "-0", "results.h5.tmp-" + dead + "-4"};
  for (const std::string& name : stale) std::ofstream(dir + "/" + name) << "half a file";
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  options.resume = true;
  const OptimizationRun run(coarseConfig("psi1", 6), options);
  for (const std::string& name : stale) EXPECT_FALSE(fs::exists(dir + "/" + name)) << name;
  EXPECT_TRUE(fs::exists(path));
}

#ifdef HINDSIGHT_CLI_PATH
// The CLI: exit code 2 and a message naming the problem, before any work.
using testing::CliResult;
using testing::runCli;

TEST(OptimizeCommand, BadInputExitsWithCodeTwoAndNamesTheProblem) {
  const std::string dir = freshDirectory("cli");
  fs::create_directories(dir);
  std::ofstream(dir + "/a_file") << "x";
  std::ofstream(dir + "/bad.json") << R"({"optimization": {"volumeFraction": 0.5, "objectiv": "psi1"}})";
  const struct {
    std::string arguments;
    std::string message;
  } cases[] = {
      {"--set optimization.volumeFraction=1.5 --out " + dir + "/o1", "optimization.volumeFraction"},
      {"--set optimization.volumeFraction=0 --out " + dir + "/o1", "optimization.volumeFraction"},
      {"--set rod.modeCount=0 --out " + dir + "/o1", "rod.modeCount"},
      {"--objective psi3 --out " + dir + "/o1", "--objective = psi3 must be one of: psi1, psi2"},
      {"--config " + dir + "/missing.json --out " + dir + "/o1", "missing.json"},
      {"--config " + dir + "/bad.json --out " + dir + "/o1", "objectiv"},
      {"--out " + dir + "/a_file/sub", "a_file"},
      {"--resume --force --out " + dir + "/o1", "--resume and --force"},
      // Flags are checked as their config fields (they used to fall back to the defaults).
      {"--iterations -1 --out " + dir + "/o1", "--iterations = -1 is outside the allowed range [0, 100000]"},
      {"--move-limit 0 --out " + dir + "/o1", "--move-limit = 0 is outside the allowed range (0, 1]"},
      {"--move-limit nan --out " + dir + "/o1", "--move-limit = nan must be a number in (0, 1]"},
      {"--filter-radius -1 --out " + dir + "/o1",
       "--filter-radius = -1 is outside the allowed range [0, 1000]"},
      {"--picture-every -2 --out " + dir + "/o1", "--picture-every = -2 is outside the allowed range"},
      // --resume with nothing to continue used to start a fresh run.
      {"--resume --iterations 1 --out " + dir + "/nonexistent_dir", "--resume: there is no"},
      {"--set simulation.integrator=dopri5 --set simulation.adaptive=true --out " + dir + "/o1",
       "simulation.adaptive"},
  };
  for (const auto& c : cases) {
    const CliResult result = runCli("optimize " + c.arguments);
    EXPECT_EQ(result.exitCode, 2) << c.arguments << "\n" << result.output;
    EXPECT_NE(result.output.find(c.message), std::string::npos) << c.arguments << "\n" << result.output;
    EXPECT_EQ(result.output.find("iter "), std::string::npos) << "work was done for " << c.arguments;
  }
  EXPECT_FALSE(fs::exists(dir + "/o1/results.h5"));
  EXPECT_FALSE(fs::exists(dir + "/nonexistent_dir"));
}

// coarseConfig() as command-line flags.
const std::string kCoarseFlags =
    "--set rod.elementsAlongLength=20 --set rod.elementsThroughHeight=4 --set rod.modeCount=4 "
    "--set rod.rampTime=0.5 --set rod.endTime=0.5 --set simulation.step=2e-4 --move-limit 0.1";

TEST(OptimizeCommand, RunsResumesAndRefusesToOverwrite) {
  const std::string dir = freshDirectory("cli_run");
  const std::string coarse = kCoarseFlags + " --picture-every 1 --out " + dir;
  CliResult result = runCli("optimize " + coarse + " --iterations 2");
  ASSERT_EQ(result.exitCode, 0) << result.output;
  EXPECT_NE(result.output.find("iter   0  psi1 "), std::string::npos) << result.output;
  for (const char* file : {"results.h5", "design_final.png", "design_final.vtk", "design_iter_0.png",
                           "design_iter_1.png", "design_iter_2.vtk"}) {
    EXPECT_TRUE(fs::exists(dir + "/" + file)) << file;
  }
  result = runCli("optimize " + coarse + " --iterations 2");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("--resume"), std::string::npos) << result.output;
  // Resume without repeating the configuration: the stored one is used; more iterations extend it.
  result = runCli("optimize --resume --iterations 3 --out " + dir);
  ASSERT_EQ(result.exitCode, 0) << result.output;
  const ResultsData extended = readResultsFile(dir + "/results.h5");
  EXPECT_EQ(extended.history.size(), 4u);
  EXPECT_TRUE(extended.finished);
  // The same as an uninterrupted 3-iteration run (pictureEvery is not part of the comparison).
  const ResultsData& reference = referenceResults(coarseConfig("psi1", 3), "psi1_3");
  ResultsData comparable = extended;
  comparable.configurationJson = reference.configurationJson;
  expectSameResults(comparable, reference);

  // The history plot (python3 + matplotlib + h5py); two directories as for the two routes.
  if (std::system("/usr/bin/python3 -c 'import matplotlib, h5py' > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "/usr/bin/python3 with matplotlib and h5py is not available";
  }
  result = runCli("plot " + dir + " " + dir + " --out " + dir + "/history.png");
  EXPECT_EQ(result.exitCode, 0) << result.output;
  EXPECT_GT(fs::file_size(dir + "/history.png"), 1000u);
  result = runCli("plot " + dir + "/missing --out " + dir + "/history2.png");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_FALSE(fs::exists(dir + "/history2.png"));
}

// The finding, as the user met it: one NaN in state/mma_low of an interrupted run, then --resume.
// Before checksums this exited 0 with a different psi1; now it exits 3 naming the dataset, and
// nothing runs or is written.
TEST(OptimizeCommand, ResumeOfACorruptedFileExitsThreeNamingTheDataset) {
  for (const bool raw : {false, true}) {
    SCOPED_TRACE(raw ? "raw bytes" : "through HDF5");
    const std::string path = interruptedRun(raw ? "cli_nan_raw" : "cli_nan");
    const std::string dir = fs::path(path).parent_path().string();
    if (raw) {
      const double nan = std::numeric_limits<double>::quiet_NaN();
      overwriteFileBytes(path, chunkOffset(path, "state/mma_low", {0}), &nan, sizeof nan);
    } else {
      setValueWithPlainHdf5(path, "state/mma_low", 0, std::numeric_limits<double>::quiet_NaN());
    }
    const auto before = fs::last_write_time(path);
    for (const std::string& configuration : {std::string(), kCoarseFlags + " --iterations 6"}) {
      const CliResult result = runCli("optimize --resume " + configuration + " --out " + dir);
      EXPECT_EQ(result.exitCode, 3) << result.output;
      EXPECT_NE(result.output.find("'/state/mma_low' is corrupted"), std::string::npos) << result.output;
      EXPECT_EQ(result.output.find("iter "), std::string::npos) << "the corrupted run was continued";
    }
    EXPECT_EQ(fs::last_write_time(path), before);
  }
}

TEST(VerifyCommand, ListsEveryDatasetAndNamesTheCorruptedOne) {
  const std::string path = interruptedRun("cli_verify");
  const std::string dir = fs::path(path).parent_path().string();
  CliResult result = runCli("verify " + dir);
  EXPECT_EQ(result.exitCode, 0) << result.output;
  for (const std::string& name : testing::resultsDatasets()) {
    EXPECT_NE(result.output.find("/" + std::string(name) + " "), std::string::npos) << name << "\n"
                                                                                    << result.output;
  }
  std::size_t oks = 0;
  for (std::size_t at = result.output.find(" OK\n"); at != std::string::npos;
       at = result.output.find(" OK\n", at + 1))
    ++oks;
  EXPECT_EQ(oks, testing::resultsDatasets().size() + 1) << result.output;  // the datasets and the root
  EXPECT_NE(result.output.find("sound"), std::string::npos) << result.output;

  setValueWithPlainHdf5(path, "designs", 80 + 5, 0.123);
  result = runCli("verify " + dir);
  EXPECT_EQ(result.exitCode, 3) << result.output;
  EXPECT_NE(result.output.find("/designs "), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("CORRUPTED: its values do not match its content hash"), std::string::npos)
      << result.output;
  EXPECT_NE(result.output.find("/state/mma_low "), std::string::npos) << result.output;  // still listed

  stripChecksums(path);  // format 1: plausible, but cannot be verified
  setValueWithPlainHdf5(path, "designs", 80 + 5, 0.5);
  result = runCli("verify " + dir);
  EXPECT_EQ(result.exitCode, 0) << result.output;
  EXPECT_NE(result.output.find("could not be verified"), std::string::npos) << result.output;

  result = runCli("verify " + dir + "/missing");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("missing"), std::string::npos) << result.output;
  result = runCli("verify " + fs::path(dir).parent_path().string());  // a directory without results.h5
  EXPECT_EQ(result.exitCode, 2) << result.output;
  std::ofstream(dir + "/results.h5", std::ios::trunc) << "not hdf5";
  result = runCli("verify " + dir);
  EXPECT_EQ(result.exitCode, 3) << result.output;
}

TEST(OptimizeCommand, ASecondRunIntoALockedDirectoryExitsTwoNamingTheHolder) {
  const std::string dir = freshDirectory("cli_locked");
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  const OptimizationRun holder(coarseConfig("psi1", 1), options);  // this process holds DIR/.lock
  const CliResult result = runCli("optimize " + kCoarseFlags + " --iterations 1 --out " + dir);
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("'" + dir + "' is in use"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("pid " + std::to_string(::getpid())), std::string::npos) << result.output;
  EXPECT_EQ(result.output.find("iter "), std::string::npos) << result.output;
}

// A full disk, simulated by a file-size limit (RLIMIT_FSIZE: write(2) fails with EFBIG as it would
// with ENOSPC) that the results file of some iteration exceeds: exit 3 naming the file, the file of
// the iteration before stays complete, no temporary is left, and a resume finishes the run as if
// nothing had happened.
TEST(OptimizeCommand, AFullDiskExitsThreeAndKeepsTheLastCompleteResults) {
  const ResultsData& reference = referenceResults(coarseConfig("psi1", 6), "psi1_6");
  const std::string dir = freshDirectory("cli_full");
  fs::create_directories(dir);
  // The size of the file after k iterations (same structure, same size; HDF5 allocates in blocks,
  // so it grows in steps): the limit goes into the first step after the first iteration.
  std::vector<std::uintmax_t> sizes(1, 0);
  for (std::size_t rows = 1; rows <= 6; ++rows) {
    ResultsData partial = reference;
    partial.history.resize(rows);
    partial.densities.resize(rows);
    partial.finished = false;
    partial.finalModes.resize(partial.finalModes.rows(), 0);
    partial.finalFrequenciesHz.clear();
    const std::string probe = dir + "/probe.h5";
    writeResultsFile(probe, partial);
    sizes.push_back(fs::file_size(probe));
    fs::remove(probe);
  }
  int failing = 2;
  while (failing <= 6 && sizes[failing] == sizes[failing - 1]) ++failing;
  ASSERT_LE(failing, 6) << "the results file does not grow over 6 iterations";
  const rlim_t limit = (sizes[failing - 1] + sizes[failing]) / 2;
  const std::string log = dir + ".log";
  std::cout.flush();
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const rlimit fileSize{limit, limit};
    setrlimit(RLIMIT_FSIZE, &fileSize);
    signal(SIGXFSZ, SIG_IGN);  // a failed write, not a killed process
    if (!std::freopen(log.c_str(), "w", stdout) || dup2(fileno(stdout), 2) < 0) std::_Exit(100);
    const std::string command =
        std::string(HINDSIGHT_CLI_PATH) + " optimize " + kCoarseFlags + " --iterations 6 --out " + dir;
    execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    std::_Exit(101);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  std::ifstream logFile(log);
  const std::string output((std::istreambuf_iterator<char>(logFile)), std::istreambuf_iterator<char>());
  ASSERT_TRUE(WIFEXITED(status)) << output;
  EXPECT_EQ(WEXITSTATUS(status), 3) << output;
  EXPECT_NE(output.find("storage failure"), std::string::npos) << output;
  EXPECT_NE(output.find(dir + "/results.h5"), std::string::npos) << output;
  EXPECT_EQ(completedIterationsWithPlainHdf5(dir + "/results.h5", 20, 4), failing - 1);
  EXPECT_FALSE(hasTemporaries(dir + "/results.h5"));
  EXPECT_EQ(runCli("verify " + dir).exitCode, 0);
  const CliResult resumed = runCli("optimize --resume --out " + dir);
  ASSERT_EQ(resumed.exitCode, 0) << resumed.output;
  ResultsData finished = readResultsFile(dir + "/results.h5");
  finished.configurationJson = reference.configurationJson;
  expectSameResults(finished, reference);
}
#endif

// ---- GCMMA, frequency guard, projection, geometry export ----

TEST(TopologyOptimizer, GcmmaHistoryOnTheRodNeverIncreasesAndEveryAcceptedDesignIsFeasible) {
  Config config = coarseConfig("psi1", 6);
  config.optimization.method = "gcmma";
  config.optimization.moveLimit = 0.5;  // the standard move limit, with which MMA needs step-backs here
  TopologyOptimizer optimizer(config);
  std::vector<IterationRecord> history;
  while (!optimizer.finished()) history.push_back(optimizer.step());
  ASSERT_EQ(history.size(), 7u);
  for (std::size_t k = 0; k < history.size(); ++k) {
    std::cout << progressLine(history[k]) << '\n';
    EXPECT_EQ(history[k].backtracks, 0) << k;
    if (k + 1 < history.size()) EXPECT_GE(history[k].innerIterations, 1) << k;
    if (k == 0) continue;
    // x0 is infeasible (V/V0 = 0.55); every accepted design satisfies the volume bound (to the
    // conservativeness tolerance) and, from the first feasible one on, psi1 never increases.
    EXPECT_LE(history[k].volumeFraction, 0.5 * (1.0 + 1e-7)) << k;
    if (k >= 2) EXPECT_LE(history[k].psi1, history[k - 1].psi1) << k;
  }
  EXPECT_LT(history.back().psi1, 0.8 * history.front().psi1);
  EXPECT_EQ(history.back().innerIterations, 0);  // the final evaluation makes no update
}

TEST(OptimizationRun, GcmmaExitAfterAnIterationThenResumeIsBitIdenticalAndExportsTheGeometry) {
  Config config = coarseConfig("psi1", 4);
  config.optimization.method = "gcmma";
  const ResultsData& reference = referenceResults(config, "gcmma_4");
  const std::string dir = freshDirectory("exit_gcmma");
  EXPECT_FALSE(runInChild(config, dir, 1));
  OptimizationRunOptions options;
  options.outputDirectory = dir;
  options.resume = true;
  const OptimizationRunSummary summary = runQuietly(config, options);
  EXPECT_EQ(summary.resumedFrom, 2);
  const ResultsData resumed = readResultsFile(dir + "/results.h5");
  expectSameResults(resumed, reference);
  for (std::size_t k = 0; k < resumed.history.size(); ++k) {
    EXPECT_EQ(resumed.history[k].innerIterations, reference.history[k].innerIterations) << k;
    EXPECT_TRUE(sameBits(resumed.history[k].grayness, reference.history[k].grayness)) << k;
    EXPECT_TRUE(sameBits(resumed.history[k].firstFrequencyHz, reference.history[k].firstFrequencyHz)) << k;
    EXPECT_GE(resumed.history[k].grayness, 0.0);
    EXPECT_GT(resumed.history[k].firstFrequencyHz, 0.0);
  }
  // The final design's geometry is written by every run; its outline encloses the solid fraction.
  for (const char* file : {"design_final.svg", "design_final.dxf", "design_final.stl"})
    EXPECT_TRUE(fs::exists(dir + "/" + file)) << file;
  const Vector& grid = resumed.densities.back();
  DensityField field;
  field.nx = resumed.nx;
  field.ny = resumed.ny;
  field.values = grid;
  field.cellWidthMm = 1000.0 * config.rod.length / field.nx;
  field.cellHeightMm = 1000.0 * config.rod.height / field.ny;
  int solid = 0;
  for (Eigen::Index e = 0; e < grid.size(); ++e) solid += grid(e) >= 0.5 ? 1 : 0;
  const double cell = field.cellWidthMm * field.cellHeightMm;
  EXPECT_NEAR(contourOutline(field, 0.5).area(), solid * cell, field.nx * cell);
}

#ifdef HINDSIGHT_CLI_PATH
TEST(ExportCommand, WritesAnyIterationAndRefusesToOverwriteWithoutForce) {
  const std::string dir = freshDirectory("cli_export");
  CliResult result = runCli("optimize " + kCoarseFlags + " --iterations 2 --out " + dir);
  ASSERT_EQ(result.exitCode, 0) << result.output;
  EXPECT_NE(result.output.find("  gray "), std::string::npos) << result.output;
  // design_final.* exist from the run: no overwrite without --force.
  result = runCli("export " + dir + " --iso 0.4");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("--force"), std::string::npos) << result.output;
  result = runCli("export " + dir + " --iso 0.4 --force");
  EXPECT_EQ(result.exitCode, 0) << result.output;
  result = runCli("export " + dir + " --iteration 1");
  ASSERT_EQ(result.exitCode, 0) << result.output;
  for (const char* file : {"design_iter_1.svg", "design_iter_1.dxf", "design_iter_1.stl"})
    EXPECT_TRUE(fs::exists(dir + "/" + file)) << file;
  result = runCli("export " + dir + " --iteration 7");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("--iteration"), std::string::npos) << result.output;
  result = runCli("export " + dir + " --iso 1.5 --force");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("--iso"), std::string::npos) << result.output;
}
#endif

TEST(TopologyOptimizer, ChainThroughFilterAndProjectionMatchesFiniteDifferences) {
  Config config = coarseConfig("psi1", 3);
  config.optimization.filterRadius = 1.5;
  config.optimization.projectionBeta = 4.0;
  config.optimization.projectionBetaMax = 16.0;
  config.optimization.projectionEvery = 2;
  const TopologyOptimizer optimizer(config);
  const int n = optimizer.designCount();
  std::mt19937 generator(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Vector x(n), w(n);
  for (int d = 0; d < n; ++d) {
    x(d) = 0.05 + 0.9 * unit(generator);
    w(d) = unit(generator) - 0.5;
  }
  for (int iteration : {0, 3}) {  // beta 4 and 8
    // phi(x) = sum_d w_d m_d(x)^2 with m the model design: d phi / dm = 2 w m.
    auto phi = [&](const Vector& v) { return w.dot(optimizer.modelDesign(v, iteration).cwiseAbs2()); };
    const Vector m = optimizer.modelDesign(x, iteration);
    const Vector gradient = optimizer.chainToDesign(2.0 * w.cwiseProduct(m), x, iteration);
    const double h = 1e-6;
    double worst = 0.0;
    for (int d = 0; d < n; ++d) {
      Vector plus = x, minus = x;
      plus(d) += h;
      minus(d) -= h;
      worst = std::max(worst, std::abs((phi(plus) - phi(minus)) / (2.0 * h) - gradient(d)));
    }
    EXPECT_LT(worst, 1e-7 * gradient.cwiseAbs().maxCoeff()) << "iteration " << iteration;
  }
  // Continuation: beta0 2^floor(k / every), capped.
  EXPECT_EQ(HeavisideProjection::continuationBeta(4.0, 16.0, 2, 0), 4.0);
  EXPECT_EQ(HeavisideProjection::continuationBeta(4.0, 16.0, 2, 3), 8.0);
  EXPECT_EQ(HeavisideProjection::continuationBeta(4.0, 16.0, 2, 100), 16.0);
  // The projection pushes the filtered densities toward 0 and 1: less gray than the filter alone.
  Config filterOnly = config;
  filterOnly.optimization.projectionBeta = 0.0;
  const TopologyOptimizer plain(filterOnly);
  EXPECT_LT(grayness(optimizer.modelDesign(x, 100)), grayness(plain.modelDesign(x, 100)));
  EXPECT_GE(optimizer.modelDesign(x, 0).minCoeff(), config.rod.designLowerBound);
  EXPECT_LE(optimizer.modelDesign(x, 0).maxCoeff(), 1.0);
}

TEST(TopologyOptimizer, ProjectedRunDecreasesPsi1AndGetsCrisper) {
  Config config = coarseConfig("psi1", 8);
  config.optimization.filterRadius = 1.5;
  config.optimization.projectionBeta = 2.0;
  config.optimization.projectionEvery = 3;
  TopologyOptimizer optimizer(config);
  std::vector<IterationRecord> history;
  while (!optimizer.finished()) history.push_back(optimizer.step());
  EXPECT_LT(history.back().psi1, history.front().psi1);
  EXPECT_LE(history.back().volumeFraction, 0.5 + 1e-6);
  EXPECT_LT(history.back().grayness, history[1].grayness);
}

// The guard at work: x0 of the coarse rod has f1 = 36.6 Hz and the unguarded run ends at 66 Hz; a bound of
// 70 Hz is violated throughout and
// MMA restores it while it reduces psi1 (constraint value and derivative from eigen_constraint.h).
// (On the divergence test's configuration the guard does not remove the step-back: the design that
// diverges there has f1 = 8 Hz, so its divergence is not a low-frequency mechanism; on the 200 x 12
// rod of the paper it is, see docs/tutorials/topology_optimization.md, "Robustness options".)
TEST(TopologyOptimizer, FrequencyGuardRestoresAViolatedFirstFrequencyBound) {
  Config config = coarseConfig("psi1", 8);
  config.optimization.minFirstFrequency = 70.0;
  TopologyOptimizer optimizer(config);
  std::vector<IterationRecord> history;
  while (!optimizer.finished()) history.push_back(optimizer.step());
  for (const IterationRecord& r : history)
    std::cout << progressLine(r) << "  f1 " << r.firstFrequencyHz << " Hz\n";
  EXPECT_LT(history.front().firstFrequencyHz, 70.0);
  EXPECT_GE(history.back().firstFrequencyHz, 70.0 * (1.0 - 1e-3));
  EXPECT_LT(history.back().psi1, history.front().psi1);
  // Both constraints are active now; with move limit 0.1 the volume settles more slowly (3 % over
  // after 8 iterations).
  EXPECT_LE(history.back().volumeFraction, 0.5 * 1.03);
  // Without the guard the same run ends below the bound: the constraint is what holds it.
  config.optimization.minFirstFrequency = 0.0;
  TopologyOptimizer unguarded(config);
  IterationRecord last;
  while (!unguarded.finished()) last = unguarded.step();
  EXPECT_LT(last.firstFrequencyHz, 70.0);
}

}  // namespace
}  // namespace hindsight
