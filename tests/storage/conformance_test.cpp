// The one conformance suite every trajectory storage strategy runs through (docs/design.md P 6,
// docs/design.md §6). Adding a strategy means adding one line to strategiesUnderTest() below. The
// cases cover Runge-Kutta (integrator state = problem state) and generalized-alpha (a larger state).
//
// Properties checked on every case: the strategy's psi and dpsi/dp against `full` (bitwise, with == and
// memcmp, for exact strategies; within the listed relative tolerance for the others); every restore
// verified against the hash of the recorded bits (setVerifyRestores(true)); the peak bytes in memory
// within budgetBytes(); counters that make sense (full recomputes nothing and stores every state); the
// same storage object reused for a second run gives the same bits.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/problems/classic/heat_equation.h>
#include <hindsight/storage/storage_factory.h>

#include <gtest/gtest.h>

#include <filesystem>

#include <cctype>
#include <cstring>

namespace hindsight {
namespace {

struct StrategyUnderTest {
  std::string spec;
  /// True for strategies that need TrajectoryInfo.stepCount (fixed steps); skipped for adaptive steps.
  bool needsKnownStepCount = false;
  /// Inexact strategies only (isExact() == false): the largest accepted ||g - g_full|| / ||g_full||.
  double relativeTolerance = 0.0;
};

constexpr bool kNeedsStepCount = true;

const std::vector<StrategyUnderTest>& strategiesUnderTest() {
  static const std::string tmp = std::filesystem::temp_directory_path().string();
  static const std::vector<StrategyUnderTest> list = {
      {"full"},
      {"full:budget=64MiB"},
      {"full:stages=1"},
      {"full:budget=64MiB,stages=1"},
      {"binomial:checkpoints=1", kNeedsStepCount},
      {"binomial:checkpoints=2", kNeedsStepCount},
      {"binomial:checkpoints=5", kNeedsStepCount},
      {"binomial:checkpoints=20,budget=16MiB", kNeedsStepCount},
      {"binomial:checkpoints=100", kNeedsStepCount},
      {"cams:checkpoints=1"},  // adaptive steps: the online mode
      {"cams:checkpoints=3"},
      {"cams:checkpoints=20"},
      {"cams:budget=64KiB"},
      {"cams:checkpoints=2,online=1"},
      {"cams:checkpoints=20,online=1"},
      {"online:checkpoints=1"},
      {"online:checkpoints=3"},
      {"online:checkpoints=20"},
      {"online:budget=1MiB"},
      {"disk:dir=" + tmp + ",chunk=7"},
      {"disk:dir=" + tmp + ",level=1"},
      {"packed"},
      {"packed:block=3"},
      {"online:checkpoints=3,stages=1"},
      {"binomial:checkpoints=5,stages=1", kNeedsStepCount},
      {"binomial:checkpoints=100,stages=1", kNeedsStepCount},
      {"disk:dir=" + tmp + ",chunk=7,stages=1"},
      {"multilevel:ram=64MiB,disk=1GiB,dir=" + tmp},
      {"multilevel:ram=24KiB,disk=16MiB,dir=" + tmp},
      {"multilevel:ram=64KiB,disk=128KiB,dir=" + tmp},
      {"multilevel:ram=48KiB,disk=16MiB,costs=1:1:0.1:0.1,dir=" + tmp},
      {"multilevel:ram=40KiB,disk=40KiB,costs=1:1:0:0,dir=" + tmp},
      {"multilevel:ram=64KiB,disk=128KiB,schedule=stride,dir=" + tmp},
      {"lossy:codec=zfp,tolerance=1e-10", false, 1e-6},
      {"lossy:codec=round,tolerance=1e-12", false, 1e-8},
      {"hermite:every=4", false, 1e-4},
  };
  return list;
}

std::vector<std::string> specs() {
  std::vector<std::string> out;
  for (const auto& s : strategiesUnderTest()) out.push_back(s.spec);
  return out;
}

const StrategyUnderTest& lookup(const std::string& spec) {
  for (const auto& s : strategiesUnderTest())
    if (s.spec == spec) return s;
  throw std::logic_error("no strategy " + spec);
}

std::string testName(const std::string& spec) {
  std::string name;
  for (char c : spec) name += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return name;
}

class Conformance : public ::testing::TestWithParam<std::string> {
 protected:
  const StrategyUnderTest& strategy() const { return lookup(GetParam()); }

