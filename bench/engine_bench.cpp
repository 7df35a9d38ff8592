// Forward and forward+adjoint time of the engine on the pendulum (non-stiff, rk4 fixed step) and on
// Robertson's stiff kinetics (trbdf2, adaptive). The ratio (forward+adjoint)/forward is the cost of
// a gradient in units of a simulation; the forward-only run is the baseline in the same binary.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/classic/classic_problems.h>

#include <benchmark/benchmark.h>

namespace hindsight {
namespace {

struct Case {
  std::unique_ptr<Problem> problem;
  Vector p;
  IntegratorOptions options;
};

Case makeCase(int which) {
  Case c;
  if (which == 0) {
    c.problem = std::make_unique<Pendulum>();
    c.p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
    c.options.method = "rk4";
    c.options.t1 = 10.0;
    c.options.step = 1e-4;
  } else {
    c.problem = std::make_unique<Robertson>(1e5);
    c.p = Robertson::nominalParameters();
    c.options.method = "trbdf2";
    c.options.adaptive = true;
    c.options.t1 = 1e5;
    c.options.step = 1e-6;
    c.options.relativeTolerance = 1e-8;
    c.options.absoluteTolerance = 1e-14;
  }
  return c;
}

void Forward(benchmark::State& state) {
  const Case c = makeCase(static_cast<int>(state.range(0)));
  std::int64_t steps = 0;
  for (auto _ : state) {
    const auto result = simulate(*c.problem, c.p, c.options);
    benchmark::DoNotOptimize(result.objective);
    steps = result.summary.steps;
  }
  state.counters["steps"] = static_cast<double>(steps);
  state.SetLabel(c.problem->name() + "/" + c.options.method);
}

void ForwardAndAdjoint(benchmark::State& state) {
  const Case c = makeCase(static_cast<int>(state.range(0)));
  std::int64_t steps = 0;
  for (auto _ : state) {
    FullStorage storage;
    const auto result = computeGradient(*c.problem, c.p, c.options, storage);
    benchmark::DoNotOptimize(result.gradient.data());
    steps = result.summary.steps;
  }
  state.counters["steps"] = static_cast<double>(steps);
  state.SetLabel(c.problem->name() + "/" + c.options.method);
}

BENCHMARK(Forward)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(ForwardAndAdjoint)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace hindsight

BENCHMARK_MAIN();
