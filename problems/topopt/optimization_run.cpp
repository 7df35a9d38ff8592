#include <hindsight/problems/topopt/optimization_run.h>
#include <hindsight/problems/topopt/run_fingerprint.h>

#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/topopt/communicator.h>
#include <hindsight/problems/topopt/geometry_export.h>
#include <hindsight/problems/topopt/pictures.h>
#include <hindsight/storage/atomic_file.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <stdexcept>

namespace hindsight {
namespace {

namespace fs = std::filesystem;

// Creates the directory and proves that a file can be written in it.
void prepareDirectory(const std::string& directory) {
  if (directory.empty()) throw std::invalid_argument("--out: the output directory name is empty");
  std::error_code error;
  fs::create_directories(directory, error);
  if (error) {
    throw std::invalid_argument("--out '" + directory +
                                "': cannot create the output directory: " + error.message());
  }
  if (!fs::is_directory(directory, error)) {
    throw std::invalid_argument("--out '" + directory + "' exists and is not a directory");
  }
  const std::string probe = (fs::path(directory) / (".write-probe-" + std::to_string(::getpid()))).string();
  bool written = false;
  {
    std::ofstream file(probe, std::ios::binary | std::ios::trunc);
    file << "probe\n";
    file.flush();
    written = static_cast<bool>(file);
  }
  std::remove(probe.c_str());
  if (!written)
    throw std::invalid_argument("--out '" + directory + "': the output directory is not writable");
}

// The configuration as JSON without the fields a resumed run may change.
nlohmann::json comparable(nlohmann::json json) {
  json["optimization"].erase("iterations");
  json["optimization"].erase("pictureEvery");
  return json;
}

void requireSameConfiguration(const Config& requested, const std::string& storedJson,
                              const std::string& path) {
  nlohmann::json stored;
  try {
    stored = comparable(toJson(configFromJson(nlohmann::json::parse(storedJson))));
  } catch (const std::exception& e) {
    throw StorageError(std::string("results file: the stored configuration cannot be read: ") + e.what(),
                       path);
  }
  const nlohmann::json wanted = comparable(toJson(requested));
  if (stored == wanted) return;
  // Every differing field, including one present on one side only (a scenarios list added or removed).
  std::string differences;
  for (const std::string& field : differingFields(wanted, stored)) {
    std::string pointerText = "/" + field;
    std::replace(pointerText.begin(), pointerText.end(), '.', '/');
    const nlohmann::json::json_pointer pointer(pointerText);
    const auto valueIn = [&](const nlohmann::json& j) {
      return j.contains(pointer) ? j.at(pointer).dump() : std::string("absent");
    };
    differences += (differences.empty() ? "" : ", ") + field + " (requested " + valueIn(wanted) +
                   ", stored " + valueIn(stored) + ")";
  }
  throw std::invalid_argument("--resume: the configuration differs from the one stored in " + path + ": " +
                              differences +
                              "; only optimization.iterations and optimization.pictureEvery may change");
}

}  // namespace

int bestFeasibleIndex(const std::vector<IterationRecord>& history, const Config& config) {
  const OptimizationSettings& settings = config.optimization;
  const bool usePsi1 = settings.objective == Objective::Psi1;
  const std::vector<ScenarioCase> cases = scenarioCases(config);
  const auto objective = [&](const IterationRecord& r) {
    if (config.scenarios.empty()) return usePsi1 ? r.psi1 : r.psi2;
    const std::vector<double>& values = usePsi1 ? r.scenarioPsi1 : r.scenarioPsi2;
    const std::vector<double>& initial =
        usePsi1 ? history.front().scenarioPsi1 : history.front().scenarioPsi2;
    double aggregate = 0.0;
    for (std::size_t s = 0; s < cases.size() && s < values.size() && s < initial.size(); ++s) {
      const double relative = cases[s].weight * values[s] / initial[s];
      aggregate = settings.aggregate == Aggregate::Max ? std::max(aggregate, relative) : aggregate + relative;
    }
    return aggregate;
  };
  int best = -1;
  for (std::size_t k = 0; k < history.size(); ++k) {
    if (!TopologyOptimizer::feasible(TopologyOptimizer::recordConstraints(history[k], settings))) continue;
    // Ties go to the later record: a run that reached the cap ends with a second evaluation of its best
    // design, which is then the final and the best one.
    if (best < 0 || objective(history[k]) <= objective(history[static_cast<std::size_t>(best)]))
      best = static_cast<int>(k);
  }
  return best;
}

std::string progressLine(const IterationRecord& r, const std::vector<std::string>& scenarioNames) {
  char change[32];
  if (std::isnan(r.maxDesignChange)) {
    std::snprintf(change, sizeof change, "%5s", "final");
  } else {
    std::snprintf(change, sizeof change, "%5.3f", r.maxDesignChange);
  }
  char line[200];
  std::snprintf(line, sizeof line, "iter %3d  psi1 %.4f  psi2 %.4f  V/V0 %.4f  max|dx| %s  %.1f s",
                r.iteration, r.psi1, r.psi2, r.volumeFraction, change, r.totalSeconds);
  std::string text = line;
  if (!std::isnan(r.grayness)) {
    char gray[32];
    std::snprintf(gray, sizeof gray, "  gray %.3f", r.grayness);
    text += gray;
  }
  if (!std::isnan(r.kktResidual)) {
    char kkt[32];
    std::snprintf(kkt, sizeof kkt, "  kkt %.1e", r.kktResidual);
    text += kkt;
  }
  if (r.converged) text += "  converged (final design)";
  if (r.innerIterations > 0) text += "  (" + std::to_string(r.innerIterations) + " GCMMA trials)";
  if (r.worstScenario >= 0 && static_cast<std::size_t>(r.worstScenario) < scenarioNames.size())
    text += "  worst: " + scenarioNames[static_cast<std::size_t>(r.worstScenario)];
  if (r.backtracks > 0)
    text += "  (" + std::to_string(r.backtracks) + " halvings after a diverged simulation)";
  return text;
}

OptimizationRun::OptimizationRun(const Config& config, const OptimizationRunOptions& options)
    : config_(config), options_(options), root_(Communicator::world().isRoot()), optimizer_(config) {
  if (options.resume && options.force) {
    throw std::invalid_argument(
        "--resume and --force exclude each other: continue the results or overwrite them");
  }
  if (options.pixelsPerElement < 1) throw std::invalid_argument("pixels per element must be >= 1");
  resultsPath_ = (fs::path(options.outputDirectory) / "results.h5").string();
  // With several ranks (problems/topopt/communicator.h) rank 0 owns the directory: it alone locks,
  // cleans and writes; the other ranks only read the results file to resume.
  if (root_) {
    prepareDirectory(options.outputDirectory);
    lock_ = std::make_unique<DirectoryLock>(options.outputDirectory, "--out");
    // Garbage of a crash during a write (results file or picture); with the lock held no other run
    // writes here.
    removeStaleTemporariesIn(options.outputDirectory);
  }

  const rod::RodConfig& rc = config_.rod;
  const bool exists = fs::exists(resultsPath_);
  if (exists && !options.resume && !options.force && root_) {
    throw std::invalid_argument(resultsPath_ +
                                " exists; use --resume to continue it or --force to overwrite it");
  }
  if (exists && options.resume) {
    data_ = readResultsFile(resultsPath_);  // every check; throws StorageError naming the dataset
    resumedUnverified_ = !data_.checksummed;
    requireSameConfiguration(config_, data_.configurationJson, resultsPath_);
    const int done = data_.state.iteration;
    if (config_.optimization.iterations < done) {
      throw std::invalid_argument(
          "optimization.iterations = " + std::to_string(config_.optimization.iterations) + " is below the " +
          std::to_string(done) + " iterations already in " + resultsPath_);
    }
    const std::size_t expectedRows = static_cast<std::size_t>(done) + (data_.finished ? 1 : 0);
    if (data_.history.size() != expectedRows || data_.nx != rc.elementsAlongLength ||
        data_.ny != rc.elementsThroughHeight) {
      throw StorageError("results file: inconsistent history (" + std::to_string(data_.history.size()) +
                             " rows after " + std::to_string(done) + " updates)",
                         resultsPath_);
    }
    optimizer_.restore(data_.state);  // checks the sizes against the configuration
    if (data_.finished && config_.optimization.iterations > done) {
      // The final evaluation made no update; a longer run redoes it as an ordinary iteration.
      data_.history.pop_back();
      data_.densities.pop_back();
      data_.finished = false;
      data_.finalModes.resize(0, 0);
      data_.finalFrequenciesHz.clear();
    }
  } else {
    data_ = ResultsData{};
    data_.nx = rc.elementsAlongLength;
    data_.ny = rc.elementsThroughHeight;
    data_.state = optimizer_.state();
  }
  data_.configurationJson = toJson(config_).dump();
  data_.configurationFingerprint = configurationFingerprint(config_);
  data_.ranks = Communicator::world().size();
  if (!config_.scenarios.empty()) {
    for (const Scenario& s : config_.scenarios) scenarioNames_.push_back(s.name);
  }
}

void OptimizationRun::writePictures(const std::string& stem, const Vector& grid) const {
  const rod::RodConfig& rc = config_.rod;
  const fs::path base = fs::path(options_.outputDirectory) / stem;
  writeDensityPng(base.string() + ".png", rc.elementsAlongLength, rc.elementsThroughHeight, grid,
                  options_.pixelsPerElement);
  writeDensityVtk(base.string() + ".vtk", rc.elementsAlongLength, rc.elementsThroughHeight, grid,
                  rc.length / rc.elementsAlongLength);
}

OptimizationRunSummary OptimizationRun::run(std::ostream& progress) {
  const Stopwatch runTimer;
  OptimizationRunSummary summary;
  summary.resumedFrom = static_cast<int>(data_.history.size());
  summary.resultsPath = resultsPath_;
  if (resumedUnverified_) {
    progress << "warning: " << resultsPath_
             << " has no checksums (written before format 2); its values were checked for plausibility "
                "only; the next write adds checksums"
             << std::endl;
  }
  for (const IterationRecord& record : data_.history)
    progress << progressLine(record, scenarioNames_) << "  (stored)\n";
  if (data_.finished) {
    progress << "the run in " << resultsPath_ << " is finished; nothing to do" << std::endl;
  }
  const int pictureEvery = config_.optimization.pictureEvery;
  while (!data_.finished) {
    const Stopwatch iterationTimer;
    IterationRecord record = optimizer_.step();
    const Vector grid = optimizer_.densityGrid(optimizer_.lastEvaluatedDesign());
    data_.state = optimizer_.state();
    data_.finished = optimizer_.finished();
    if (data_.finished && optimizer_.lastEvaluation()) {  // rank 0 always has it (scenario 0)
      const PistonRodEvaluation& evaluation = *optimizer_.lastEvaluation();
      data_.finalModes = evaluation.modes;
      data_.finalFrequenciesHz = evaluation.frequenciesHz;
    }
    data_.history.push_back(record);
    data_.densities.push_back(grid);
    std::exception_ptr error;
    if (root_) {
      try {
        // Pictures before the results file: after a crash in between, the resumed run rewrites them.
        if (pictureEvery > 0 && record.iteration % pictureEvery == 0) {
          writePictures("design_iter_" + std::to_string(record.iteration), grid);
        }
        if (data_.finished) {
          writePictures("design_final", grid);
          // The best feasible design, when the last one is not it (a run that ended at its
          // iteration limit rather than by the convergence rule can end above its best).
          const int best = bestFeasibleIndex(data_.history, config_);
          if (best >= 0 && static_cast<std::size_t>(best) + 1 != data_.history.size())
            writePictures("design_best", data_.densities[static_cast<std::size_t>(best)]);
          // The geometry for CAD: outline at density 0.5 (SVG, DXF) and the extruded solid (STL); of the
          // solid member its surface (STL) and densities (VTU).
          if (config_.rod.isSolid()) {
            exportSolidGeometry((fs::path(options_.outputDirectory) / "design_final").string(),
                                optimizer_.solidField(optimizer_.lastEvaluatedDesign(), record.iteration),
                                0.5);
          } else {
            DensityField field;
            field.nx = config_.rod.elementsAlongLength;
            field.ny = config_.rod.elementsThroughHeight;
            field.values = grid;
            field.cellWidthMm = 1000.0 * config_.rod.length / field.nx;
            field.cellHeightMm = 1000.0 * config_.rod.height / field.ny;
            exportGeometry((fs::path(options_.outputDirectory) / "design_final").string(), field, 0.5,
                           1000.0 * config_.rod.thickness);
          }
        }
        data_.history.back().totalSeconds = record.totalSeconds = iterationTimer.seconds();
        writeResultsFile(resultsPath_, data_);
      } catch (...) {
        error = std::current_exception();
      }
    }
    Communicator::world().agree(error);  // a failed write stops every rank
    progress << progressLine(record, scenarioNames_) << std::endl;
    if (options_.afterCommit) options_.afterCommit(record);
  }
  summary.history = data_.history;
  summary.finished = data_.finished;
  summary.wallSeconds = runTimer.seconds();
  return summary;
}

}  // namespace hindsight