  void run(const Problem& problem, const Vector& p, const IntegratorOptions& options) {
    if (options.adaptive && strategy().needsKnownStepCount) {
      GTEST_SKIP() << "'" << GetParam()
                   << "' needs the number of steps in advance; adaptive steps make it unknown";
    }
    FullStorage full;
    full.setVerifyRestores(true);
    const GradientResult reference = computeGradient(problem, p, options, full);
    ASSERT_EQ(full.counters().recomputedSteps, 0);
    ASSERT_EQ(full.counters().statesStored, reference.summary.steps);

    const std::unique_ptr<TrajectoryStorage> storage = createStorage(GetParam());
    storage->setVerifyRestores(true);
    const GradientResult result = computeGradient(problem, p, options, *storage);
    expectSameGradient(result, reference, *storage);

    const StorageCounters& counters = storage->counters();
    EXPECT_LE(counters.peakBytesInMemory, storage->budgetBytes());
    EXPECT_GT(counters.peakBytesInMemory, 0);
    EXPECT_GE(counters.statesStored, 1);
    EXPECT_GE(counters.recomputedSteps, 0);
    EXPECT_EQ(result.summary.recomputedSteps, counters.recomputedSteps);
    EXPECT_EQ(result.summary.steps, reference.summary.steps);
    if (StorageSpec::parse(GetParam()).name() == "full") EXPECT_EQ(counters.recomputedSteps, 0);
    const std::string name = StorageSpec::parse(GetParam()).name();
    if (storage->keepsStepData() && (name == "full" || name == "disk") &&
        isRungeKutta(parseIntegratorMethod(options.method))) {
      // Every step's stage values are kept: no adjoint step evaluates the right-hand side, so the run
      // evaluates it exactly as often as the forward sweep alone.
      EXPECT_EQ(counters.stepDataRestored, result.summary.steps);
      EXPECT_EQ(counters.stepDataStored, result.summary.steps);
      EXPECT_EQ(result.summary.rhsEvaluations, simulate(problem, p, options).summary.rhsEvaluations);
      EXPECT_LT(result.summary.rhsEvaluations, reference.summary.rhsEvaluations);
    }

    if (storage->keepsStepData() && (name == "binomial" || name == "online") &&
        isRungeKutta(parseIntegratorMethod(options.method)) && result.summary.steps > 2) {
      // Every restore that recomputes leaves the stages of the step before it, so the next adjoint
      // step finds them; restores that load a checkpoint placed exactly there leave none.
      EXPECT_GT(counters.stepDataRestored, 0);
      // The same revolve schedule as without stages, and fewer right-hand sides.
      std::string plainSpec = GetParam();
      plainSpec.erase(plainSpec.find(",stages=1"), 9);
      const std::unique_ptr<TrajectoryStorage> plain = createStorage(plainSpec);
      const GradientResult plainResult = computeGradient(problem, p, options, *plain);
      EXPECT_EQ(counters.recomputedSteps, plain->counters().recomputedSteps);
      EXPECT_LT(result.summary.rhsEvaluations, plainResult.summary.rhsEvaluations);
    }

    // Reuse: begin() resets everything; the second run reproduces the first, counters included.
    const std::int64_t recomputed = counters.recomputedSteps;
    const GradientResult again = computeGradient(problem, p, options, *storage);
    expectSameGradient(again, reference, *storage);
    // multilevel without costs= times forward steps and disk I/O at the start of each run and plans by
    // those times (storage/multilevel_storage.h), so its recomputation count may differ between runs;
    // the gradient's bits may not.
    const bool timedPlan =
        GetParam().rfind("multilevel", 0) == 0 && GetParam().find("costs=") == std::string::npos;
    if (!timedPlan) EXPECT_EQ(storage->counters().recomputedSteps, recomputed);
    EXPECT_LE(storage->counters().peakBytesInMemory, storage->budgetBytes());
  }

