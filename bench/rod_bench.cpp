// The piston-rod benchmark suite (docs/design.md §8) on the reduced (modal) rod: every group has its
// baseline in the same run (docs/design.md P 10).
//
//   rod_design/...   one forward run of the design (FE model, modes, invariants, simulation) against
//                    one gradient dpsi1/dx by hindsight's route (discrete adjoint + adjoint Nelson) and
//                    by the paper's route (discrete adjoint + Nelson per design variable), meshes
//                    100x6 ... 1600x96 (the number of design variables grows 4x per step).
//   rod_storage/...  the slider-crank with the invariants of the 200x12 initial design, m modes, horizons
//                    T of 3-100 s (the crank turns at constant speed after 2 s), fixed-step rk4, one
//                    gradient dpsi1/dp per strategy: full, binomial, online, disk, multilevel, hermite,
//                    lossy; baseline: the forward sweep alone. m20/T100 is 10^6 steps.
//   rod_routes/...   peers on the same problem (200x12, 10 modes, T = 3 s): discrete adjoint (rk4 at
//                    the default step; dopri5 adaptive), continuous adjoint (dopri5), CVODES (Adams and
//                    BDF, Hermite and polynomial, Nd in {10, 100, 1000}, configured as its user guide
//                    advises, plus the alternatives of bench::forEachCvodesVariant at Hermite Nd 100);
//                    baselines: forward sweeps. CVODES runs also report bwd_rhs, vjps, nl_iters,
//                    lin_iters, setups and recomputed_rhs (bench::gradientWithCounters).
//
// Counters: steps, recomputed (steps re-integrated by the storage), ratio_to_revolve
// ((N - 1 + recomputed) / T(N, c), Griewank & Walther), peak_bytes (held by the storage),
// disk_bytes, compression (uncompressed / compressed), grad_rel_err (rod_storage: against full
// storage of the same run; rod_routes: against a tight discrete reference, rk4 at h = 2e-5, computed
// once outside the timing), designs, and the phase seconds of PistonRod::evaluate (model_s,
// simulation_s, chain_s), rss_base and rss_peak (the process's resident set when the benchmark starts
// and its high-water mark over the benchmark, bench/bench_support.h). Every benchmark runs one iteration per
// repetition; bench/run_suite.py chooses the filters and repetitions and computes medians, min and max.
//
// Run: build/bench/rod_bench --benchmark_filter=... --benchmark_repetitions=3
//      (see bench/run_suite.py and bench/RESULTS.md)
#include <hindsight/engine/storage_spec.h>
#include <hindsight/problems/app/gradient_routes.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/invariants.h>
#include <hindsight/problems/rod/modal_reduction.h>
#include <hindsight/storage/storage_factory.h>
#include "bench_support.h"
#include "support/slider_crank.h"

#include <benchmark/benchmark.h>

