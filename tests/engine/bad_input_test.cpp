// Bad input is rejected with std::invalid_argument naming the argument and the value; numerical
// failures carry the simulation time (docs/design.md P 4).
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/storage_factory.h>
#include "support/engine_fixtures.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hindsight {
namespace {

using testing::invalidArgumentMessage;

TEST(BadInput, WrongParameterSizeNamesBothSizes) {
  ExponentialDecay problem;
  const auto message =
      invalidArgumentMessage([&] { simulate(problem, Vector::Ones(3), IntegratorOptions{}); });
  EXPECT_NE(message.find("parameter vector p has size 3"), std::string::npos) << message;
  EXPECT_NE(message.find("expects 2"), std::string::npos) << message;
}

TEST(BadInput, NonPositiveStepNamesTheField) {
  ExponentialDecay problem;
  IntegratorOptions options;
  for (double step : {0.0, -1e-3, std::numeric_limits<double>::quiet_NaN()}) {
    options.step = step;
    const auto message = invalidArgumentMessage([&] { simulate(problem, Vector::Ones(2), options); });
    EXPECT_NE(message.find("IntegratorOptions.step"), std::string::npos) << message;
  }
}

TEST(BadInput, EndTimeNotAfterStartTime) {
  ExponentialDecay problem;
  IntegratorOptions options;
  options.t0 = 1.0;
  options.t1 = 1.0;
  const auto message = invalidArgumentMessage([&] { simulate(problem, Vector::Ones(2), options); });
  EXPECT_NE(message.find("t1 = 1"), std::string::npos) << message;
  EXPECT_NE(message.find("t0 = 1"), std::string::npos) << message;
}

TEST(BadInput, NaNInInitialStateNamesTheEntry) {
  ExponentialDecay problem;
  const Vector p = Eigen::Vector2d(1.0, std::numeric_limits<double>::quiet_NaN());
  const auto message = invalidArgumentMessage([&] { simulate(problem, p, IntegratorOptions{}); });
  EXPECT_NE(message.find("z0[0]"), std::string::npos) << message;
}

TEST(BadInput, UnknownMethodListsTheKnownOnes) {
  ExponentialDecay problem;
  IntegratorOptions options;
  options.method = "euler";
  const auto message = invalidArgumentMessage([&] { simulate(problem, Vector::Ones(2), options); });
  EXPECT_NE(message.find("'euler'"), std::string::npos) << message;
  EXPECT_NE(message.find("trbdf2"), std::string::npos) << message;
}

TEST(BadInput, AdaptiveNeedsAnEmbeddedPair) {
  ExponentialDecay problem;
  IntegratorOptions options;
  options.method = "rk4";
  options.adaptive = true;
  const auto message = invalidArgumentMessage([&] { simulate(problem, Vector::Ones(2), options); });
  EXPECT_NE(message.find("no embedded error estimate"), std::string::npos) << message;
}

/// z' = z^2 blows up at t = 1/z0: the adaptive controller must give up with the time.
class BlowUp final : public Problem {
 public:
  std::string name() const override { return "blow-up"; }
  int stateSize() const override { return 1; }
  int parameterSize() const override { return 1; }
  void initialState(ConstVectorRef p, VectorRef z0) const override { z0(0) = p(0); }
  void rhs(double, ConstVectorRef z, ConstVectorRef, VectorRef f, ProblemWorkspace*) const override {
    f(0) = z(0) * z(0);
  }
  void rhsJacobian(double, ConstVectorRef z, ConstVectorRef, MatrixRef j, ProblemWorkspace*) const override {
    j(0, 0) = 2.0 * z(0);
  }
  void addRhsParameterVjp(double, ConstVectorRef, ConstVectorRef, ConstVectorRef, VectorRef,
                          ProblemWorkspace*) const override {}
  double integrand(double, ConstVectorRef, ConstVectorRef, ProblemWorkspace*) const override { return 0.0; }
  void addIntegrandStateGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                 ProblemWorkspace*) const override {}
  void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                     ProblemWorkspace*) const override {}
};

TEST(NumericalFailure, StepSizeUnderflowCarriesTheTime) {
  BlowUp problem;
  IntegratorOptions options;
  options.method = "dopri5";
  options.adaptive = true;
  options.t1 = 2.0;
  options.minStep = 1e-10;
  try {
    simulate(problem, Vector::Ones(1), options);
    FAIL() << "no NumericalError";
  } catch (const NumericalError& e) {
    EXPECT_NEAR(e.time(), 1.0, 1e-3) << e.what();
    EXPECT_NE(std::string(e.what()).find("at t = "), std::string::npos);
  }
}

