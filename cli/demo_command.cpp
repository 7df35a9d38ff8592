// `hindsight demo`: the engine on a small problem with a known answer. Prints psi, the adjoint
// gradient, a finite-difference check of it and the run summary.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/storage_factory.h>
#include "commands.h"

#include <nlohmann/json.hpp>

#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

namespace hindsight::cli {
namespace {

struct DemoSettings {
  std::string problem = "pendulum";
  std::string method = "rk4";
  std::string storage = "full";
  double step = 1e-3;
  double endTime = 4.0;
  bool adaptive = false;
  double rtol = 1e-8;
  double atol = 1e-10;
  bool json = false;
};

std::unique_ptr<Problem> makeProblem(const std::string& name, Vector& p, double endTime) {
  if (name == "pendulum") {
    p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
    return std::make_unique<Pendulum>();
  }
  if (name == "oscillator") {
    p = Eigen::Vector3d(4.0, 0.4, 0.8);
    return std::make_unique<Oscillator>();
  }
  if (name == "robertson") {
    p = Robertson::nominalParameters();
    return std::make_unique<Robertson>(endTime);
  }
  throw std::invalid_argument("--problem = '" + name +
                              "' is unknown; known: pendulum, oscillator, robertson");
}

int runDemo(const DemoSettings& s) {
  Vector p;
  auto problem = makeProblem(s.problem, p, s.endTime);
  IntegratorOptions options;
  options.method = s.method;
  options.t1 = s.endTime;
  options.step = s.step;
  options.adaptive = s.adaptive;
  options.relativeTolerance = s.rtol;
  options.absoluteTolerance = s.atol;
  options.validate();
  auto storage = createStorage(s.storage);
  const GradientResult result = computeGradient(*problem, p, options, *storage);
  IntegratorOptions frozen = options;
  frozen.replayTimes = result.times;
  const auto check = checkGradient([&](const Vector& x) { return simulate(*problem, x, frozen).objective; },
                                   p, result.gradient, {1e-6});
  if (s.json) {
    nlohmann::json out;
    out["problem"] = problem->name();
    out["psi"] = result.objective;
    out["gradient"] =
        std::vector<double>(result.gradient.data(), result.gradient.data() + result.gradient.size());
    out["finite_difference"] = std::vector<double>(
        check.finiteDifference.data(), check.finiteDifference.data() + check.finiteDifference.size());
    out["max_relative_error"] = check.maxError;
    out["steps"] = result.summary.steps;
    out["recomputed_steps"] = result.summary.recomputedSteps;
    out["peak_bytes_in_memory"] = result.summary.peakBytesInMemory;
    std::cout << out.dump(2) << '\n';
  } else {
    std::cout << std::setprecision(12) << "problem: " << problem->name() << "\npsi: " << result.objective
              << '\n';
    std::cout << "   i        adjoint dpsi/dp    finite difference\n";
    for (Eigen::Index i = 0; i < p.size(); ++i) {
      std::cout << std::setw(4) << i << std::setw(22) << result.gradient(i) << std::setw(21)
                << check.finiteDifference(i) << '\n';
    }
    std::cout << "finite-difference check: " << (check.passed ? "passed" : "FAILED") << " (" << check.message
              << ")\n";
    result.summary.print(std::cout);
  }
  return check.passed ? 0 : 4;
}

}  // namespace

void registerDemo(CLI::App& app) {
  auto settings = std::make_shared<DemoSettings>();
  CLI::App* demo =
      app.add_subcommand("demo", "Gradient of a small engine problem, checked by finite differences");
  demo->add_option("--problem", settings->problem, "pendulum | oscillator | robertson")
      ->capture_default_str();
  demo->add_option("--integrator", settings->method, "rk4 | dopri5 | trbdf2 | sdirk2 | midpoint")
      ->capture_default_str();
  demo->add_option("--storage", settings->storage,
                   "trajectory storage spec, e.g. full, binomial:checkpoints=20")
      ->capture_default_str();
  demo->add_option("--step", settings->step, "fixed step (or first step when adaptive) [s]")
      ->capture_default_str();
  demo->add_option("--t1", settings->endTime, "end time [s]")->capture_default_str();
  demo->add_flag("--adaptive", settings->adaptive, "adaptive steps (dopri5, trbdf2)");
  demo->add_option("--rtol", settings->rtol, "relative tolerance (adaptive)")->capture_default_str();
  demo->add_option("--atol", settings->atol, "absolute tolerance (adaptive)")->capture_default_str();
  demo->add_flag("--json", settings->json, "one JSON object on stdout");
  commands().push_back({demo, [settings] { return guarded([&] { return runDemo(*settings); }); }});
}

}  // namespace hindsight::cli
