// Stage-aware storage. Prints two tables (no Google Benchmark fixtures: the quantities are
// ratios of one run's sweeps and plan counts):
//  1. (forward + backward) / forward seconds, median of 5 runs, for `full` and `full:stages=1` on the
//     pendulum (rk4, 200 000 steps) with the rhs evaluations of each run;
//  2. cams against binomial at the same bytes (binomial:checkpoints=C holds C + 1 states): step
//     evaluations (forward + recomputed + adjoint recomputations; x4 = rhs evaluations for rk4, whose
//     step record is 4 states) from the plans, without running a model, and the time to build the plan.
// Usage: stage_bench [max_steps_for_plans]   (default 30000)
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/cams_checkpointing.h>
#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/storage_factory.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <vector>

using namespace hindsight;

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

void sweepRatios() {
  Pendulum problem;
  const Eigen::Vector4d p(1.5, 0.8, 0.3, 1.2);
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 200.0;
  options.step = 1e-3;
  std::printf(
      "| problem | storage | forward s | backward s | (fwd+bwd)/fwd | rhs evaluations "
      "|\n|---|---|---|---|---|---|\n");
  for (const char* spec : {"full", "full:stages=1"}) {
    std::vector<double> forward, backward, ratio;
    std::int64_t rhs = 0;
    for (int run = 0; run < 5; ++run) {
      const auto storage = createStorage(spec);
      const GradientResult r = computeGradient(problem, p, options, *storage);
      forward.push_back(r.summary.forwardSeconds);
      backward.push_back(r.summary.backwardSeconds);
      ratio.push_back((r.summary.forwardSeconds + r.summary.backwardSeconds) / r.summary.forwardSeconds);
      rhs = r.summary.rhsEvaluations;
    }
    std::printf("| pendulum rk4, N = 200000 | %s | %.3f | %.3f | %.2f | %lld |\n", spec, median(forward),
                median(backward), median(ratio), static_cast<long long>(rhs));
  }
}

void planTable(std::int64_t maxSteps) {
  std::printf(
      "\n| N | C | binomial steps | cams steps | cams without records | cams / binomial | plan s |\n"
      "|---|---|---|---|---|---|---|\n");
  for (std::int64_t n : {std::int64_t{3000}, std::int64_t{10000}, std::int64_t{30000}}) {
    if (n > maxSteps) continue;
    for (std::int64_t c :
         {std::int64_t{10}, std::int64_t{20}, std::int64_t{50}, std::int64_t{100}, std::int64_t{200}}) {
      if (n * (c + 2) > cams::Plan::kMaxTableEntries || (n >= 30000 && c > 50) || (n >= 10000 && c > 100))
        continue;
      const std::int64_t binomial =
          n + static_cast<std::int64_t>(revolve::simulateSchedule(n, c).recomputedSteps) + n;
      const Stopwatch watch;
      const cams::Plan plan(n, c + 1, 4);
      const double seconds = watch.seconds();
      const cams::Plan statesOnly(n, c + 1, 1'000'000);
      std::printf("| %lld | %lld | %lld | %lld | %lld | %.4f | %.1f |\n", static_cast<long long>(n),
                  static_cast<long long>(c), static_cast<long long>(binomial),
                  static_cast<long long>(plan.optimalStepEvaluations()),
                  static_cast<long long>(statesOnly.optimalStepEvaluations()),
                  static_cast<double>(plan.optimalStepEvaluations()) / static_cast<double>(binomial),
                  seconds);
      std::fflush(stdout);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::int64_t maxSteps = argc > 1 ? std::atoll(argv[1]) : 30000;
  sweepRatios();
  planTable(maxSteps);
  return 0;
}
