// The discrete adjoint against closed forms (linear ODEs) and against finite differences of the
// computed psi (nonlinear and stiff problems), for every integrator.
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/engine/runge_kutta.h>
#include <hindsight/problems/classic/classic_problems.h>
#include "support/engine_fixtures.h"

#include <gtest/gtest.h>

#include <cmath>

namespace hindsight {
namespace {

using testing::complexStepGradient;
using testing::computedObjective;
using testing::gradientWithFullStorage;

IntegratorOptions fixedStep(const std::string& method, double t1, double h) {
  IntegratorOptions options;
  options.method = method;
  options.t1 = t1;
  options.step = h;
  return options;
}

class EveryMethod : public ::testing::TestWithParam<std::string> {};

INSTANTIATE_TEST_SUITE_P(Integrators, EveryMethod,
                         ::testing::Values("rk4", "dopri5", "trbdf2", "sdirk2", "midpoint"),
                         [](const auto& info) { return info.param; });

TEST_P(EveryMethod, ExponentialDecayMatchesClosedForm) {
  ExponentialDecay problem;
  const Vector p = Eigen::Vector2d(1.3, 0.7);
  const double horizon = 2.0;
  const auto options = fixedStep(GetParam(), horizon, 1e-3);
  const GradientResult result = gradientWithFullStorage(problem, p, options);
  const double exact = ExponentialDecay::exactObjective(p(0), p(1), horizon);
  const Vector exactGradient = complexStepGradient(
      [&](const Eigen::VectorXcd& x) { return ExponentialDecay::exactObjective(x(0), x(1), horizon); }, p);
  // Order-2 methods at h = 1e-3 are accurate to ~1e-6 relative; order 4 and 5 to ~1e-12.
  const double tolerance = (GetParam() == "rk4" || GetParam() == "dopri5") ? 1e-10 : 2e-6;
  EXPECT_NEAR(result.objective, exact, tolerance * std::abs(exact));
  EXPECT_LT((result.gradient - exactGradient).norm(), tolerance * exactGradient.norm());
  // The discrete adjoint is the derivative of the computed psi.
  const auto check = checkGradient(computedObjective(problem, options), p, result.gradient, {1e-8});
  EXPECT_TRUE(check.passed) << check.message;
}

TEST_P(EveryMethod, OscillatorMatchesClosedFormUndampedAndDamped) {
  Oscillator problem;
  const double horizon = 3.0;
  for (double damping : {0.0, 0.4}) {
    const Vector p = Eigen::Vector3d(4.0, damping, 0.8);
    const auto options = fixedStep(GetParam(), horizon, 1e-3);
    const GradientResult result = gradientWithFullStorage(problem, p, options);
    const double exact = Oscillator::exactObjective(p(0), p(1), p(2), horizon);
    const Vector exactGradient = complexStepGradient(
        [&](const Eigen::VectorXcd& x) { return Oscillator::exactObjective(x(0), x(1), x(2), horizon); }, p);
    const double tolerance = (GetParam() == "rk4" || GetParam() == "dopri5") ? 1e-9 : 5e-6;
    EXPECT_NEAR(result.objective, exact, tolerance * std::abs(exact)) << "damping " << damping;
    EXPECT_LT((result.gradient - exactGradient).norm(), tolerance * exactGradient.norm())
        << "damping " << damping;
    const auto check = checkGradient(computedObjective(problem, options), p, result.gradient, {1e-8});
    EXPECT_TRUE(check.passed) << "damping " << damping << ": " << check.message;
  }
}

TEST_P(EveryMethod, PendulumGradientIsDerivativeOfComputedObjective) {
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);  // a large swing: strongly nonlinear
  const auto options = fixedStep(GetParam(), 4.0, 2e-3);
  const GradientResult result = gradientWithFullStorage(problem, p, options);
  const auto check = checkGradient(computedObjective(problem, options), p, result.gradient, {1e-7});
  EXPECT_TRUE(check.passed) << check.message;
}

TEST_P(EveryMethod, ConvergesWithItsOrder) {
  Oscillator problem;
  const Vector p = Eigen::Vector3d(4.0, 0.4, 0.8);
  const double horizon = 3.0;
  const double exact = Oscillator::exactObjective(p(0), p(1), p(2), horizon);
  const int order = ButcherTableau::byName(GetParam()).order;
  // Steps large enough that round-off does not matter, small enough for the asymptotic regime.
  const double h = order >= 4 ? 0.02 : 0.01;
  const double e1 = std::abs(simulate(problem, p, fixedStep(GetParam(), horizon, h)).objective - exact);
  const double e2 = std::abs(simulate(problem, p, fixedStep(GetParam(), horizon, h / 2)).objective - exact);
  const double observed = std::log2(e1 / e2);
  EXPECT_NEAR(observed, order, 0.3) << "errors " << e1 << ", " << e2;
}

class AdaptiveMethod : public ::testing::TestWithParam<std::string> {};

INSTANTIATE_TEST_SUITE_P(Integrators, AdaptiveMethod, ::testing::Values("dopri5", "trbdf2"),
                         [](const auto& info) { return info.param; });

TEST_P(AdaptiveMethod, PendulumGradientMatchesFrozenStepFiniteDifferences) {
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  IntegratorOptions options;
  options.method = GetParam();
  options.t1 = 4.0;
  options.adaptive = true;
  options.step = 1e-3;
  options.relativeTolerance = 1e-8;
  options.absoluteTolerance = 1e-10;
  const GradientResult result = gradientWithFullStorage(problem, p, options);
  EXPECT_GT(result.summary.steps, 20);
  const auto check =
      checkGradient(computedObjective(problem, options, result.times), p, result.gradient, {1e-7});
  EXPECT_TRUE(check.passed) << check.message;
  // Against a tight fixed-step reference, the adaptive psi is within its tolerance.
  const double reference = simulate(problem, p, fixedStep("rk4", 4.0, 1e-4)).objective;
  EXPECT_NEAR(result.objective, reference, 1e-5 * std::abs(reference));
}

TEST(StiffProblem, RobertsonOverElevenDecadesWithAdaptiveTrBdf2) {
  Robertson problem(1e5);
  const Vector p = Robertson::nominalParameters();
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 1e5;
  options.adaptive = true;
  options.step = 1e-6;
  options.relativeTolerance = 1e-7;
  options.absoluteTolerance = 1e-12;
  const GradientResult result = gradientWithFullStorage(problem, p, options);
  // The steps span many decades: from about 1e-6 s to thousands of seconds.
  double smallest = 1e300, largest = 0.0;
  for (std::size_t i = 1; i < result.times.size(); ++i) {
    smallest = std::min(smallest, result.times[i] - result.times[i - 1]);
    largest = std::max(largest, result.times[i] - result.times[i - 1]);
  }
  EXPECT_GT(largest / smallest, 1e8) << "steps from " << smallest << " to " << largest;
  EXPECT_LT(result.summary.steps, 5000);
  const auto check =
      checkGradient(computedObjective(problem, options, result.times), p, result.gradient, {1e-7});
  EXPECT_TRUE(check.passed) << check.message;
}

TEST(StiffProblem, ExplicitMethodNeedsFarMoreStepsThanImplicit) {
  // The stiffness is real: dopri5 is stability-limited on Robertson, trbdf2 is not.
  Robertson problem(10.0);
  const Vector p = Robertson::nominalParameters();
  IntegratorOptions options;
  options.t1 = 10.0;
  options.adaptive = true;
  options.step = 1e-6;
  options.relativeTolerance = 1e-6;
  options.absoluteTolerance = 1e-12;
  options.method = "trbdf2";
  const auto implicit = simulate(problem, p, options);
  options.method = "dopri5";
  const auto explicitRun = simulate(problem, p, options);
  EXPECT_GT(explicitRun.summary.steps, 20 * implicit.summary.steps);
  EXPECT_NEAR(explicitRun.objective, implicit.objective, 1e-5 * std::abs(implicit.objective));
}

// z' = A(p) z + b(t), A = [[0, 1], [-k, -c]], b = (0, sin 3t), psi = int z_0^2 dt: affine in z, so it may
// declare isLinearInState() and have its implicit stages solved by one Newton step.
class ForcedOscillator final : public Problem {
 public:
  explicit ForcedOscillator(bool declareLinear) : declareLinear_(declareLinear) {}
  std::string name() const override { return "forced-oscillator"; }
  int stateSize() const override { return 2; }
  int parameterSize() const override { return 2; }
  bool isLinearInState() const override { return declareLinear_; }
  void initialState(ConstVectorRef, VectorRef z0) const override { z0 << 1.0, 0.0; }
  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
    f(0) = z(1);
    f(1) = -p(0) * z(0) - p(1) * z(1) + std::sin(3.0 * t);
  }
  void rhsJacobian(double, ConstVectorRef, ConstVectorRef p, MatrixRef j, ProblemWorkspace*) const override {
    j << 0.0, 1.0, -p(0), -p(1);
  }
  void addRhsParameterVjp(double, ConstVectorRef z, ConstVectorRef, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace*) const override {
    out(0) -= z(0) * w(1);
    out(1) -= z(1) * w(1);
  }
  double integrand(double, ConstVectorRef z, ConstVectorRef, ProblemWorkspace*) const override {
    return z(0) * z(0);
  }
  void addIntegrandStateGradient(double, ConstVectorRef z, ConstVectorRef, double scale, VectorRef out,
                                 ProblemWorkspace*) const override {
    out(0) += scale * 2.0 * z(0);
  }
  void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                     ProblemWorkspace*) const override {}

 private:
  bool declareLinear_;
};

