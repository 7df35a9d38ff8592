// The stage-aware strategies (full:stages=1, disk:stages=1, cams) on the reduced rod,
// the full-order rod and Robertson (adaptive): psi and dpsi/dp bitwise equal to `full`, every restore and
// every restored step record hash-verified, the byte budget never exceeded, and the adjoint steps served
// from stored stage values evaluating no right-hand side.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/integrator.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/problems/rod/full_order_rod.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_factory.h>
#include "support/allocation_counting.h"
#include "support/same_bits.h"
#include "support/slider_crank.h"
#include "support/synthetic_rod.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>

namespace hindsight::rod {
namespace {

using testing::sameBits;

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
    EXPECT_TRUE(sameBits(result.gradient, reference.gradient));
    EXPECT_LE(storage->counters().peakBytesInMemory, storage->budgetBytes());
    EXPECT_GT(storage->counters().stepDataRestored, 0);
    if (spec.find("stages=1") != std::string::npos &&
        (spec.rfind("full", 0) == 0 || spec.rfind("disk", 0) == 0)) {
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
                           "cams:checkpoints=50", "cams:budget=4KiB", "binomial:checkpoints=10,stages=1",
                           "online:checkpoints=10,stages=1"});
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
    EXPECT_TRUE(sameBits(r.gradient, b.gradient));
  }
}

