// The 50-iteration topology optimisation of the piston rod end to end: what
// `hindsight optimize --objective psi1|psi2` does on the default configuration (200x12, 10 modes,
// rk4 h = 1e-4, T = 3 s, MMA with move limit 0.5), through OptimizationRun, so that the figure includes
// the crash-safe results.h5 after every iteration and the final pictures.
//
//   rod_optimize/psi1   the paper's psi1 = int q^T K_ee q dt with exact gradients (discrete adjoint +
//                       adjoint Nelson), 51 evaluations
//   rod_optimize/psi2   the equivalent-static-load route (docs/design.md §7), 51 evaluations
//
// Counters: evaluations (iterations recorded, 51 for 50 updates), psi1_final and psi2_final (both objectives
// of the final design, whichever was optimised), psi1_initial, volume_final (V/V0), backtracks (halvings
// after a diverged simulation, see docs/tutorials/topology_optimization.md), evaluation_s and mma_s (summed
// over the iterations). Wall time of one repetition = the whole run. Results go to
// /tmp/hindsight-optimize-bench/OBJECTIVE (overwritten).
//
// Run: build/bench/optimize_bench --benchmark_filter=rod_optimize/psi2
#include <hindsight/problems/app/config.h>
#include <hindsight/problems/topopt/optimization_run.h>

#include <benchmark/benchmark.h>

#include <sstream>
#include <string>

namespace hindsight {
namespace {

void optimize(benchmark::State& state, std::string objective) {
  Config config;
  config.optimization.objective = parseObjective(objective);
  OptimizationRunOptions options;
  options.outputDirectory = "/tmp/hindsight-optimize-bench/" + objective;
  options.force = true;
  OptimizationRunSummary summary;
  for (auto _ : state) {
    try {
      OptimizationRun run(config, options);
      std::ostringstream progress;  // one line per iteration; not printed between benchmark rows
      summary = run.run(progress);
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      return;
    }
  }
  if (summary.history.empty()) {
    state.SkipWithError("no iteration recorded");
    return;
  }
  double evaluation = 0.0, mma = 0.0;
  int backtracks = 0;
  for (const IterationRecord& record : summary.history) {
    evaluation += record.evaluationSeconds;
    mma += record.mmaSeconds;
    backtracks += record.backtracks;
  }
  state.counters["evaluations"] = static_cast<double>(summary.history.size());
  state.counters["psi1_initial"] = summary.history.front().psi1;
  state.counters["psi1_final"] = summary.history.back().psi1;
  state.counters["psi2_final"] = summary.history.back().psi2;
  state.counters["volume_final"] = summary.history.back().volumeFraction;
  state.counters["backtracks"] = backtracks;
  state.counters["evaluation_s"] = evaluation;
  state.counters["mma_s"] = mma;
}

}  // namespace
}  // namespace hindsight

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  for (const char* objective : {"psi1", "psi2"}) {
    benchmark::RegisterBenchmark((std::string("rod_optimize/") + objective).c_str(), hindsight::optimize,
                                 std::string(objective))
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