  void expectSameGradient(const GradientResult& result, const GradientResult& reference,
                          const TrajectoryStorage& storage) {
    ASSERT_EQ(result.gradient.size(), reference.gradient.size());
    if (storage.isExact()) {
      EXPECT_EQ(result.objective, reference.objective);
      EXPECT_EQ(std::memcmp(result.gradient.data(), reference.gradient.data(),
                            sizeof(double) * static_cast<std::size_t>(result.gradient.size())),
                0)
          << "gradient differs from full: " << (result.gradient - reference.gradient).transpose();
    } else {
      ASSERT_GT(strategy().relativeTolerance, 0.0) << "an inexact strategy needs a tolerance in the list";
      EXPECT_LE((result.gradient - reference.gradient).norm(),
                strategy().relativeTolerance * reference.gradient.norm());
    }
  }
};

INSTANTIATE_TEST_SUITE_P(Strategies, Conformance, ::testing::ValuesIn(specs()),
                         [](const auto& info) { return testName(info.param); });

TEST_P(Conformance, PendulumRk4FixedStep) {
  Pendulum problem;
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 4.0;
  options.step = 4e-3;  // N = 1000
  run(problem, Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), options);
}

TEST_P(Conformance, PendulumTrBdf2Adaptive) {
  Pendulum problem;
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 4.0;
  options.adaptive = true;
  options.step = 1e-3;
  options.relativeTolerance = 1e-6;
  options.absoluteTolerance = 1e-8;
  run(problem, Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), options);
}

TEST_P(Conformance, PendulumGeneralizedAlphaFixedStep) {
  // The strategies record, restore and recompute the integrator's state (y, v, d, a), twice the
  // problem's; a strategy that interpolates needs a state derivative generalized-alpha does not have.
  if (createStorage(GetParam())->needsDerivative()) {
    GTEST_SKIP() << "'" << GetParam() << "' interpolates with the state derivative";
  }
  Pendulum problem;
  IntegratorOptions options;
  options.method = "generalized-alpha";
  options.rhoInfinity = 0.8;
  options.t1 = 4.0;
  options.step = 4e-3;  // N = 1000
  run(problem, Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), options);
}

TEST_P(Conformance, ShortestTrajectoryOfOneStep) {
  Pendulum problem;
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 0.01;
  options.step = 0.01;
  run(problem, Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), options);
}

TEST_P(Conformance, LargeStateReactionDiffusionRk4) {
  HeatEquation problem(2000, 3);  // 16 kB per state
  Vector p = problem.nominalParameters();
  p(0) = 1e-4;  // D / h^2 = 400: RK4 stable for h_t < 1.7e-3
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 0.15;
  options.step = 1e-3;  // N = 150
  run(problem, p, options);
}

TEST_P(Conformance, LargeStateReactionDiffusionTrBdf2Adaptive) {
  HeatEquation problem(1000, 3);
  Vector p = problem.nominalParameters();
  p(0) = 1e-3;
  p(1) = 3.0;
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 1.0;
  options.adaptive = true;
  options.step = 1e-3;
  options.relativeTolerance = 1e-6;
  options.absoluteTolerance = 1e-9;
  run(problem, p, options);
}

TEST(StorageFactory, EveryListedStrategyIsRegisteredAndUnknownNamesListThem) {
  for (const auto& s : strategiesUnderTest()) EXPECT_NO_THROW(createStorage(s.spec)) << s.spec;
  try {
    createStorage("revolve:checkpoints=3");
    FAIL() << "no std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    for (const auto& name : storageStrategyNames()) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace hindsight