class ImplicitMethod : public ::testing::TestWithParam<std::string> {};

INSTANTIATE_TEST_SUITE_P(Integrators, ImplicitMethod, ::testing::Values("trbdf2", "sdirk2", "midpoint"),
                         [](const auto& info) { return info.param; });

TEST_P(ImplicitMethod, LinearProblemTakesOneNewtonStepPerStageWithTheSameResult) {
  const Vector p = Eigen::Vector2d(40.0, 0.3);
  const auto options = fixedStep(GetParam(), 2.0, 1e-2);
  const ForcedOscillator linear(true), iterated(false);
  const GradientResult one = gradientWithFullStorage(linear, p, options);
  const GradientResult many = gradientWithFullStorage(iterated, p, options);
  const ButcherTableau tableau = ButcherTableau::byName(GetParam());
  int implicitStages = 0;
  for (Eigen::Index i = 0; i < tableau.a.rows(); ++i) implicitStages += tableau.a(i, i) != 0.0 ? 1 : 0;
  // Forward sweeps alone (the backward sweep re-solves each step's stages once more).
  const ForwardResult oneForward = simulate(linear, p, options), manyForward = simulate(iterated, p, options);
  EXPECT_EQ(oneForward.summary.newtonIterations, implicitStages * oneForward.summary.steps);
  EXPECT_GE(manyForward.summary.newtonIterations, 2 * implicitStages * manyForward.summary.steps);
  EXPECT_EQ(one.summary.newtonIterations, 2 * implicitStages * one.summary.steps);
  // One exact step solves the affine stage equation: the iterated result differs by round-off only.
  EXPECT_NEAR(one.objective, many.objective, 1e-13 * std::abs(many.objective));
  EXPECT_LT((one.gradient - many.gradient).norm(), 1e-11 * many.gradient.norm());
  // And the discrete adjoint is still the derivative of the psi so computed.
  const auto check = checkGradient(computedObjective(linear, options), p, one.gradient, {1e-8});
  EXPECT_TRUE(check.passed) << check.message;
}

}  // namespace
}  // namespace hindsight
