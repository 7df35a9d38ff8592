// Accuracy against cost of the three adjoint routes (docs/design.md §8): discrete (hindsight's
// integrator transposed), continuous (own backward dopri5 over the storage) and CVODES, on the
// nonlinear pendulum and on stiff Robertson kinetics, at several tolerances; for CVODES also
// Nd in {10, 100, 1000} and both interpolation types, configured as the CVODES user guide advises
// (Adams: fixed-point iteration; BDF: Newton with a dense direct solver), and on the pendulum the
// alternatives of bench::forEachCvodesVariant (Newton for Adams, GMRES for BDF, Anderson acceleration).
//
// Counters per benchmark: gradient_error (relative to a tight reference computed once, before any
// timing: the discrete adjoint of rk4 at h = 1e-4 for the pendulum, of adaptive trbdf2 at
// rtol = 1e-11 for Robertson, in log-scaled parameters k_i dpsi/dk_i), forward steps, rhs and
// Jacobian evaluations, check points / states stored. Each iteration is a complete gradient
// computation from scratch (new storage, new CVODES memory).
//
// Run: build/bench/adjoint_routes_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
//      --benchmark_out=bench/adjoint_routes.json --benchmark_out_format=json
// On Robertson the continuous route runs with the implicit backward trbdf2 (forward trbdf2, full
// storage): the default backward dopri5 is stability-limited on the stiff adjoint system (see
// engine/continuous_adjoint.h).
#include <hindsight/problems/app/gradient_routes.h>
#include <hindsight/problems/classic/classic_problems.h>
#include "bench_support.h"

#include <benchmark/benchmark.h>

#include <cstdio>
#include <memory>
#include <string>

