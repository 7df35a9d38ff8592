// The reaction-diffusion problem: every derivative against finite differences, the tridiagonal solver
// against its defining residual (also on a non-symmetric matrix, so a wrong transpose cannot pass), and
// the whole gradient against finite differences of the computed psi for explicit and implicit methods.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/engine/integrator.h>
#include <hindsight/problems/classic/heat_equation.h>

#include "support/random_design.h"

#include <gtest/gtest.h>

#include <random>

namespace hindsight {
namespace {

using testing::randomVector;

TEST(TridiagonalLu, SolvesWithTheMatrixAndItsTransposeOnANonSymmetricMatrix) {
  std::mt19937 generator(42);
  const int n = 30;
  Vector sub = randomVector(n, generator), super = randomVector(n, generator);
  Vector diagonal = randomVector(n, generator, 3.0, 4.0);  // diagonally dominant
  sub(0) = 0.0;
  super(n - 1) = 0.0;
  Matrix dense = Matrix::Zero(n, n);
  for (int i = 0; i < n; ++i) {
    dense(i, i) = diagonal(i);
    if (i > 0) dense(i, i - 1) = sub(i);
    if (i + 1 < n) dense(i, i + 1) = super(i);
  }
  TridiagonalLu lu(n);
  lu.factorize(sub, diagonal, super, 0.0);
  const Vector b = randomVector(n, generator);
  Vector x = b;
  lu.solve(x);
  EXPECT_LT((dense * x - b).norm(), 1e-13 * b.norm());
  Vector y = b;
  lu.solveTransposed(y);
  EXPECT_LT((dense.transpose() * y - b).norm(), 1e-13 * b.norm());
  EXPECT_GT((dense * y - b).norm(), 1e-3);  // the matrix is not symmetric: the two solves differ
}

TEST(TridiagonalLu, AVanishingPivotIsANewtonFailure) {
  TridiagonalLu lu(2);
  Vector sub(2), diagonal(2), super(2);
  sub << 0.0, 1.0;
  diagonal << 1.0, 1.0;
  super << 1.0, 0.0;  // [[1, 1], [1, 1]] is singular
  EXPECT_THROW(lu.factorize(sub, diagonal, super, 0.5), NewtonFailure);
}

class HeatDerivatives : public ::testing::Test {
 protected:
  HeatEquation problem{12, 3};
  std::mt19937 generator{7};
  Vector p = problem.nominalParameters();
  Vector z = randomVector(12, generator, 0.0, 1.0);
  Vector w = randomVector(12, generator);
};

TEST_F(HeatDerivatives, StateVjpMatchesFiniteDifferences) {
  p(0) = 0.01;
  Vector vjp(12);
  problem.rhsStateVjp(0.0, z, p, w, vjp, nullptr);
  const auto dot = [&](const Vector& state) {
    Vector f(12);
    problem.rhs(0.0, state, p, f, nullptr);
    return w.dot(f);
  };
  const auto check = checkGradient(dot, z, vjp);
  EXPECT_TRUE(check.passed) << check.message;
}

TEST_F(HeatDerivatives, ParameterVjpAndInitialStateVjpMatchFiniteDifferences) {
  Vector vjp = Vector::Zero(problem.parameterSize());
  problem.addRhsParameterVjp(0.0, z, p, w, vjp, nullptr);
  const auto dot = [&](const Vector& parameters) {
    Vector f(12);
    problem.rhs(0.0, z, parameters, f, nullptr);
    return w.dot(f);
  };
  auto check = checkGradient(dot, p, vjp);
  EXPECT_TRUE(check.passed) << check.message;

  Vector initialVjp = Vector::Zero(problem.parameterSize());
  problem.addInitialStateVjp(p, w, initialVjp);
  const auto initialDot = [&](const Vector& parameters) {
    Vector z0(12);
    problem.initialState(parameters, z0);
    return w.dot(z0);
  };
  check = checkGradient(initialDot, p, initialVjp, {1e-6, 1e-3, {2, 3, 4}});
  EXPECT_TRUE(check.passed) << check.message;
}

TEST_F(HeatDerivatives, NewtonSolverInvertsIMinusAlphaJacobian) {
  p(0) = 0.01;
  const double alpha = 0.05;
  auto solver = problem.createNewtonSolver();
  solver->factorize(0.0, z, p, alpha, nullptr);
  Vector x = w;
  solver->solve(x);
  // (I - alpha F_z) x = x - alpha F_z x, with F_z x = F_z^T x (symmetric) from rhsStateVjp.
  Vector jx(12);
  problem.rhsStateVjp(0.0, z, p, x, jx, nullptr);
  EXPECT_LT((x - alpha * jx - w).norm(), 1e-13 * w.norm());
  Vector y = w;
  solver->solveTransposed(y);
  problem.rhsStateVjp(0.0, z, p, y, jx, nullptr);
  EXPECT_LT((y - alpha * jx - w).norm(), 1e-13 * w.norm());
}

class HeatGradient : public ::testing::TestWithParam<std::string> {};

INSTANTIATE_TEST_SUITE_P(Methods, HeatGradient, ::testing::Values("rk4", "trbdf2", "sdirk2"),
                         [](const auto& info) { return info.param; });

TEST_P(HeatGradient, MatchesFiniteDifferencesOfTheComputedObjective) {
  HeatEquation problem(40, 3);
  Vector p = problem.nominalParameters();
  p(0) = 0.01;  // D / h^2 = 16.8: RK4 at h_t = 0.01 is stable
  p(1) = 2.0;
  IntegratorOptions options;
  options.method = GetParam();
  options.t1 = 1.0;
  options.step = 0.01;
  FullStorage storage;
  storage.setVerifyRestores(true);
  const GradientResult result = computeGradient(problem, p, options, storage);
  EXPECT_GT(result.objective, 0.0);
  const auto objective = [&](const Vector& parameters) {
    return simulate(problem, parameters, options).objective;
  };
  const auto check = checkGradient(objective, p, result.gradient, {1e-7});
  EXPECT_TRUE(check.passed) << check.message;
}

TEST(HeatEquation, RejectsBadSizes) {
  EXPECT_THROW(HeatEquation(0, 3), std::invalid_argument);
  EXPECT_THROW(HeatEquation(10, -1), std::invalid_argument);
}

}  // namespace
}  // namespace hindsight
