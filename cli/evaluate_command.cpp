// `hindsight evaluate`: psi1, psi2, the volume fraction, the modes' frequencies and the run summary
// of one piston-rod design; with --gradient, also dpsi1/dx, dpsi2/dx and dV/dx into an HDF5 file.
// psi2 is skipped (and said so) with adaptive steps, which cannot place its load times.
#include <hindsight/problems/app/full_order_evaluation.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/rod/design_io.h>
#include <hindsight/problems/rod/full_order_rod.h>
#include <hindsight/problems/rod/parallel.h>
#include "commands.h"

#include <nlohmann/json.hpp>

#include <unistd.h>

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>

namespace hindsight::cli {
namespace {

struct EvaluateSettings {
  std::string configFile;
  std::vector<std::string> assignments;
  std::string designFile;
  std::string gradientFile;
  ConfigFlags flags;  // --storage, --integrator, --adjoint, --model: applied after --set
  bool force = false;
  bool json = false;
  bool printConfig = false;
  bool rodOnly = false;  // evaluate the rod section of a configuration with scenarios
  int threads = 0;       // 0: not given, the cores available
  CLI::Option* threadsOption = nullptr;
};

// The full-order model of docs/design.md §9: psi1,full, the volume fraction and the run summary (no psi2, no
// modes).
int runFullOrder(const Config& config, const PistonRod& rod, const Vector& design,
                 const EvaluateSettings& s) {
  const bool gradient = !s.gradientFile.empty();
  const rod::FullOrderRodEvaluation result = rod::evaluateFullOrderRod(config, design, gradient);
  if (gradient) {
    writeDesignFields(s.gradientFile, config.rod,
                      {{"dpsi1_dx", result.dpsi1}, {"dvolume_dx", result.dvolume}}, 0.0);
  }
  if (s.json) {
    nlohmann::json out;
    out["model"] = "full";
    out["psi1"] = result.psi1;
    out["volume_fraction"] = result.volumeFraction;
    out["state_size"] = result.stateSize;
    out["omega_max"] = result.omegaMax;
    out["n_design"] = rod.designCount();
    out["coupling"] = config.simulation.fullOrderCoupling;
    out["summary"] = summaryToJson(result.summary);
    out["seconds"] = {{"model", result.modelSeconds}, {"simulation", result.simulationSeconds}};
    if (gradient) out["gradient_file"] = s.gradientFile;
    std::cout << out.dump(2) << '\n';
    return 0;
  }
  std::cout << std::setprecision(8)
            << "model: full order (unreduced FE rod in the rigid mechanism's frame), coupling terms "
            << (config.simulation.fullOrderCoupling ? "kept" : "dropped") << "\npsi1 (full): " << result.psi1
            << "\nvolume fraction: " << result.volumeFraction << "\ndesign variables: " << rod.designCount()
            << "\nstate size: " << result.stateSize
            << "\nhighest FE frequency omega_max [rad/s]: " << result.omegaMax << '\n';
  if (gradient) std::cout << "gradients written to " << s.gradientFile << '\n';
  result.summary.print(std::cout);
  std::cout << "model seconds: " << result.modelSeconds << '\n';
  return 0;
}

/// The --gradient file is written only after the whole computation: refuse a path that cannot be
/// written, an existing file without --force, and the --design input always, before any work.
void checkGradientFile(const EvaluateSettings& s) {
  namespace fs = std::filesystem;
  if (s.gradientFile.empty()) return;
  const fs::path path(s.gradientFile);
  std::error_code error;
  if (!s.designFile.empty() && fs::exists(path, error) && fs::equivalent(path, s.designFile, error)) {
    throw std::invalid_argument("--gradient '" + s.gradientFile +
                                "' is the --design input; write the gradients to another file");
  }
  if (fs::is_directory(path, error))
    throw std::invalid_argument("--gradient '" + s.gradientFile + "' is a directory");
  if (fs::exists(path, error) && !s.force) {
    throw std::invalid_argument("--gradient '" + s.gradientFile + "' exists; use --force to overwrite it");
  }
  const fs::path directory = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (!fs::is_directory(directory, error)) {
    throw std::invalid_argument("--gradient '" + s.gradientFile + "': directory '" + directory.string() +
                                "' does not exist");
  }
  // The file is written to a temporary name in the same directory and renamed (storage/atomic_file.h).
  if (access(directory.c_str(), W_OK | X_OK) != 0) {
    throw std::invalid_argument("--gradient '" + s.gradientFile + "': directory '" + directory.string() +
                                "' is not writable");
  }
}

int runEvaluate(const EvaluateSettings& s) {
  if (s.threadsOption->count() > 0 && s.threads < 1)
    throw std::invalid_argument("--threads = " + std::to_string(s.threads) +
                                " is outside the allowed range [1, inf)");
  const ThreadLimit threads(s.threads > 0 ? s.threads : availableThreads());
  Config config = s.configFile.empty() ? Config{} : readConfigFile(s.configFile);
  // Every --set and flag first, then the checks across fields once (their order does not matter).
  for (const auto& assignment : s.assignments) applySetting(config, assignment, /*validate=*/false);
  s.flags.apply(config);
  // `--model full` alone: the full-order defaults (TR-BDF2, h = 1e-3 s; the model is far too stiff for
  // the reduced model's RK4 at 1e-4), unless the integrator or the step were chosen explicitly.
  if (s.flags.given("--model") && config.simulation.model == RodModel::Full && s.configFile.empty() &&
      !s.flags.given("--integrator")) {
    bool chosen = false;
    for (const auto& assignment : s.assignments) {
      chosen = chosen || assignment.rfind("simulation.integrator", 0) == 0 ||
               assignment.rfind("simulation.step", 0) == 0;
    }
    if (!chosen) {
      config.simulation.integrator = rod::kFullOrderDefaultIntegrator;
      config.simulation.step = rod::kFullOrderDefaultStep;
    }
  }
  config.validate();
  if (s.printConfig) {
    std::cout << toJson(config).dump(2) << '\n';
    return 0;
  }
  if (!config.scenarios.empty() && !s.rodOnly) {
    // evaluate runs one rod; silently evaluating the rod section would answer another question.
    throw std::invalid_argument(
        "config field 'scenarios' has " + std::to_string(config.scenarios.size()) +
        " scenarios, which evaluate does not run (it evaluates one rod): add --rod-only "
        "to evaluate the configuration's rod section, with --set rod.crankSpeed=... "
        "for one scenario's speed");
  }
  checkGradientFile(s);
  const PistonRod rod(config);
  const Vector design = s.designFile.empty() ? rod.initialDesign() : readDesignFile(s.designFile, config.rod);
  const bool gradient = !s.gradientFile.empty();
  if (config.simulation.model == RodModel::Full) return runFullOrder(config, rod, design, s);
  // psi2 samples the trajectory at load times that must be grid points: with adaptive steps it
  // cannot be computed, and psi1 (with its gradient) is still worth reporting.
  const std::string psi2Skipped =
      config.simulation.adaptive
          ? "psi2 needs fixed steps (its load times must be grid points) and simulation.adaptive = true"
          : "";
  const bool psi2 = psi2Skipped.empty();
  const PistonRodEvaluation result = rod.evaluate(design, {gradient, psi2, gradient && psi2});
  if (gradient) {
    std::vector<std::pair<std::string, Vector>> fields = {{"dpsi1_dx", result.dpsi1}};
    if (psi2) fields.emplace_back("dpsi2_dx", result.dpsi2);
    fields.emplace_back("dvolume_dx", result.dvolume);
    writeDesignFields(s.gradientFile, config.rod, fields, 0.0);
  }
  if (s.json) {
    nlohmann::json out;
    out["psi1"] = result.psi1;
    out["psi2"] = psi2 ? nlohmann::json(result.psi2) : nlohmann::json(nullptr);
    if (!psi2) out["psi2_skipped"] = psi2Skipped;
    out["volume_fraction"] = result.volumeFraction;
    out["frequencies_hz"] = result.frequenciesHz;
    out["gap_ratio"] = result.gapRatio;
    out["warning"] = result.warning;
    out["n_design"] = rod.designCount();
    out["summary"] = summaryToJson(result.summary);
    out["seconds"] = {{"model", result.modelSeconds},
                      {"simulation", result.simulationSeconds},
                      {"chain", result.chainSeconds},
                      {"esl", result.eslSeconds}};
    if (gradient) out["gradient_file"] = s.gradientFile;
    std::cout << out.dump(2) << '\n';
    return 0;
  }
  std::cout << std::setprecision(8) << "psi1: " << result.psi1 << "\npsi2: ";
  if (psi2) {
    std::cout << result.psi2;
  } else {
    std::cout << "skipped: " << psi2Skipped;
  }
  std::cout << "\nvolume fraction: " << result.volumeFraction << "\ndesign variables: " << rod.designCount()
            << "\nfrequencies [Hz]:";
  for (double f : result.frequenciesHz) std::cout << ' ' << f;
  std::cout << "\nspectral gap lambda_{n+1}/lambda_n: " << result.gapRatio << '\n';
  if (!result.warning.empty()) std::cout << "warning: " << result.warning << '\n';
  if (gradient) std::cout << "gradients written to " << s.gradientFile << '\n';
  result.summary.print(std::cout);
  std::cout << "model seconds: " << result.modelSeconds << "\nchain seconds: " << result.chainSeconds
            << "\nESL seconds: " << result.eslSeconds << '\n';
  return 0;
}

}  // namespace

void registerEvaluate(CLI::App& app) {
  auto s = std::make_shared<EvaluateSettings>();
  CLI::App* cmd =
      app.add_subcommand("evaluate", "psi1, psi2, volume fraction and frequencies of a piston-rod design");
  cmd->add_option("--config", s->configFile, "JSON configuration file (see --print-config)");
  cmd->add_option("--set", s->assignments, "section.field=value, e.g. rod.modeCount=12 (repeatable)");
  cmd->add_option(
      "--design", s->designFile,
      "HDF5 file with dataset x of shape (ny, nx), the solid's (nz, ny, nx); default: uniform x0");
  cmd->add_option(
      "--gradient", s->gradientFile,
      "write dpsi1_dx, dpsi2_dx, dvolume_dx (ny, nx), the solid's (nz, ny, nx), to this HDF5 file");
  cmd->add_flag("--force", s->force, "overwrite an existing --gradient file (never the --design input)");
  s->flags.add(cmd, "simulation.storage");
  s->flags.add(cmd, "simulation.integrator");
  s->flags.add(cmd, "simulation.adjoint");
  s->flags.add(cmd, "simulation.model",
               "; without --config, --integrator or --set simulation.integrator/step, full also selects "
               "trbdf2 with h = 1e-3 s");
  cmd->add_flag("--json", s->json, "exactly one JSON object on stdout");
  s->threadsOption = cmd->add_option(
      "--threads", s->threads,
      "threads, >= 1 (default: the cores available); results are bitwise the same for every count");
  cmd->add_flag("--print-config", s->printConfig, "print the complete configuration and exit");
  cmd->add_flag("--rod-only", s->rodOnly,
                "with a configuration that lists scenarios: evaluate its rod section (refused otherwise)");
  cmd->footer(kConfigFieldsFooter);
  commands().push_back({cmd, [s] { return guarded([&] { return runEvaluate(*s); }); }});
}

}  // namespace hindsight::cli
