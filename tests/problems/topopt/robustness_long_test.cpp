// The optimizer-robustness claims (GCMMA never worse, the frequency guard's no step-back), end to end on the
// default 200 x 12 problem (50 iterations each; minutes of CPU, so DISABLED_ here and run by the ctest entry
// `optimizer.robustness`, label `long`):
//   ctest --test-dir build -L long -R robustness --output-on-failure
#include <hindsight/problems/topopt/topology_optimizer.h>

#include <gtest/gtest.h>

#include <iostream>

namespace hindsight {
namespace {

std::vector<IterationRecord> run(const Config& config) {
  TopologyOptimizer optimizer(config);
  std::vector<IterationRecord> history;
  while (!optimizer.finished()) history.push_back(optimizer.step());
  return history;
}

// The claims were measured with 50 updates of plain MMA / GCMMA (bench/RESULTS.md, "Optimizer
// robustness"); the default method now runs to its stopping rule, so the runs say what they test.
Config fiftyUpdates(const std::string& method) {
  Config config;
  config.optimization.method = method;
  config.optimization.kktTolerance = 0.0;
  config.optimization.iterations = 50;
  config.optimization.moveLimit = 0.5;  // Svanberg's move, with which the claims were measured
  if (method == "mma") config.optimization.minAsymptoteDistance = 0.01;  // the paper's MMA (README)
  return config;
}

TEST(OptimizerRobustness, DISABLED_GcmmaPsi1HistoryNeverIncreasesAndEndsBelowFifteenPercent) {
  const Config config = fiftyUpdates("gcmma");
  const std::vector<IterationRecord> history = run(config);
  ASSERT_EQ(history.size(), 51u);
  for (std::size_t k = 1; k < history.size(); ++k) {
    EXPECT_LE(history[k].psi1, history[k - 1].psi1) << "iteration " << k;
    EXPECT_EQ(history[k].backtracks, 0) << "iteration " << k;
    EXPECT_LE(history[k].volumeFraction, 0.5 * (1.0 + 1e-7)) << "iteration " << k;
  }
  std::cout << "[ gcmma ] psi1 " << history.front().psi1 << " -> " << history.back().psi1 << "\n";
  EXPECT_LT(history.back().psi1, 0.15 * history.front().psi1);
}

TEST(OptimizerRobustness, DISABLED_FrequencyGuardLetsMmaRunWithoutStepBack) {
  Config config = fiftyUpdates("mma");
  config.optimization.minFirstFrequency = 5.0;
  const std::vector<IterationRecord> history = run(config);
  int stepBacks = 0;
  for (const IterationRecord& r : history) stepBacks += r.backtracks;
  std::cout << "[ guard ] psi1 " << history.front().psi1 << " -> " << history.back().psi1 << ", step-backs "
            << stepBacks << "\n";
  EXPECT_EQ(stepBacks, 0);
  EXPECT_LT(history.back().psi1, 0.1 * history.front().psi1);
}

}  // namespace
}  // namespace hindsight