// `hindsight schedule` (storage/schedule.h) predicts the strategies that keep stages without a model: on the
// reduced rod (rk4, N = 1000; its records hold each stage's rhs data, 9 doubles for 3 modes) every counter
// of the run, for few and many checkpoints.
TEST(StageAwareStorage, ReducedRodStagesAsPredicted) {
  const testing::SyntheticRod body(3, 1.0, 7);
  const SliderCrankProblem problem(3, 1.0, CrankMotion{});
  const Vector p = body.invariants();
  IntegratorOptions options;
  options.t1 = 1.0;
  options.step = 1e-3;  // N = 1000
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  const std::int64_t stateBytes = 8 * problem.stateSize();
  const std::int64_t stageBytes = 8 * problem.rhsDataSize();
  ASSERT_EQ(stageBytes, 8 * (3 + 6));
  std::vector<std::string> specs = {"full:stages=1", "cams:checkpoints=10", "online:checkpoints=10,stages=1"};
  for (int c : {2, 10, 50, 2000}) specs.push_back("binomial:checkpoints=" + std::to_string(c) + ",stages=1");
  for (const std::string& spec : specs) {
    SCOPED_TRACE(spec);
    const auto storage = createStorage(spec);
    storage->setVerifyRestores(true);
    const GradientResult result = computeGradient(problem, p, options, *storage);
    EXPECT_TRUE(sameBits(result.gradient, reference.gradient));
    const SchedulePrediction predicted =
        predictSchedule(spec, result.summary.steps, stateBytes, 4, nullptr, stageBytes);
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

// The rhs data of a SecondOrderProblem (engine/second_order_problem.h): a workspace restored from the data
// that one rhs() left gives every product at that point the bits of a workspace that evaluated rhs() there,
// and of one that evaluates it inside the product.
TEST(StageAwareStorage, RestoredRhsDataGiveTheProductsOfAnEvaluatedRhs) {
  for (int modes : {3, 10}) {
    SCOPED_TRACE(modes);
    const testing::SyntheticRod body(modes, 1.0, 7);
    const SliderCrankProblem problem(modes, 1.0, CrankMotion{});
    const Problem& first = problem;  // the first-order interface the integrators use
    const Vector p = body.invariants();
    const int n = problem.stateSize();
    ASSERT_EQ(problem.rhsDataSize(), modes + modes * (modes + 1) / 2);
    std::mt19937 generator(5);
    std::uniform_real_distribution<double> u(-0.02, 0.02);
    Vector z(n), w(n);
    for (int i = 0; i < n; ++i) {
      z(i) = u(generator);
      w(i) = 50.0 * u(generator);
    }
    const double t = 0.37;
    const auto evaluated = first.createWorkspaceFor(p);
    const auto restored = first.createWorkspaceFor(p);
    const auto cold = first.createWorkspaceFor(p);
    Vector f(n), data(problem.rhsDataSize()), again(problem.rhsDataSize());
    first.rhs(t, z, p, f, evaluated.get());
    first.saveRhsData(evaluated.get(), data);
    // The data are the acceleration and the factor's lower triangle: the acceleration is F's second half.
    EXPECT_TRUE(sameBits(data.head(modes), f.tail(modes)));
    first.restoreRhsData(t, z, p, data, restored.get());
    first.saveRhsData(restored.get(), again);
    EXPECT_TRUE(sameBits(data, again));
    Vector fRestored(n);
    first.rhs(t, z, p, fRestored, restored.get());
    EXPECT_TRUE(sameBits(f, fRestored));

    ProblemWorkspace* spaces[3] = {evaluated.get(), restored.get(), cold.get()};
    Vector state[3], gradient[3], stateOnly[3], parameterOnly[3];
    Matrix jacobian[3];
    for (int k = 0; k < 3; ++k) {
      state[k] = Vector::Zero(n);
      gradient[k] = Vector::Zero(p.size());
      stateOnly[k] = Vector::Zero(n);
      parameterOnly[k] = Vector::Zero(p.size());
      jacobian[k] = Matrix::Zero(n, n);
      first.rhsVjps(t, z, p, w, state[k], gradient[k], spaces[k]);
      first.rhsStateVjp(t, z, p, w, stateOnly[k], spaces[k]);
      first.addRhsParameterVjp(t, z, p, w, parameterOnly[k], spaces[k]);
      first.rhsJacobian(t, z, p, jacobian[k], spaces[k]);
    }
    for (int k = 1; k < 3; ++k) {
      SCOPED_TRACE(k);
      EXPECT_TRUE(sameBits(state[k], state[0]));
      EXPECT_TRUE(sameBits(gradient[k], gradient[0]));
      EXPECT_TRUE(sameBits(stateOnly[k], stateOnly[0]));
      EXPECT_TRUE(sameBits(parameterOnly[k], parameterOnly[0]));
      EXPECT_TRUE(sameBits(jacobian[k], jacobian[0]));
    }
    // The products are not trivially equal: the point matters.
    EXPECT_GT(state[0].norm(), 0.0);
    EXPECT_GT(gradient[0].norm(), 0.0);
  }
}

// rk4's step records with rhs data (Integrator::stepRhsDataSize()): each stage's data are the bits a fresh
// rhs() at that stage's state and time leaves, the acceleration among them; without rhs data the record is
// the stage states alone.
TEST(StageAwareStorage, StoredAccelerationsEqualRecomputedOnes) {
  const testing::SyntheticRod body(4, 1.0, 7);
  const SliderCrankProblem problem(4, 1.0, CrankMotion{});
  const Problem& first = problem;
  const Vector p = body.invariants();
  const int n = problem.stateSize(), d = problem.rhsDataSize();
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 1.0;
  options.step = 1e-3;
  const auto integrator = createIntegrator(problem, p, options);
  ASSERT_EQ(integrator->stepDataSize(), 3 * n);
  ASSERT_EQ(integrator->stepRhsDataSize(), 4 * d);
  integrator->setSavesStepData(true, true);
  Vector z(n);
  integrator->initialState(0.0, z);
  double t = 0.0;
  const double h = 1e-3;
  for (int k = 0; k < 300; ++k, t += h) integrator->step(t, h, z);  // into the ramp: a moving state
  const Vector zStart = z;
  integrator->step(t, h, z);
  Vector data(3 * n + 4 * d);
  integrator->saveStepData(data);
  const double c[4] = {0.0, 0.5, 0.5, 1.0};
  for (int i = 0; i < 4; ++i) {
    SCOPED_TRACE(i);
    const Vector stage = i == 0 ? zStart : Vector(data.segment((i - 1) * n, n));
    const auto ws = first.createWorkspaceFor(p);
    Vector f(n), fresh(d);
    first.rhs(t + c[i] * h, stage, p, f, ws.get());
    first.saveRhsData(ws.get(), fresh);
    EXPECT_TRUE(sameBits(data.segment(3 * n + i * d, d), fresh));
    EXPECT_TRUE(sameBits(data.segment(3 * n + i * d, 4), f.tail(4)));
    EXPECT_GT(f.tail(4).norm(), 0.0);
  }
  // Asked for the stage states alone, the record is those, the same bits.
  const auto plain = createIntegrator(problem, p, options);
  plain->setSavesStepData(true, false);
  Vector zPlain = zStart;
  plain->step(t, h, zPlain);
  Vector states(3 * n);
  plain->saveStepData(states);
  EXPECT_TRUE(sameBits(states, data.head(3 * n)));
  EXPECT_TRUE(sameBits(zPlain, z));
  // The adjoint step from either record, and the one that recomputes the stages, agree bit for bit.
  Vector lambda[3], gradient[3];
  for (int k = 0; k < 3; ++k) {
    lambda[k] = Vector::Constant(n, 0.25);
    gradient[k] = Vector::Zero(p.size());
  }
  {
    // The step that keeps rhs data, its record and the adjoint step from it allocate nothing.
    Vector zAgain = zStart;
    Vector record(data.size());
    testing::AllocationCounter counter;
    integrator->step(t, h, zAgain);
    integrator->saveStepData(record);
    integrator->adjointStepFromData(t, h, zStart, record, lambda[0], gradient[0]);
    EXPECT_EQ(counter.count(), 0);
    EXPECT_TRUE(sameBits(record, data));
  }
  plain->adjointStepFromData(t, h, zStart, states, lambda[1], gradient[1]);
  plain->adjointStep(t, h, zStart, lambda[2], gradient[2]);
  for (int k = 1; k < 3; ++k) {
    EXPECT_TRUE(sameBits(lambda[k], lambda[0])) << k;
    EXPECT_TRUE(sameBits(gradient[k], gradient[0])) << k;
  }
}

}  // namespace
}  // namespace hindsight::rod
