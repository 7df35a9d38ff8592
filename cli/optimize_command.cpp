// `hindsight optimize`: topology optimization of the piston rod (docs/design.md §7) into an output
// directory: DIR/results.h5 (crash-safe, resumable), progress lines on stdout, design pictures.
// Every input is checked before the first evaluation; bad input exits with code 2.
#include <hindsight/problems/topopt/optimization_run.h>
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
  std::string objective;
  int iterations = -1;         // -1: from the configuration
  double filterRadius = -1.0;  // < 0: from the configuration
  int pictureEvery = -1;
  double moveLimit = -1.0;  // <= 0: from the configuration
  std::string outputDirectory = "results";
  bool resume = false;
  bool force = false;
};

template <typename T>
std::string jsonText(const T& value) {
  return nlohmann::json(value).dump();
}

Config buildConfig(const OptimizeSettings& s) {
  Config config;
  const std::string stored = (std::filesystem::path(s.outputDirectory) / "results.h5").string();
  if (!s.configFile.empty()) {
    config = readConfigFile(s.configFile);
  } else if (s.resume && std::filesystem::exists(stored)) {
    // Resuming without --config continues the stored configuration.
    config = configFromJson(nlohmann::json::parse(readResultsConfiguration(stored)));
  }
  for (const std::string& assignment : s.settings) applySetting(config, assignment);
  if (!s.objective.empty()) applySetting(config, "optimization.objective=" + jsonText(s.objective));
  if (s.iterations >= 0) applySetting(config, "optimization.iterations=" + jsonText(s.iterations));
  if (s.filterRadius >= 0.0) applySetting(config, "optimization.filterRadius=" + jsonText(s.filterRadius));
  if (s.moveLimit > 0.0) applySetting(config, "optimization.moveLimit=" + jsonText(s.moveLimit));
  if (s.pictureEvery >= 0) applySetting(config, "optimization.pictureEvery=" + jsonText(s.pictureEvery));
  config.validate();
  return config;
}

int runOptimize(const OptimizeSettings& s) {
  const Config config = buildConfig(s);
  OptimizationRunOptions options;
  options.outputDirectory = s.outputDirectory;
  options.resume = s.resume;
  options.force = s.force;
  OptimizationRun run(config, options);  // all remaining input checks, before any work

  const rod::RodConfig& rc = config.rod;
  std::cout << "optimize " << config.optimization.objective << ": " << rc.elementsAlongLength << " x "
            << rc.elementsThroughHeight << " elements, " << rc.designCount() << " design variables, "
            << config.optimization.iterations << " iterations, V/V0 <= " << config.optimization.volumeFraction
            << ", filter radius " << config.optimization.filterRadius << ", move limit "
            << config.optimization.moveLimit << "; results in " << run.resultsPath()
            << (run.resumedIterations() > 0
                    ? " (resumed after " + std::to_string(run.resumedIterations()) + " iterations)"
                    : std::string())
            << std::endl;
  const OptimizationRunSummary summary = run.run(std::cout);
  if (!summary.history.empty()) {
    const IterationRecord& first = summary.history.front();
    const IterationRecord& last = summary.history.back();
    std::cout << std::setprecision(6) << "psi1: " << first.psi1 << " -> " << last.psi1
              << ", psi2: " << first.psi2 << " -> " << last.psi2 << ", V/V0 " << last.volumeFraction << "; "
              << summary.history.size() << " evaluations, " << std::setprecision(4) << summary.wallSeconds
              << " s in this invocation\n";
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
  command->add_option("--objective", s->objective,
                      "psi1 (integral compliance) | psi2 (equivalent static loads)");
  command->add_option("--iterations", s->iterations, "MMA iterations (default: optimization.iterations, 50)");
  command->add_option("--filter-radius", s->filterRadius,
                      "density filter radius in elements; 0 = none (default, the paper's choice)");
  command->add_option(
      "--move-limit", s->moveLimit,
      "MMA move limit in (0, 1] (default optimization.moveLimit, 0.5, Svanberg's standard value)");
  command->add_option("--picture-every", s->pictureEvery,
                      "a design picture every K iterations; 0 = final only");
  command->add_option("--out", s->outputDirectory, "output directory")->capture_default_str();
  command->add_flag("--resume", s->resume, "continue DIR/results.h5");
  command->add_flag("--force", s->force, "overwrite DIR/results.h5");
  commands().push_back({command, [s] { return guarded([&] { return runOptimize(*s); }); }});
}

}  // namespace hindsight::cli
