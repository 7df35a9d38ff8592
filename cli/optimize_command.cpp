// `hindsight optimize`: topology optimization of the piston rod (docs/design.md §7) into an output
// directory: DIR/results.h5 (crash-safe, resumable), progress lines on stdout, design pictures.
// Every input is checked before the first evaluation; bad input exits with code 2.
#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/topopt/communicator.h>
#include <hindsight/problems/topopt/optimization_run.h>
#include <hindsight/problems/topopt/run_fingerprint.h>
#include "commands.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

namespace hindsight::cli {
namespace {

struct OptimizeSettings {
  std::string configFile;
  std::vector<std::string> settings;
  ConfigFlags flags;  // --objective, --iterations, ...: applied after --set
  std::string outputDirectory = "results";
  bool resume = false;
  bool force = false;
  int threads = 0;  // 0: not given, the cores available
  CLI::Option* threadsOption = nullptr;
};

Config buildConfig(const OptimizeSettings& s) {
  Config config;
  const std::string stored = (std::filesystem::path(s.outputDirectory) / "results.h5").string();
  if (s.resume && !s.force && !std::filesystem::exists(stored)) {  // both: OptimizationRun says they exclude
    // Without this, a mistyped --out would start a fresh run of the configured length.
    throw std::invalid_argument("--resume: there is no " + stored +
                                " to continue (check --out, or start a new run without --resume)");
  }
  if (!s.configFile.empty()) {
    config = readConfigFile(s.configFile);
  } else if (s.resume && std::filesystem::exists(stored)) {
    // Resuming without --config continues the stored configuration.
    config = configFromJson(nlohmann::json::parse(readResultsConfiguration(stored)));
  }
  // Every --set and flag first, then the checks across fields once (their order does not matter).
  for (const std::string& assignment : s.settings) applySetting(config, assignment, /*validate=*/false);
  s.flags.apply(config);
  config.validate();
  if (config.simulation.adaptive) {
    // Every iteration records psi2 (and optimizes it for objective psi2); its load times must be
    // grid points of a fixed-step grid.
    throw std::invalid_argument(
        "config field 'simulation.adaptive' = true: optimize evaluates psi2 at every "
        "iteration (optimization.objective = " +
        toString(config.optimization.objective) +
        "), which needs fixed steps; set simulation.adaptive = false");
  }
  return config;
}

int runOptimize(const OptimizeSettings& s) {
  // Under mpirun every rank runs this; the checks below fail on every rank alike, and a check that
  // only rank 0 makes (the output directory) is agreed on before any collective work.
  const Communicator& world = Communicator::world();
  Config config;
  {
    // Each rank reads its own command line: its failure is agreed on (no rank left waiting), then
    // every rank checks that all ranks run the same configuration (problems/topopt/run_fingerprint.h).
    std::exception_ptr error;
    try {
      if (s.threadsOption->count() > 0 && s.threads < 1) {
        throw std::invalid_argument("--threads = " + std::to_string(s.threads) +
                                    " is outside the allowed range [1, inf)");
      }
      config = buildConfig(s);
    } catch (...) {
      error = std::current_exception();
    }
    world.agree(error);
    agreeOnConfiguration(world, config,
                         {{"out", std::filesystem::absolute(s.outputDirectory).lexically_normal().string()},
                          {"resume", s.resume},
                          {"force", s.force},
                          {"version", version()}});
  }
  const ThreadLimit threads(s.threads > 0 ? s.threads : availableThreads());
  OptimizationRunOptions options;
  options.outputDirectory = s.outputDirectory;
  options.resume = s.resume;
  options.force = s.force;
  std::unique_ptr<OptimizationRun> runPointer;
  std::exception_ptr error;
  try {
    runPointer = std::make_unique<OptimizationRun>(config, options);  // all remaining input checks
  } catch (...) {
    error = std::current_exception();
  }
  world.agree(error);
  OptimizationRun& run = *runPointer;
  std::ostream quiet(nullptr);  // ranks other than 0 print nothing
  std::ostream& out = world.isRoot() ? std::cout : quiet;

  const rod::RodConfig& rc = config.rod;
  if (!config.scenarios.empty() || world.parallel()) {
    out << "scenarios: " << (config.scenarios.empty() ? 1 : config.scenarios.size()) << " ("
        << toString(config.optimization.aggregate) << "), " << world.size() << " rank(s), "
        << (s.threads > 0 ? s.threads : availableThreads()) << " thread(s) per rank"
        << (threadsSupported() ? "" : " (built without TBB: 1)") << std::endl;
  }
  out << "optimize " << toString(config.optimization.objective) << ": " << rc.elementsAlongLength << " x "
      << rc.elementsThroughHeight
      << (rc.isSolid() ? " x " + std::to_string(rc.elementsThroughThickness) +
                             (rc.midPlaneSymmetry ? " (half, mid-plane symmetry) solid" : " solid")
                       : std::string())
      << " elements, " << rc.designCount() << " design variables, " << config.optimization.iterations
      << " iterations, V/V0 <= " << config.optimization.volumeFraction << ", filter radius "
      << config.optimization.filterRadius << ", move limit " << config.optimization.moveLimit
      << "; results in " << run.resultsPath()
      << (run.resumedIterations() > 0
              ? " (resumed after " + std::to_string(run.resumedIterations()) + " iterations)"
              : std::string())
      << std::endl;
  const OptimizationRunSummary summary = run.run(out);
  if (!summary.history.empty()) {
    const IterationRecord& first = summary.history.front();
    const IterationRecord& last = summary.history.back();
    out << std::setprecision(6) << "psi1: " << first.psi1 << " -> " << last.psi1 << ", psi2: " << first.psi2
        << " -> " << last.psi2 << ", V/V0 " << last.volumeFraction << "; " << summary.history.size()
        << " evaluations, " << std::setprecision(4) << summary.wallSeconds << " s in this invocation\n";
    if (summary.finished) {
      out << (last.converged
                  ? "stopped by the convergence rule at iteration " + std::to_string(last.iteration)
                  : "stopped after optimization.iterations = " +
                        std::to_string(config.optimization.iterations) + " updates");
      const int best = bestFeasibleIndex(summary.history, config);
      if (best >= 0) {
        const IterationRecord& b = summary.history[static_cast<std::size_t>(best)];
        out << std::setprecision(6) << "; best feasible design: iteration " << b.iteration << ", psi1 "
            << b.psi1 << ", V/V0 " << b.volumeFraction;
      } else {
        out << "; no design met the volume bound";
      }
      out << "\n";
    }
    if (!config.scenarios.empty() || world.parallel()) {
      const TopologyOptimizer::Times& t = run.optimizer().times();
      out << std::setprecision(4) << "rank 0: " << t.localSeconds << " s evaluating its scenarios, "
          << t.exchangeSeconds << " s in the exchange of results (waiting included; smallest "
          << t.smallestExchangeSeconds * 1e3 << " ms)\n";
    }
  }
  return 0;
}

}  // namespace

void registerOptimize(CLI::App& app) {
  auto s = std::make_shared<OptimizeSettings>();
  CLI::App* command = app.add_subcommand(
      "optimize",
      "Topology optimization of the piston rod (MMA; psi1 exact adjoint or psi2 equivalent static loads)");
  command->add_option("--config", s->configFile, "JSON configuration file (defaults: the paper's problem)");
  command->add_option("--set", s->settings, "section.field=value, applied after --config (repeatable)");
  for (const char* key : {"optimization.objective", "optimization.iterations", "optimization.filterRadius",
                          "optimization.moveLimit", "optimization.pictureEvery"})
    s->flags.add(command, key);
  command->add_option("--out", s->outputDirectory, "output directory")->capture_default_str();
  command->add_flag("--resume", s->resume, "continue DIR/results.h5");
  s->threadsOption = command->add_option(
      "--threads", s->threads,
      "threads per process, >= 1 (default: the cores available); results are bitwise the same "
      "for every count");
  command->add_flag("--force", s->force, "overwrite DIR/results.h5");
  command->footer(kConfigFieldsFooter);
  commands().push_back({command, [s] { return guarded([&] { return runOptimize(*s); }); }});
}

}  // namespace hindsight::cli
