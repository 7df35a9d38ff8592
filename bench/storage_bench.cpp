// Storage strategies on a large state (docs/design.md §8): the reaction-diffusion problem with
// n = 10^4 unknowns (80 kB per state), 10^3 and 5000 fixed steps of RK4, 10^3 of TR-BDF2, one gradient per
// iteration through full, binomial (several c) and online storage, next to the forward-only baseline of
// the same configuration. Counters: recomputed steps, the ratio of (N - 1) + recomputed steps to the
// revolve optimum T(N, c) (full: T(N, N - 1) = N - 1), peak bytes in memory, the relative gradient
// difference to full storage (0 for exact strategies) and the checkpoint count.
//
// Run (see bench/RESULTS.md):
//   ./build/bench/storage_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/online_checkpointing.h>
#include <hindsight/problems/classic/heat_equation.h>
#include <hindsight/storage/storage_factory.h>
#include "bench_support.h"

#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <string>

namespace hindsight {
namespace {

constexpr int kGridPoints = 10'000;

const HeatEquation& problem() {
  static const HeatEquation heat(kGridPoints, 3);
  return heat;
}

Vector parameters() {
  Vector p = problem().nominalParameters();
  p(0) = 5e-6;  // D / h^2 = 500: RK4 is stable for h_t < 1.4e-3
  p(1) = 1.0;
  return p;
}

IntegratorOptions options(const std::string& method, std::int64_t steps) {
  IntegratorOptions o;
  o.method = method;
  o.t0 = 0.0;
  o.t1 = 1.0;
  o.step = 1.0 / static_cast<double>(steps);
  return o;
}

/// Full-storage gradients per configuration, the reference of the gradient-difference counter. The
/// `full` benchmark of a configuration runs first and fills it, so no gradient is computed twice; a
/// filtered run that skips it computes the reference here, outside the timing.
std::map<std::pair<std::string, std::int64_t>, Vector>& referenceGradients() {
  static std::map<std::pair<std::string, std::int64_t>, Vector> cache;
  return cache;
}

const Vector& referenceGradient(const std::string& method, std::int64_t steps) {
  auto& cache = referenceGradients();
  const auto key = std::make_pair(method, steps);
  auto it = cache.find(key);
  if (it == cache.end()) {
    FullStorage full(std::int64_t{8} << 30);
    it = cache.emplace(key, computeGradient(problem(), parameters(), options(method, steps), full).gradient)
             .first;
  }
  return it->second;
}

void forwardOnly(benchmark::State& state, std::string method, std::int64_t steps) {
  const Vector p = parameters();
  const IntegratorOptions o = options(method, steps);
  double objective = 0.0;
  for (auto _ : state) {
    // (No DoNotOptimize on the double: simulate() has effects the compiler cannot drop, and
    // benchmark 1.7.1's "+r,m" constraint garbles floating-point lvalues with GCC.)
    objective = simulate(problem(), p, o).objective;
  }
  state.counters["psi"] = objective;
  state.counters["peak_bytes"] = 0.0;
}

std::int64_t checkpointCount(const std::string& spec, std::int64_t steps) {
  const StorageSpec parsed = StorageSpec::parse(spec);
  if (parsed.name() == "full") return steps - 1;
  return parsed.integer("checkpoints", 0, 0, BinomialCheckpointing::kMaxCheckpoints);
}

void gradient(benchmark::State& state, std::string method, std::int64_t steps, std::string spec) {
  const Vector p = parameters();
  const IntegratorOptions o = options(method, steps);
  const std::unique_ptr<TrajectoryStorage> storage = createStorage(spec);
  GradientResult result;
  for (auto _ : state) {
    result = computeGradient(problem(), p, o, *storage);
    benchmark::DoNotOptimize(result.gradient.data());
  }
  if (StorageSpec::parse(spec).name() == "full")
    referenceGradients().emplace(std::make_pair(method, steps), result.gradient);
  const Vector& full = referenceGradient(method, steps);
  const std::int64_t c = checkpointCount(spec, steps);
  const auto total = static_cast<double>(steps - 1 + storage->counters().recomputedSteps);
  state.counters["recomputed"] = static_cast<double>(storage->counters().recomputedSteps);
  state.counters["ratio_to_revolve"] = total / bench::revolveOptimum(spec, steps);
  state.counters["checkpoints"] = static_cast<double>(c);
  state.counters["peak_bytes"] = static_cast<double>(storage->counters().peakBytesInMemory);
  state.counters["grad_rel_diff"] = (result.gradient - full).norm() / full.norm();
  state.counters["psi"] = result.objective;
}

void registerAll() {
  // Sized to keep one run (three repetitions) under three minutes on a shared 2-core machine.
  struct Configuration {
    std::string method;
    std::int64_t steps;
    std::vector<std::string> strategies;
  };
  const std::vector<Configuration> configurations = {
      {"rk4",
       1000,
       {"full:budget=8GiB", "binomial:checkpoints=10", "binomial:checkpoints=100", "online:checkpoints=10",
        "online:checkpoints=100"}},
      // At 5000 steps `full` (400 MB) is computed once, untimed, as the gradient reference only.
      {"rk4", 5000, {"binomial:checkpoints=100", "online:checkpoints=100"}},
      {"trbdf2", 1000, {"full:budget=8GiB", "binomial:checkpoints=50", "online:checkpoints=50"}},
  };
  for (const Configuration& configuration : configurations) {
    const std::string suffix = "/" + configuration.method + "/N" + std::to_string(configuration.steps);
    benchmark::RegisterBenchmark(("forward_only" + suffix).c_str(), forwardOnly, configuration.method,
                                 configuration.steps)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(1);
    for (const std::string& spec : configuration.strategies) {
      benchmark::RegisterBenchmark(("gradient" + suffix + "/" + spec).c_str(), gradient, configuration.method,
                                   configuration.steps, spec)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->Iterations(1);
    }
  }
}

}  // namespace
}  // namespace hindsight

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  hindsight::registerAll();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
