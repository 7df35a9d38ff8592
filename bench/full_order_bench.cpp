// Storage trade-offs on the full-order rod (docs/design.md §9): the unreduced
// FE model of the initial design x0 = 0.5 carried by the rigid slider-crank motion, state 2n with
// n = 2 (nx+1)(ny+1) - 3 free DOFs (22 kB per state at 100x6, 1.25 MB at 800x48), TR-BDF2 at
// h = 1e-3 s (the CLI's `--model full` default), one gradient dpsi1,full/dx per storage strategy.
//
//   full_order/MESH/forward    the forward sweep alone (baseline of the group)
//   full_order/MESH/SPEC       forward + discrete adjoint with storage SPEC
//
// Horizon. One step costs ~20 ms at 200x12 and ~1.3 s at 800x48 (4 Newton solves of a banded
// Cholesky factor whose size grows with n times the band 2 (ny+1)), so the runs are short: N = 100
// steps up to 400x24 and N = 40 at 800x48, over the first N ms of a crank that reaches full speed
// after 50 ms (a hard start, so that the trajectory is not nearly zero). The counter
// full_bytes_T3 says what full storage would hold for the paper's T = 3 s at this step
// (3001 states), the reason checkpointing matters for this model.
//
// Counters: steps, state_bytes, recomputed, ratio_to_revolve ((N - 1 + recomputed) / T(N, c)),
// peak_bytes (held by the storage), disk_bytes, compression, io_s, grad_rel_err (against full storage
// of the same mesh, computed by the `full` benchmark that runs first in each group), rss_base and
// rss_peak (process resident set at the start and its high-water mark, bench/bench_support.h), psi1,
// forward_s, backward_s. One iteration per repetition; bench/run_suite.py chooses repetitions.
//
// Run: build/bench/full_order_bench --benchmark_filter='full_order/200x12/'
#include <hindsight/engine/adjoint.h>
#include <hindsight/problems/app/full_order_evaluation.h>
#include <hindsight/problems/rod/full_order_rod.h>
#include <hindsight/problems/rod/rod_config.h>
#include <hindsight/storage/storage_factory.h>
#include "bench_support.h"

#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {
namespace {

constexpr double kStep = 1e-3;
constexpr double kRampTime = 0.05;
const std::string kDir = "/tmp/hindsight-full-order-bench";

struct Mesh {
  int nx, ny, steps;
  std::string name() const { return std::to_string(nx) + "x" + std::to_string(ny); }
  int stateSize() const { return 2 * (2 * (nx + 1) * (ny + 1) - 3); }
  double stateBytes() const { return 8.0 * stateSize(); }
};

/// The problem of one mesh, built once (its FE model and factorised mass are not what is measured).
struct Case {
  rod::RodConfig config;
  Vector design;
  std::unique_ptr<rod::FullOrderRodProblem> problem;
  IntegratorOptions options;
};

const Case& caseOf(const Mesh& mesh) {
  static std::map<std::string, Case> cache;
  auto it = cache.find(mesh.name());
  if (it == cache.end()) {
    Case c;
    c.config.elementsAlongLength = mesh.nx;
    c.config.elementsThroughHeight = mesh.ny;
    c.design = Vector::Constant(c.config.designCount(), c.config.initialDesign);
    rod::CrankMotion crank;
    crank.radius = c.config.crankRadius;
    crank.omega = c.config.crankSpeed;
    crank.rampTime = kRampTime;
    c.problem = std::make_unique<rod::FullOrderRodProblem>(c.config, c.design, crank, true);
    c.options.method = rod::kFullOrderDefaultIntegrator;
    c.options.t0 = 0.0;
    c.options.t1 = mesh.steps * kStep;
    c.options.step = kStep;
    c.options.newtonTolerance = 1e-10;  // as evaluateFullOrderRod(): see problems/rod/full_order_rod.cpp
    it = cache.emplace(mesh.name(), std::move(c)).first;
  }
  return it->second;
}

std::map<std::string, Vector>& fullGradients() {
  static std::map<std::string, Vector> cache;
  return cache;
}

void setCommon(benchmark::State& state, const Mesh& mesh, double rssBase, double psi1) {
  state.counters["state_bytes"] = mesh.stateBytes();
  state.counters["full_bytes_T3"] = mesh.stateBytes() * 3001.0;
  state.counters["rss_base"] = rssBase;
  state.counters["rss_peak"] = rssBase < 0 ? -1.0 : bench::peakRssBytes();
  state.counters["psi1"] = psi1;
}

void forward(benchmark::State& state, Mesh mesh) {
  const Case& c = caseOf(mesh);
  const double rssBase = bench::resetPeakRss();
  ForwardResult result;
  for (auto _ : state) {
    try {
      result = simulate(*c.problem, c.design, c.options);
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      return;
    }
  }
  state.counters["steps"] = static_cast<double>(result.summary.steps);
  setCommon(state, mesh, rssBase, result.objective);
}

void gradient(benchmark::State& state, Mesh mesh, std::string spec) {
  const Case& c = caseOf(mesh);
  const double rssBase = bench::resetPeakRss();
  GradientResult result;
  StorageCounters counters;
  for (auto _ : state) {
    try {
      auto storage = createStorage(spec);
      result = computeGradient(*c.problem, c.design, c.options, *storage);
      counters = storage->counters();
    } catch (const std::exception& error) {
      state.SkipWithError(error.what());
      return;
    }
    benchmark::DoNotOptimize(result.gradient.data());
  }
  setCommon(state, mesh, rssBase, result.objective);
  if (spec == "full") fullGradients()[mesh.name()] = result.gradient;
  auto reference = fullGradients().find(mesh.name());
  state.counters["grad_rel_err"] =
      reference == fullGradients().end()
          ? -1.0  // run filtered without `full`: no reference
          : (result.gradient - reference->second).norm() / reference->second.norm();
  bench::setStorageCounters(state, spec, result.summary, counters);
}

void registerAll() {
  const std::vector<Mesh> meshes = {{100, 6, 100}, {200, 12, 100}, {400, 24, 100}, {800, 48, 40}};
  for (const Mesh& mesh : meshes) {
    const std::string prefix = "full_order/" + mesh.name() + "/";
    // A RAM level of a quarter of the trajectory, so that multilevel spills three quarters to disk.
    const double quarter = std::ceil(mesh.stateBytes() * (mesh.steps + 1) / 4.0 / (1 << 20));
    const std::vector<std::string> specs = {
        "full",
        "binomial:checkpoints=10",
        "online:checkpoints=10",
        "disk:dir=" + kDir,
        "multilevel:ram=" + std::to_string(static_cast<int>(quarter)) + "MiB,disk=4GiB,dir=" + kDir,
        "hermite:every=4",
        "lossy:codec=zfp,tolerance=1e-8",
    };
    benchmark::RegisterBenchmark((prefix + "forward").c_str(), forward, mesh)
        ->Unit(benchmark::kMillisecond)
        ->Iterations(1);
    for (const std::string& spec : specs) {
      benchmark::RegisterBenchmark((prefix + spec).c_str(), gradient, mesh, spec)
          ->Unit(benchmark::kMillisecond)
          ->Iterations(1);
    }
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