#include <cstdio>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {
namespace {

// ---------------------------------------------------------------------------------------------------
// rod_design: forward vs gradient (adjoint Nelson vs Nelson per design variable) over the mesh.

Config meshConfig(int nx, int ny) {
  Config config;
  config.rod.elementsAlongLength = nx;
  config.rod.elementsThroughHeight = ny;
  return config;
}

std::string meshName(int nx, int ny) { return std::to_string(nx) + "x" + std::to_string(ny); }

/// dpsi1/dx of hindsight's route per mesh, kept from the gradient benchmark that runs first, so that
/// the paper's route reports its difference without an extra untimed gradient.
std::map<std::string, Vector>& designGradients() {
  static std::map<std::string, Vector> cache;
  return cache;
}

void designRun(benchmark::State& state, int nx, int ny, std::string what) {
  Config config = meshConfig(nx, ny);
  if (what == "gradient-nelson")
    config.simulation.eigenvectorRoute = rod::EigenvectorSensitivityMethod::NelsonPerVariable;
  const PistonRod rod(config);
  const Vector x = rod.initialDesign();
  PistonRod::Request request;
  request.psi1Gradient = what != "forward";
  request.psi2 = false;
  request.psi2Gradient = false;
  PistonRodEvaluation result;
  for (auto _ : state) {
    try {
      result = rod.evaluate(x, request);
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      return;
    }
    benchmark::DoNotOptimize(result.dpsi1.data());
  }
  state.counters["designs"] = rod.designCount();
  state.counters["steps"] = static_cast<double>(result.summary.steps);
  state.counters["model_s"] = result.modelSeconds;
  state.counters["simulation_s"] = result.simulationSeconds;
  state.counters["chain_s"] = result.chainSeconds;
  state.counters["psi1"] = result.psi1;
  const std::string key = meshName(nx, ny);
  if (what == "gradient-adjoint-nelson") designGradients()[key] = result.dpsi1;
  if (what == "gradient-nelson") {
    auto it = designGradients().find(key);
    if (it == designGradients().end()) {
      // Filtered run without hindsight's route: compute it here, after the timed loop.
      Config reference = meshConfig(nx, ny);
      it = designGradients().emplace(key, PistonRod(reference).evaluate(x, request).dpsi1).first;
    }
    state.counters["grad_rel_diff"] = (result.dpsi1 - it->second).norm() / it->second.norm();
  }
}

// ---------------------------------------------------------------------------------------------------
// The reduced slider-crank problem for a rod configuration (200x12 initial design, m modes).

struct ReducedRod {
  std::unique_ptr<rod::SliderCrankProblem> problem;
  Vector p;
};

const ReducedRod& reducedRod(int modes) {
  static std::map<int, ReducedRod> cache;
  auto it = cache.find(modes);
  if (it == cache.end()) {
    Config config = meshConfig(200, 12);
    config.rod.modeCount = modes;
    const rod::RodConfig& rc = config.rod;
    const Vector x = Vector::Constant(rc.designCount(), rc.initialDesign);
    const rod::FeModel model(rc, x);
    const rod::ModalBasis basis = rod::computeModalBasis(model, rod::ModalReductionOptions::fromConfig(rc));
    rod::CrankMotion crank;
    crank.radius = rc.crankRadius;
    crank.omega = rc.crankSpeed;
    crank.rampTime = rc.rampTime;
    ReducedRod r;
    r.problem = std::make_unique<rod::SliderCrankProblem>(basis.columnCount(), rc.length, crank);
    r.p = rod::computeInvariants(model, basis).pack();
    it = cache.emplace(modes, std::move(r)).first;
  }
  return it->second;
}

IntegratorOptions fixedStep(const std::string& method, double endTime, double step) {
  IntegratorOptions o;
  o.method = method;
  o.t0 = 0.0;
  o.t1 = endTime;
  o.step = step;
  return o;
}

// ---------------------------------------------------------------------------------------------------
// rod_storage: strategies on a long horizon.

/// rk4 is stable for h * omega_max < 2.78: the 20th mode of the 200x12 rod is below 4.4 kHz (h = 1e-4
/// works), the 40th is at 7.0 kHz (h = 1e-4 diverges at t = 0.016 s; 5e-5 is used).
double storageStep(int modes) { return modes > 20 ? 5e-5 : 1e-4; }

std::string storageKey(int modes, double endTime) {
  return "m" + std::to_string(modes) + "/T" + std::to_string(static_cast<int>(endTime));
}

std::map<std::string, Vector>& fullGradients() {
  static std::map<std::string, Vector> cache;
  return cache;
}

const Vector& fullGradient(int modes, double endTime) {
  auto& cache = fullGradients();
  const std::string key = storageKey(modes, endTime);
  auto it = cache.find(key);
  if (it == cache.end()) {
    const ReducedRod& r = reducedRod(modes);
    auto full = createStorage("full");
    it = cache
             .emplace(key,
                      computeGradient(*r.problem, r.p, fixedStep("rk4", endTime, storageStep(modes)), *full)
                          .gradient)
             .first;
  }
  return it->second;
}

void storageForward(benchmark::State& state, int modes, double endTime) {
  const ReducedRod& r = reducedRod(modes);
  const IntegratorOptions o = fixedStep("rk4", endTime, storageStep(modes));
  ForwardResult result;
  const double rssBase = bench::resetPeakRss();
  for (auto _ : state) {
    try {
      result = simulate(*r.problem, r.p, o);
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      return;
    }
  }
  state.counters["steps"] = static_cast<double>(result.summary.steps);
  state.counters["h"] = o.step;
  state.counters["state_bytes"] = 8.0 * 2 * modes;
  state.counters["psi1"] = result.objective;
  state.counters["rss_base"] = rssBase;
  state.counters["rss_peak"] = rssBase < 0 ? -1.0 : bench::peakRssBytes();
}

void storageGradient(benchmark::State& state, int modes, double endTime, std::string spec) {
  const ReducedRod& r = reducedRod(modes);
  const IntegratorOptions o = fixedStep("rk4", endTime, storageStep(modes));
  const bool isFull = StorageSpec::parse(spec).name() == "full";
  GradientResult result;
  StorageCounters counters;
  const double rssBase = bench::resetPeakRss();
  for (auto _ : state) {
    try {
      auto storage = createStorage(spec);
      result = computeGradient(*r.problem, r.p, o, *storage);
      counters = storage->counters();
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      return;
    }
    benchmark::DoNotOptimize(result.gradient.data());
  }
  if (isFull) fullGradients().emplace(storageKey(modes, endTime), result.gradient);
  const Vector& full = fullGradient(modes, endTime);
  bench::setStorageCounters(state, spec, result.summary, counters);
  state.counters["grad_rel_err"] = (result.gradient - full).norm() / full.norm();
  state.counters["rss_base"] = rssBase;
  state.counters["rss_peak"] = rssBase < 0 ? -1.0 : bench::peakRssBytes();
}

// ---------------------------------------------------------------------------------------------------
// rod_routes: peers on the 3 s, 10-mode rod.

constexpr int kRouteModes = 10;
constexpr double kRouteEndTime = 3.0;

/// rk4's error is O(h^4): 5^4 = 625 times below that of the default h = 1e-4.
constexpr double kReferenceStep = 2e-5;

const Vector& routeReference() {
  static const Vector reference = [] {
    const ReducedRod& r = reducedRod(kRouteModes);
    auto full = createStorage("full");
    return computeGradient(*r.problem, r.p, fixedStep("rk4", kRouteEndTime, kReferenceStep), *full).gradient;
  }();
  return reference;
}

void routeForward(benchmark::State& state, IntegratorOptions options) {
  const ReducedRod& r = reducedRod(kRouteModes);
  ForwardResult result;
  for (auto _ : state) {
    try {
      result = simulate(*r.problem, r.p, options);
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      return;
    }
  }
  state.counters["steps"] = static_cast<double>(result.summary.steps);
  state.counters["rhs_evals"] = static_cast<double>(result.summary.rhsEvaluations);
  state.counters["psi1"] = result.objective;
}

void routeGradient(benchmark::State& state, GradientOptions options) {
  const ReducedRod& r = reducedRod(kRouteModes);
  const Vector& reference = routeReference();  // outside the timed loop
  GradientResult result;
  for (auto _ : state) {
    try {
      result = bench::gradientWithCounters(*r.problem, r.p, options, state);
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      return;
    }
    benchmark::DoNotOptimize(result.gradient.data());
  }
  state.counters["grad_rel_err"] = (result.gradient - reference).norm() / reference.norm();
  state.counters["steps"] = static_cast<double>(result.summary.steps);
  state.counters["rhs_evals"] = static_cast<double>(result.summary.rhsEvaluations);
  state.counters["jac_evals"] = static_cast<double>(result.summary.jacobianEvaluations);
  state.counters["recomputed"] = static_cast<double>(result.summary.recomputedSteps);
  state.counters["stored"] = static_cast<double>(result.summary.statesStored);
  state.counters["psi1"] = result.objective;
}

std::string tolerance(double rtol) {
  char text[32];
  std::snprintf(text, sizeof text, "%.0e", rtol);
  return text;
}

template <class... Args>
void add(const std::string& name, Args&&... args) {
  benchmark::RegisterBenchmark(name.c_str(), std::forward<Args>(args)...)
      ->Unit(benchmark::kMillisecond)
      ->Iterations(1);
}

void registerAll() {
  // ---- rod_design ----
  // 1600x96 (153 600 design variables, 310 000 FE DOFs): hindsight's route only (`full`, 1 repetition).
  const std::vector<std::pair<int, int>> meshes = {{100, 6}, {200, 12}, {400, 24}, {800, 48}, {1600, 96}};
  for (const auto& [nx, ny] : meshes) {
    const std::string mesh = meshName(nx, ny);
    for (const char* what : {"forward", "gradient-adjoint-nelson", "gradient-nelson"})
      add("rod_design/" + mesh + "/" + what, designRun, nx, ny, std::string(what));
  }

  // ---- rod_storage ----
  const std::string dir = "/tmp/hindsight-rod-bench";
  const std::vector<std::string> allSpecs = {
      "full",
      "binomial:checkpoints=10",
      "binomial:checkpoints=100",
      "binomial:checkpoints=1000",
      "online:checkpoints=100",
      "online:checkpoints=1000",
      "disk:dir=" + dir,
      "multilevel:ram=4MiB,disk=64MiB,dir=" + dir,
      "hermite:every=4",
      "hermite:every=16",
      "lossy:codec=round,tolerance=1e-6",
      "lossy:codec=round,tolerance=1e-10",
      "lossy:codec=zfp,tolerance=1e-6",
      "lossy:codec=zfp,tolerance=1e-10",
  };
  // The long horizons run one of each family (about 2.5 min per gradient at 10^6 steps).
  const std::vector<std::string> longSpecs = {
      "full",
      "binomial:checkpoints=100",
      "binomial:checkpoints=1000",
      "online:checkpoints=100",
      "disk:dir=" + dir,
      "multilevel:ram=4MiB,disk=64MiB,dir=" + dir,
      "hermite:every=16",
      "lossy:codec=zfp,tolerance=1e-10",
  };
  struct Horizon {
    int modes;
    double endTime;
    const std::vector<std::string>* specs;
  };
  // m20/T3: quick; m20/T10 (10^5 steps), m20/T30 (3e5), m20/T100 (10^6) and m40/T10 (h = 5e-5, 2e5
  // steps): full.
  const std::vector<Horizon> horizons = {{20, 3.0, &allSpecs},
                                         {20, 10.0, &allSpecs},
                                         {20, 30.0, &allSpecs},
                                         {20, 100.0, &longSpecs},
                                         {40, 10.0, &longSpecs}};
  for (const Horizon& h : horizons) {
    const std::string prefix = "rod_storage/" + storageKey(h.modes, h.endTime);
    add(prefix + "/forward", storageForward, h.modes, h.endTime);
    for (const std::string& spec : *h.specs)
      add(prefix + "/" + spec, storageGradient, h.modes, h.endTime, spec);
  }

  // ---- rod_routes ----
  add("rod_routes/forward/rk4/h:1e-4", routeForward, fixedStep("rk4", kRouteEndTime, 1e-4));
  {
    GradientOptions discrete;
    discrete.integrator = fixedStep("rk4", kRouteEndTime, 1e-4);
    add("rod_routes/discrete-rk4/full/h:1e-4", routeGradient, discrete);
    discrete.integrator = fixedStep("trbdf2", kRouteEndTime, 1e-4);
    add("rod_routes/forward/trbdf2/h:1e-4", routeForward, discrete.integrator);
    add("rod_routes/discrete-trbdf2/full/h:1e-4", routeGradient, discrete);
  }
  for (double rtol : {1e-4, 1e-6, 1e-8}) {
    const std::string suffix = "/rtol:" + tolerance(rtol);
    GradientOptions base;
    base.integrator.method = "dopri5";
    base.integrator.t0 = 0.0;
    base.integrator.t1 = kRouteEndTime;
    base.integrator.adaptive = true;
    base.integrator.step = 1e-4;
    base.integrator.relativeTolerance = rtol;
    base.integrator.absoluteTolerance = rtol * 1e-4;
    base.continuous.relativeTolerance = rtol;
    base.continuous.absoluteTolerance = rtol * 1e-4;
    base.cvodes.relativeTolerance = rtol;
    base.cvodes.absoluteTolerance = rtol * 1e-4;
    base.cvodes.maxSteps = 100'000'000;
    add("rod_routes/forward/dopri5" + suffix, routeForward, base.integrator);
    GradientOptions discrete = base;
    discrete.adjoint = AdjointMethod::Discrete;
    add("rod_routes/discrete-dopri5/full" + suffix, routeGradient, discrete);
    GradientOptions continuous = base;
    continuous.adjoint = AdjointMethod::Continuous;
    add("rod_routes/continuous-dopri5/full" + suffix, routeGradient, continuous);
    bench::forEachCvodesVariant(base, [&](const std::string& label, const GradientOptions& cvodes) {
      add("rod_routes/" + label + suffix, routeGradient, cvodes);
    });
  }
}

}  // namespace
}  // namespace hindsight

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  hindsight::registerAll();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
