// AutoDiffProblem: every derived derivative against finite differences, against the hand-derived
// pendulum (same numbers to round-off, same psi and gradient from computeGradient), the optional
// parts of the functor API, and allocation-free evaluation.
#include <hindsight/engine/autodiff_problem.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/engine/integrator.h>
#include <hindsight/engine/runge_kutta.h>
#include <hindsight/problems/classic/classic_problems.h>
#include "support/allocation_counting.h"
#include "support/engine_fixtures.h"

#include <gtest/gtest.h>

#include <cmath>

namespace hindsight {
namespace {

using testing::AllocationCounter;
using testing::computedObjective;
using testing::gradientWithFullStorage;

// A functor that uses every term: z0, G and phi depend on p, F couples all states and parameters
// nonlinearly (a forced Van der Pol oscillator with a third, driven state).
struct CoupledEquations {
  template <class T>
  void rhs(double t, const T* z, const T* p, T* f) const {
    using std::cos;
    using std::exp;
    f[0] = z[1];
    f[1] = p[0] * (1.0 - z[0] * z[0]) * z[1] - p[1] * z[0] + p[2] * cos(2.0 * t) * z[2];
    f[2] = -exp(-p[1] * z[0]) * z[2] + z[0] * z[1];
  }
  template <class T>
  T integrand(double t, const T* z, const T* p) const {
    using std::sin;
    return z[0] * z[0] * p[0] + sin(z[1] * p[2]) + 0.1 * t * z[2] * z[2];
  }
  template <class T>
  T terminal(const T* z, const T* p) const {
    return z[0] * z[2] * p[1] + 0.5 * z[1] * z[1];
  }
  template <class T>
  void initialState(const T* p, T* z0) const {
    z0[0] = p[2] * p[2];
    z0[1] = T(0.3);
    z0[2] = 1.0 / p[0];
  }
};
using CoupledProblem = AutoDiffProblem<CoupledEquations, 3, 3>;

// The minimal functor: no terminal term and a double-only initial state (independent of p), which
// is a data member set through the constructor.
struct DecayEquations {
  double initialValue = 0.0;
  template <class T>
  void rhs(double, const T* z, const T* p, T* f) const {
    f[0] = -p[0] * z[0];
  }
  template <class T>
  T integrand(double, const T* z, const T*) const {
    return z[0] * z[0];
  }
  void initialState(const double*, double* z0) const { z0[0] = initialValue; }
};

const Vector kCoupledP = Eigen::Vector3d(0.8, 1.3, 0.6);
const Vector kCoupledZ = Eigen::Vector3d(0.4, -0.7, 1.1);
constexpr double kT = 0.37;

// 1e-8 relative is far below the size of any term of CoupledEquations at these points (O(0.1..1)),
// so a missing or wrong term fails, and far above the error of central differences (~1e-10).
GradientCheckOptions strict() {
  GradientCheckOptions options;
  options.tolerance = 1e-8;
  return options;
}

TEST(AutoDiffProblem, SizesAndName) {
  const CoupledProblem problem("coupled");
  EXPECT_EQ(problem.name(), "coupled");
  EXPECT_EQ(problem.stateSize(), 3);
  EXPECT_EQ(problem.parameterSize(), 3);
  EXPECT_TRUE(problem.hasDenseJacobian());
  EXPECT_FALSE(problem.hasStateVjp());
}

TEST(AutoDiffProblem, RhsJacobianMatchesFiniteDifferencesRowByRow) {
  const CoupledProblem problem("coupled");
  Matrix jacobian(3, 3);
  problem.rhsJacobian(kT, kCoupledZ, kCoupledP, jacobian, nullptr);
  for (int i = 0; i < 3; ++i) {
    const auto fi = [&](const Vector& z) {
      Vector f(3);
      problem.rhs(kT, z, kCoupledP, f, nullptr);
      return f(i);
    };
    const auto check = checkGradient(fi, kCoupledZ, jacobian.row(i).transpose(), strict());
    EXPECT_TRUE(check.passed) << "row " << i << ": " << check.message;
  }
}

TEST(AutoDiffProblem, ParameterVjpMatchesFiniteDifferencesAndAccumulates) {
  const CoupledProblem problem("coupled");
  const Vector w = Eigen::Vector3d(0.9, -1.4, 0.5);
  const Vector start = Eigen::Vector3d(1.0, 2.0, 3.0);
  Vector out = start;
  problem.addRhsParameterVjp(kT, kCoupledZ, kCoupledP, w, out, nullptr);
  const auto wDotF = [&](const Vector& p) {
    Vector f(3);
    problem.rhs(kT, kCoupledZ, p, f, nullptr);
    return w.dot(f);
  };
  const auto check = checkGradient(wDotF, kCoupledP, out - start, strict());
  EXPECT_TRUE(check.passed) << check.message;
}

TEST(AutoDiffProblem, IntegrandGradientsMatchFiniteDifferencesAndAreScaled) {
  const CoupledProblem problem("coupled");
  const double scale = -2.5;
  Vector gz = Vector::Ones(3), gp = Vector::Ones(3);
  problem.addIntegrandStateGradient(kT, kCoupledZ, kCoupledP, scale, gz, nullptr);
  problem.addIntegrandParameterGradient(kT, kCoupledZ, kCoupledP, scale, gp, nullptr);
  const auto gOfZ = [&](const Vector& z) { return scale * problem.integrand(kT, z, kCoupledP, nullptr); };
  const auto gOfP = [&](const Vector& p) { return scale * problem.integrand(kT, kCoupledZ, p, nullptr); };
  const auto checkZ = checkGradient(gOfZ, kCoupledZ, gz - Vector::Ones(3), strict());
  const auto checkP = checkGradient(gOfP, kCoupledP, gp - Vector::Ones(3), strict());
  EXPECT_TRUE(checkZ.passed) << checkZ.message;
  EXPECT_TRUE(checkP.passed) << checkP.message;
}

TEST(AutoDiffProblem, TerminalAndInitialStateDerivativesMatchFiniteDifferences) {
  const CoupledProblem problem("coupled");
  Vector gz = Vector::Zero(3), gp = Vector::Zero(3);
  problem.addTerminalGradient(kCoupledZ, kCoupledP, gz, gp);
  const auto phiOfZ = [&](const Vector& z) { return problem.terminal(z, kCoupledP); };
  const auto phiOfP = [&](const Vector& p) { return problem.terminal(kCoupledZ, p); };
  const auto checkZ = checkGradient(phiOfZ, kCoupledZ, gz, strict());
  const auto checkP = checkGradient(phiOfP, kCoupledP, gp, strict());
  EXPECT_TRUE(checkZ.passed) << checkZ.message;
  EXPECT_TRUE(checkP.passed) << checkP.message;

  const Vector lambda0 = Eigen::Vector3d(0.3, -1.1, 2.0);
  Vector vjp = Vector::Zero(3);
  problem.addInitialStateVjp(kCoupledP, lambda0, vjp);
  const auto lambdaDotZ0 = [&](const Vector& p) {
    Vector z0(3);
    problem.initialState(p, z0);
    return lambda0.dot(z0);
  };
  const auto checkZ0 = checkGradient(lambdaDotZ0, kCoupledP, vjp, strict());
  EXPECT_TRUE(checkZ0.passed) << checkZ0.message;
}

TEST(AutoDiffProblem, GradientIsDerivativeOfComputedObjective) {
  // End to end through the discrete adjoint, with an explicit and an implicit method (the latter
  // uses the derived Jacobian in its Newton matrix and its transpose).
  const CoupledProblem problem("coupled");
  for (const char* method : {"rk4", "trbdf2"}) {
    IntegratorOptions options;
    options.method = method;
    options.t1 = 3.0;
    options.step = 5e-3;
    const GradientResult result = gradientWithFullStorage(problem, kCoupledP, options);
    const auto check = checkGradient(computedObjective(problem, options), kCoupledP, result.gradient, {1e-7});
    EXPECT_TRUE(check.passed) << method << ": " << check.message;
  }
}

TEST(AutoDiffProblem, OptionalPartsDefaultToZero) {
  // No terminal term: phi = 0 and no gradient; a double-only initialState: dz0/dp = 0. The result
  // equals the hand-written ExponentialDecay with the same initial value (z0 = a = 0.7).
  const AutoDiffProblem<DecayEquations, 1, 1> problem("decay", DecayEquations{0.7});
  EXPECT_EQ(problem.functor().initialValue, 0.7);
  const Vector z = Vector::Constant(1, 0.4), p = Vector::Constant(1, 1.3);
  EXPECT_EQ(problem.terminal(z, p), 0.0);
  Vector gz = Vector::Zero(1), gp = Vector::Zero(1), vjp = Vector::Zero(1);
  problem.addTerminalGradient(z, p, gz, gp);
  problem.addInitialStateVjp(p, Vector::Ones(1), vjp);
  EXPECT_EQ(gz(0), 0.0);
  EXPECT_EQ(gp(0), 0.0);
  EXPECT_EQ(vjp(0), 0.0);

  IntegratorOptions options;
  options.t1 = 2.0;
  const GradientResult derived = gradientWithFullStorage(problem, p, options);
  const GradientResult handWritten =
      gradientWithFullStorage(ExponentialDecay(), Eigen::Vector2d(1.3, 0.7), options);
  EXPECT_NEAR(derived.objective, handWritten.objective, 1e-15 * std::abs(handWritten.objective));
  EXPECT_NEAR(derived.gradient(0), handWritten.gradient(0), 1e-14 * std::abs(handWritten.gradient(0)));
}

// ---- Against the hand-derived pendulum (problems/classic/classic_problems.h). ----

class AgainstHandDerivedPendulum : public ::testing::Test {
 protected:
  Pendulum pendulum;
  const Problem& hand = pendulum;  // the first-order interface, which SecondOrderProblem overloads
  AutoDiffPendulum derived{"pendulum-autodiff"};
  std::unique_ptr<ProblemWorkspace> handWs = hand.createWorkspace();
  std::unique_ptr<ProblemWorkspace> derivedWs = derived.createWorkspace();
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
};

// |a - b| <= 1e-14 max(1, |b|), elementwise: the two differ only in the order of operations (the
// adapter divides by M through a Cholesky factor, the functor divides directly).
void expectSame(const Vector& a, const Vector& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    EXPECT_NEAR(a(i), b(i), 1e-14 * std::max(1.0, std::abs(b(i)))) << what << " [" << i << "]";
  }
}

TEST_F(AgainstHandDerivedPendulum, SameFunctionsAndDerivatives) {
  EXPECT_EQ(derived.stateSize(), hand.stateSize());
  EXPECT_EQ(derived.parameterSize(), hand.parameterSize());
  Vector z0Hand(2), z0Derived(2);
  hand.initialState(p, z0Hand);
  derived.initialState(p, z0Derived);
  expectSame(z0Derived, z0Hand, "z0");
  const Vector lambda0 = Eigen::Vector2d(0.7, -0.2);
  Vector vjpHand = Vector::Zero(4), vjpDerived = Vector::Zero(4);
  hand.addInitialStateVjp(p, lambda0, vjpHand);
  derived.addInitialStateVjp(p, lambda0, vjpDerived);
  expectSame(vjpDerived, vjpHand, "(dz0/dp)^T lambda");

  const Vector w = Eigen::Vector2d(-0.6, 1.7);
  for (const Eigen::Vector2d z :
       {Eigen::Vector2d(1.2, 0.0), Eigen::Vector2d(-0.4, 2.3), Eigen::Vector2d(3.0, -1.1)}) {
    const double t = 0.25;
    Vector fHand(2), fDerived(2);
    hand.rhs(t, z, p, fHand, handWs.get());
    derived.rhs(t, z, p, fDerived, derivedWs.get());
    expectSame(fDerived, fHand, "F");
    Matrix jHand(2, 2), jDerived(2, 2);
    hand.rhsJacobian(t, z, p, jHand, handWs.get());
    derived.rhsJacobian(t, z, p, jDerived, derivedWs.get());
    expectSame(jDerived.reshaped(), jHand.reshaped(), "F_z");
    Vector fpHand = Vector::Zero(4), fpDerived = Vector::Zero(4);
    hand.addRhsParameterVjp(t, z, p, w, fpHand, handWs.get());
    derived.addRhsParameterVjp(t, z, p, w, fpDerived, derivedWs.get());
    expectSame(fpDerived, fpHand, "F_p^T w");
    EXPECT_NEAR(derived.integrand(t, z, p, derivedWs.get()), hand.integrand(t, z, p, handWs.get()), 1e-15);
    Vector gzHand = Vector::Zero(2), gzDerived = Vector::Zero(2);
    Vector gpHand = Vector::Zero(4), gpDerived = Vector::Zero(4);
    hand.addIntegrandStateGradient(t, z, p, 0.3, gzHand, handWs.get());
    derived.addIntegrandStateGradient(t, z, p, 0.3, gzDerived, derivedWs.get());
    hand.addIntegrandParameterGradient(t, z, p, 0.3, gpHand, handWs.get());
    derived.addIntegrandParameterGradient(t, z, p, 0.3, gpDerived, derivedWs.get());
    expectSame(gzDerived, gzHand, "G_z");
    expectSame(gpDerived, gpHand, "G_p");
    EXPECT_EQ(derived.terminal(z, p), hand.terminal(z, p));
    Vector tzHand = Vector::Zero(2), tzDerived = Vector::Zero(2), tpHand = Vector::Zero(4),
           tpDerived = Vector::Zero(4);
    hand.addTerminalGradient(z, p, tzHand, tpHand);
    derived.addTerminalGradient(z, p, tzDerived, tpDerived);
    expectSame(tzDerived, tzHand, "phi_z");
    expectSame(tpDerived, tpHand, "phi_p");
  }
}

TEST_F(AgainstHandDerivedPendulum, SameObjectiveAndGradient) {
  for (const char* method : {"rk4", "dopri5", "trbdf2"}) {
    IntegratorOptions options;
    options.method = method;
    options.t1 = 4.0;
    options.step = 2e-3;
    const GradientResult a = gradientWithFullStorage(hand, p, options);
    const GradientResult b = gradientWithFullStorage(derived, p, options);
    // Round-off of the order of operations, accumulated over 2000 steps: 1e-12 relative.
    EXPECT_NEAR(b.objective, a.objective, 1e-12 * std::abs(a.objective)) << method;
    EXPECT_LT((b.gradient - a.gradient).norm(), 1e-12 * a.gradient.norm()) << method;
  }
}

// ---- No allocation. ----

TEST(AutoDiffProblem, EvaluationsAndStepsAllocateNothing) {
  if (!AllocationCounter::available()) GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  const CoupledProblem problem("coupled");
  const Vector w = Eigen::Vector3d(0.9, -1.4, 0.5);
  Vector f(3), gz = Vector::Zero(3), gp = Vector::Zero(3), z0(3);
  Matrix jacobian(3, 3);
  double sink = 0.0;
  long evaluationAllocations = 0;
  {
    AllocationCounter counter;
    for (int i = 0; i < 10; ++i) {
      problem.initialState(kCoupledP, z0);
      problem.addInitialStateVjp(kCoupledP, w, gp);
      problem.rhs(kT, kCoupledZ, kCoupledP, f, nullptr);
      problem.rhsJacobian(kT, kCoupledZ, kCoupledP, jacobian, nullptr);
      problem.addRhsParameterVjp(kT, kCoupledZ, kCoupledP, w, gp, nullptr);
      sink += problem.integrand(kT, kCoupledZ, kCoupledP, nullptr);
      problem.addIntegrandStateGradient(kT, kCoupledZ, kCoupledP, 1.0, gz, nullptr);
      problem.addIntegrandParameterGradient(kT, kCoupledZ, kCoupledP, 1.0, gp, nullptr);
      sink += problem.terminal(kCoupledZ, kCoupledP);
      problem.addTerminalGradient(kCoupledZ, kCoupledP, gz, gp);
    }
    evaluationAllocations = counter.count();
  }
  EXPECT_EQ(evaluationAllocations, 0);
  EXPECT_TRUE(std::isfinite(sink + gz.sum() + gp.sum()));

  // The integrator's steps with the derived derivatives, explicit and implicit.
  for (const char* method : {"rk4", "trbdf2"}) {
    IntegratorOptions options;
    options.method = method;
    RungeKuttaIntegrator integrator(problem, kCoupledP, options);
    Vector z = kCoupledZ, lambda = Vector::Ones(3), gradient = Vector::Zero(3);
    long stepAllocations = 0;
    {
      AllocationCounter counter;
      for (int i = 0; i < 10; ++i) integrator.step(0.01 * i, 0.01, z, nullptr);
      for (int i = 0; i < 10; ++i) integrator.adjointStep(0.01 * i, 0.01, kCoupledZ, lambda, gradient);
      stepAllocations = counter.count();
    }
    EXPECT_EQ(stepAllocations, 0) << method;
  }
}

}  // namespace
}  // namespace hindsight