TEST(NumericalFailure, NewtonDivergenceCarriesTheTime) {
  // Fixed-step implicit midpoint with a step far beyond the blow-up: the stage equation
  // k = (z + h k / 2)^2 has no real solution, so Newton cannot converge.
  BlowUp problem;
  IntegratorOptions options;
  options.method = "midpoint";
  options.t1 = 2.0;
  options.step = 0.5;
  try {
    simulate(problem, Vector::Ones(1) * 3.0, options);
    FAIL() << "no NumericalError";
  } catch (const NumericalError& e) {
    EXPECT_GE(e.time(), 0.0);
    EXPECT_LE(e.time(), 2.0);
    EXPECT_NE(std::string(e.what()).find("Newton"), std::string::npos) << e.what();
  }
}

TEST(GradientChecker, AcceptsTheRightGradientAndRejectsAWrongOne) {
  const auto f = [](const Vector& x) { return std::sin(x(0)) * x(1) * x(1) + std::exp(0.3 * x(2)); };
  const Vector x = Eigen::Vector3d(0.4, -1.7, 2.0);
  Vector right(3);
  right << std::cos(x(0)) * x(1) * x(1), 2.0 * std::sin(x(0)) * x(1), 0.3 * std::exp(0.3 * x(2));
  const auto good = checkGradient(f, x, right, {1e-8});
  EXPECT_TRUE(good.passed) << good.message;
  EXPECT_LT(good.maxError, 1e-8);
  // A wrong term (a factor 2 dropped in one component) must be caught, and the component named.
  Vector wrong = right;
  wrong(1) = std::sin(x(0)) * x(1);
  const auto bad = checkGradient(f, x, wrong, {1e-6});
  EXPECT_FALSE(bad.passed);
  EXPECT_EQ(bad.worstIndex, 1);
  EXPECT_NE(bad.message.find("worst component 1"), std::string::npos) << bad.message;
  // A small relative perturbation (1e-4) of one component is caught too.
  Vector slightlyWrong = right;
  slightlyWrong(2) *= 1.0 + 1e-4;
  EXPECT_FALSE(checkGradient(f, x, slightlyWrong, {1e-6}).passed);
  EXPECT_THROW(checkGradient(f, x, Vector::Zero(2)), std::invalid_argument);
}

TEST(StorageSpecs, MalformedSpecsAndUnknownKeysAreRejectedWithTheValidOnes) {
  EXPECT_NE(invalidArgumentMessage([] { createStorage("nonsense"); }).find("known: full"), std::string::npos);
  const auto unknownKey = invalidArgumentMessage([] { createStorage("full:every=3"); });
  EXPECT_NE(unknownKey.find("unknown key 'every'"), std::string::npos) << unknownKey;
  EXPECT_NE(unknownKey.find("valid keys: budget"), std::string::npos) << unknownKey;
  EXPECT_NE(invalidArgumentMessage([] { createStorage("full:budget"); }).find("key=value"),
            std::string::npos);
  EXPECT_NE(invalidArgumentMessage([] { createStorage("full:budget=-3MiB"); }).find("full.budget"),
            std::string::npos);
  EXPECT_NE(invalidArgumentMessage([] { createStorage("full:budget=12XB"); }).find("full.budget"),
            std::string::npos);
  EXPECT_EQ(createStorage("full:budget=32MiB")->budgetBytes(), 32 << 20);
  EXPECT_EQ(createStorage("full")->spec(), "full");
}

TEST(StorageBudget, FullStorageNeverExceedsItsBudgetAndSaysSo) {
  ExponentialDecay problem;
  IntegratorOptions options;
  options.t1 = 1.0;
  options.step = 1e-3;  // 1000 states of 8 bytes
  FullStorage storage(4000);
  try {
    computeGradient(problem, Eigen::Vector2d(1.0, 1.0), options, storage);
    FAIL() << "no StorageError";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("budget"), std::string::npos) << e.what();
  }
  EXPECT_LE(storage.counters().peakBytesInMemory, 4000);
  FullStorage enough(8000);
  const auto result = computeGradient(problem, Eigen::Vector2d(1.0, 1.0), options, enough);
  EXPECT_EQ(enough.counters().peakBytesInMemory, 8000);
  EXPECT_EQ(result.summary.recomputedSteps, 0);
}

}  // namespace
}  // namespace hindsight