namespace hindsight {
namespace {

struct Case {
  std::shared_ptr<Problem> problem;
  Vector p;
  double horizon;
  Vector reference;
  bool logScaled;
};

Case& pendulum() {
  static Case c = [] {
    Case k{std::make_shared<Pendulum>(), Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), 4.0, {}, false};
    GradientOptions options;
    options.integrator.method = "rk4";
    options.integrator.t1 = k.horizon;
    options.integrator.step = 1e-4;
    k.reference = computeGradientByMethod(*k.problem, k.p, options).gradient;
    return k;
  }();
  return c;
}

Case& robertson() {
  static Case c = [] {
    Case k{std::make_shared<Robertson>(1e5), Robertson::nominalParameters(), 1e5, {}, true};
    GradientOptions options;
    options.integrator.method = "trbdf2";
    options.integrator.t1 = k.horizon;
    options.integrator.adaptive = true;
    options.integrator.step = 1e-8;
    options.integrator.relativeTolerance = 1e-11;
    options.integrator.absoluteTolerance = 1e-16;
    k.reference = computeGradientByMethod(*k.problem, k.p, options).gradient;
    return k;
  }();
  return c;
}

double relativeError(const Case& c, const Vector& gradient) {
  if (c.logScaled) {
    const Vector a = gradient.cwiseProduct(c.p), b = c.reference.cwiseProduct(c.p);
    return (a - b).norm() / b.norm();
  }
  return (gradient - c.reference).norm() / c.reference.norm();
}

void run(benchmark::State& state, Case& (*problemCase)(), GradientOptions options) {
  Case& c = problemCase();  // the reference is computed outside the timed loop
  options.integrator.t1 = c.horizon;
  GradientResult result;
  for (auto _ : state) {
    result = bench::gradientWithCounters(*c.problem, c.p, options, state);
    benchmark::DoNotOptimize(result.gradient.data());
  }
  state.counters["gradient_error"] = relativeError(c, result.gradient);
  state.counters["steps"] = static_cast<double>(result.summary.steps);
  state.counters["rhs_evals"] = static_cast<double>(result.summary.rhsEvaluations);
  state.counters["jac_evals"] = static_cast<double>(result.summary.jacobianEvaluations);
  state.counters["stored"] = static_cast<double>(result.summary.statesStored);
}

std::string tolerance(double rtol) {
  char text[32];
  std::snprintf(text, sizeof text, "%.0e", rtol);
  return text;
}

void add(const std::string& name, Case& (*problemCase)(), const GradientOptions& options) {
  benchmark::RegisterBenchmark(name.c_str(), run, problemCase, options)
      ->Unit(benchmark::kMillisecond)
      ->MinTime(0.05);
}

void registerAll() {
  // ---- Pendulum (non-stiff): all three routes. ----
  for (double rtol : {1e-4, 1e-6, 1e-8, 1e-10}) {
    GradientOptions base;
    base.integrator.method = "dopri5";
    base.integrator.adaptive = true;
    base.integrator.step = 1e-3;
    base.integrator.relativeTolerance = rtol;
    base.integrator.absoluteTolerance = rtol / 100;
    base.continuous.relativeTolerance = rtol;
    base.continuous.absoluteTolerance = rtol / 100;
    base.cvodes.relativeTolerance = rtol;
    base.cvodes.absoluteTolerance = rtol / 100;
    const std::string suffix = "/rtol:" + tolerance(rtol);

    GradientOptions discrete = base;
    discrete.adjoint = AdjointMethod::Discrete;
    add("pendulum/discrete-dopri5/full" + suffix, &pendulum, discrete);

    GradientOptions continuous = base;
    continuous.adjoint = AdjointMethod::Continuous;
    add("pendulum/continuous-dopri5/full" + suffix, &pendulum, continuous);
    continuous.storage = "hermite:every=4";
    add("pendulum/continuous-dopri5/hermite4" + suffix, &pendulum, continuous);

    bench::forEachCvodesVariant(base, [&](const std::string& label, const GradientOptions& cvodes) {
      add("pendulum/" + label + suffix, &pendulum, cvodes);
    });
  }
  // ---- Robertson (stiff, t1 = 1e5): discrete trbdf2, continuous with backward trbdf2, CVODES BDF. ----
  for (double rtol : {1e-5, 1e-7, 1e-9}) {
    GradientOptions base;
    base.integrator.method = "trbdf2";
    base.integrator.adaptive = true;
    base.integrator.step = 1e-6;
    base.integrator.relativeTolerance = rtol;
    base.integrator.absoluteTolerance = rtol * 1e-5;
    base.cvodes.method = CvodesMethod::Bdf;
    base.cvodes.relativeTolerance = rtol;
    base.cvodes.absoluteTolerance = rtol * 1e-5;
    const std::string suffix = "/rtol:" + tolerance(rtol);
    GradientOptions discrete = base;
    discrete.adjoint = AdjointMethod::Discrete;
    add("robertson/discrete-trbdf2/full" + suffix, &robertson, discrete);
    GradientOptions continuous = base;
    continuous.adjoint = AdjointMethod::Continuous;
    continuous.continuous.method = "trbdf2";
    continuous.continuous.relativeTolerance = rtol;
    continuous.continuous.absoluteTolerance = rtol * 1e-5;
    add("robertson/continuous-trbdf2/full" + suffix, &robertson, continuous);
    for (CvodesInterpolation interpolation :
         {CvodesInterpolation::Hermite, CvodesInterpolation::Polynomial}) {
      for (std::int64_t nd : {10, 100, 1000}) {
        GradientOptions cvodes = base;
        cvodes.adjoint = AdjointMethod::Cvodes;
        cvodes.cvodes.interpolation = interpolation;
        cvodes.cvodes.checkpointSteps = nd;
        add("robertson/cvodes-bdf/" + toString(interpolation) + "-Nd" + std::to_string(nd) + suffix,
            &robertson, cvodes);
      }
    }
  }
}

}  // namespace
}  // namespace hindsight

int main(int argc, char** argv) {
  hindsight::registerAll();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
