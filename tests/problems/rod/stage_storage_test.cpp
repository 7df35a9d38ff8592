// The stage-aware strategies (full:stages=1, disk:stages=1, cams) on the reduced rod,
// the full-order rod and Robertson (adaptive): psi and dpsi/dp bitwise equal to `full`, every restore and
// every restored step record hash-verified, the byte budget never exceeded, and the adjoint steps served
// from stored stage values evaluating no right-hand side.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/problems/rod/full_order_rod.h>
#include <hindsight/problems/rod/slider_crank.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_factory.h>
#include "support/synthetic_rod.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <random>

namespace hindsight::rod {
namespace {

void expectBitwiseLikeFull(const Problem& problem, const Vector& p, const IntegratorOptions& options,
                           const std::vector<std::string>& specs) {
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  const std::int64_t forwardRhs = simulate(problem, p, options).summary.rhsEvaluations;
  for (const std::string& spec : specs) {
    SCOPED_TRACE(spec + " with " + options.method);
    const auto storage = createStorage(spec);
    storage->setVerifyRestores(true);
    const GradientResult result = computeGradient(problem, p, options, *storage);
    EXPECT_EQ(result.objective, reference.objective);
    ASSERT_EQ(result.gradient.size(), reference.gradient.size());
    EXPECT_EQ(std::memcmp(result.gradient.data(), reference.gradient.data(),
                          sizeof(double) * static_cast<std::size_t>(result.gradient.size())),
              0);
    EXPECT_LE(storage->counters().peakBytesInMemory, storage->budgetBytes());
    EXPECT_GT(storage->counters().stepDataRestored, 0);
    if (spec.find("stages=1") != std::string::npos) {
      // Every step's stage values stored: the adjoint evaluates no right-hand side at all.
      EXPECT_EQ(storage->counters().stepDataRestored, result.summary.steps);
      EXPECT_EQ(result.summary.rhsEvaluations, forwardRhs);
    }
  }
}

TEST(StageAwareStorage, ReducedRodBitwiseLikeFull) {
  const testing::SyntheticRod body(3, 1.0, 7);
  const SliderCrankProblem problem(3, 1.0, CrankMotion{});
  const Vector p = body.invariants();
  const std::string tmp = std::filesystem::temp_directory_path().string();
  for (const std::string method : {"rk4", "trbdf2", "sdirk2"}) {
    IntegratorOptions options;
    options.method = method;
    options.t1 = 1.0;
    options.step = 1e-3;  // N = 1000
    expectBitwiseLikeFull(problem, p, options,
                          {"full:stages=1", "disk:dir=" + tmp + ",chunk=16,stages=1", "cams:checkpoints=10",
                           "cams:checkpoints=50", "cams:budget=4KiB"});
  }
}

TEST(StageAwareStorage, ReducedRodCamsNeedsFewerRhsThanBinomialAtTheSameBytes) {
  const testing::SyntheticRod body(3, 1.0, 7);
  const SliderCrankProblem problem(3, 1.0, CrankMotion{});
  const Vector p = body.invariants();
  IntegratorOptions options;
  options.t1 = 1.0;
  options.step = 5e-4;  // N = 2000
  for (int c : {10, 50}) {
    const auto binomial = createStorage("binomial:checkpoints=" + std::to_string(c));
    const auto cams = createStorage("cams:checkpoints=" + std::to_string(c));
    const GradientResult b = computeGradient(problem, p, options, *binomial);
    const GradientResult r = computeGradient(problem, p, options, *cams);
    EXPECT_LT(r.summary.rhsEvaluations, b.summary.rhsEvaluations) << c;
    EXPECT_LE(cams->counters().peakBytesInMemory, binomial->counters().peakBytesInMemory) << c;
    EXPECT_EQ(std::memcmp(r.gradient.data(), b.gradient.data(),
                          sizeof(double) * static_cast<std::size_t>(p.size())),
              0);
  }
}

// `hindsight schedule` (storage/schedule.h) predicts binomial:stages=1 without a model: on the reduced rod
// (rk4, N = 1000) every counter of the run, for few and many checkpoints.
TEST(StageAwareStorage, ReducedRodBinomialStagesAsPredicted) {
  const testing::SyntheticRod body(3, 1.0, 7);
  const SliderCrankProblem problem(3, 1.0, CrankMotion{});
  const Vector p = body.invariants();
  IntegratorOptions options;
  options.t1 = 1.0;
  options.step = 1e-3;  // N = 1000
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  const std::int64_t stateBytes = 8 * problem.stateSize();
  for (int c : {2, 10, 50, 2000}) {
    const std::string spec = "binomial:checkpoints=" + std::to_string(c) + ",stages=1";
    SCOPED_TRACE(spec);
    const auto storage = createStorage(spec);
    storage->setVerifyRestores(true);
    const GradientResult result = computeGradient(problem, p, options, *storage);
    EXPECT_EQ(std::memcmp(result.gradient.data(), reference.gradient.data(),
                          sizeof(double) * static_cast<std::size_t>(p.size())),
              0);
    const SchedulePrediction predicted = predictSchedule(spec, result.summary.steps, stateBytes, 4, nullptr);
    EXPECT_EQ(predicted.recomputedSteps, result.summary.recomputedSteps);
    EXPECT_EQ(predicted.rhsEvaluations, result.summary.rhsEvaluations);
    EXPECT_EQ(predicted.stepDataStored, storage->counters().stepDataStored);
    EXPECT_EQ(predicted.stepDataRestored, storage->counters().stepDataRestored);
    EXPECT_EQ(predicted.statesStored, storage->counters().statesStored);
    EXPECT_EQ(predicted.peakRamBytes, storage->counters().peakBytesInMemory);
    EXPECT_GT(predicted.stepDataRestored, 0);
  }
}

TEST(StageAwareStorage, FullOrderRodBitwiseLikeFull) {
  RodConfig config;
  config.elementsAlongLength = 10;
  config.elementsThroughHeight = 2;
  std::mt19937 generator(13);
  std::uniform_real_distribution<double> u(0.02, 1.0);
  Vector x(config.designCount());
  for (Eigen::Index i = 0; i < x.size(); ++i) x(i) = u(generator);
  const FullOrderRodProblem problem(config, x, CrankMotion{0.15, 10.0 * M_PI, 0.05}, true);
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 0.02;
  options.step = 1e-4;  // N = 200
  options.newtonTolerance = 1e-10;
  expectBitwiseLikeFull(problem, x, options, {"full:stages=1", "cams:checkpoints=5", "cams:checkpoints=30"});
}

TEST(StageAwareStorage, RobertsonAdaptiveStagesAreTheAcceptedStepsStages) {
  const Robertson problem(40.0);
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 40.0;
  options.adaptive = true;
  options.step = 1e-6;
  options.relativeTolerance = 1e-6;
  options.absoluteTolerance = 1e-10;
  const std::string tmp = std::filesystem::temp_directory_path().string();
  // cams with adaptive steps runs its online mode (N unknown while recording).
  expectBitwiseLikeFull(problem, Robertson::nominalParameters(), options,
                        {"full:stages=1", "disk:dir=" + tmp + ",chunk=5,stages=1", "cams:checkpoints=5",
                         "cams:checkpoints=30"});
}

}  // namespace
}  // namespace hindsight::rod
