// Tests of the MMA optimizer: published problems with known optima (Svanberg 1987 and 2007), a problem
// with a closed-form KKT point, bit-exact restart, allocation-free updates and argument checking.
#include <hindsight/problems/topopt/mma.h>

#include "support/allocation_counting.h"
#include "support/same_bits.h"
#include "support/svanberg_problems.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {
namespace {

using testing::sameBits;

using Problem = testing::OptimizationProblem;
using testing::CantileverBeam;
using testing::kBeamCompliance;
using testing::kBeamWeight;
using testing::kSphereCenters;
using testing::TwoSpheres;

struct RunResult {
  Vector x;
  double objective = 0.0;
  Vector constraints;
  int iterations = 0;
};

// Runs MMA until the largest design change falls below `tolerance` or `max_iterations` is reached.
RunResult Optimize(const Problem& problem, int max_iterations, double tolerance, Mma* mma = nullptr) {
  Mma local(problem.n, problem.m);
  Mma& optimizer = mma != nullptr ? *mma : local;
  RunResult result;
  Vector x = problem.x0;
  Vector df0(problem.n), f(problem.m), previous(problem.n);
  Matrix df(problem.m, problem.n);
  double f0 = 0.0;
  for (int k = 0; k < max_iterations; ++k) {
    problem.evaluate(x, &f0, &df0, &f, &df);
    previous = x;
    optimizer.update(f0, df0, f, df, problem.xmin, problem.xmax, x);
    result.iterations = k + 1;
    if ((x - previous).cwiseAbs().maxCoeff() < tolerance) break;
  }
  problem.evaluate(x, &f0, &df0, &f, &df);
  result.x = x;
  result.objective = f0;
  result.constraints = f;
  return result;
}

// Svanberg (1987), sec. 6: the cantilever beam (tests/support/svanberg_problems.h).
TEST(Mma, CantileverBeamOfSvanberg1987) {
  const RunResult r = Optimize(CantileverBeam(), 200, 1e-9);
  EXPECT_LT(r.iterations, 200);

  // Closed form: stationarity 0.0624 = 3 lambda c_j / x_j^4 gives x_j = t c_j^(1/4); the active
  // constraint sum c_j^(1/4) / t^3 = 1 gives t = (sum c_j^(1/4))^(1/3), f* = 0.0624 t sum c_j^(1/4).
  double rootSum = 0.0;
  for (double c : kBeamCompliance) rootSum += std::pow(c, 0.25);
  const double t = std::cbrt(rootSum);
  const double exactObjective = kBeamWeight * t * rootSum;
  std::cout << "[ beam     ] f = " << r.objective << " (exact " << exactObjective << ", paper 1.340) after "
            << r.iterations << " iterations, x = " << r.x.transpose() << "\n";

  EXPECT_NEAR(r.objective, exactObjective, 1e-6 * exactObjective);
  for (int j = 0; j < 5; ++j) EXPECT_NEAR(r.x(j), t * std::pow(kBeamCompliance[j], 0.25), 1e-5) << j;
  // The subproblem is solved to the barrier parameter 1e-7, so an active constraint holds to about
  // 1e-7 / lambda (the slack s = epsilon / lambda).
  EXPECT_NEAR(r.constraints(0), 0.0, 1e-6);
  // The values printed in Svanberg (1987), three decimals; x4 is printed as 3.502 where the exact
  // optimum is 3.5015, hence the tolerance of one unit in the last printed digit.
  EXPECT_NEAR(r.objective, 1.340, 5e-4);
  const double paper[5] = {6.016, 5.309, 4.494, 3.502, 2.153};
  for (int j = 0; j < 5; ++j) EXPECT_NEAR(r.x(j), paper[j], 1e-3) << j;
}

// Svanberg (2007): the two spheres (tests/support/svanberg_problems.h).
TEST(Mma, TwoSpheresOfSvanberg2007) {
  Mma mma(3, 2);
  const RunResult r = Optimize(TwoSpheres(), 200, 1e-10, &mma);
  EXPECT_LT(r.iterations, 200);
  const Vector& lambda = mma.lastSubproblem().lambda;
  std::cout << "[ spheres  ] f = " << r.objective << " after " << r.iterations
            << " iterations, x = " << r.x.transpose() << ", lambda = " << lambda.transpose() << "\n";

  // The problem is convex, so a KKT point is the global minimum: check the KKT conditions with the
  // multipliers of the last subproblem.
  Vector stationarity = 2.0 * r.x;
  for (int i = 0; i < 2; ++i) {
    EXPECT_GT(lambda(i), 0.0) << i;
    EXPECT_NEAR(r.constraints(i), 0.0, 1e-6) << i;  // active, to the barrier tolerance
    for (int j = 0; j < 3; ++j) stationarity(j) += lambda(i) * 2.0 * (r.x(j) - kSphereCenters[i][j]);
  }
  EXPECT_LT(stationarity.cwiseAbs().maxCoeff(), 1e-6) << stationarity.transpose();
  // The solution reported in the note, to its four decimals.
  EXPECT_NEAR(r.x(0), 2.0175, 1e-4);
  EXPECT_NEAR(r.x(1), 1.7800, 1e-4);
  EXPECT_NEAR(r.x(2), 1.2375, 1e-4);
}

// A convex separable quadratic with one linear constraint:
//   minimize sum_j 1/2 w_j (x_j - t_j)^2  subject to  sum_j g_j x_j - V <= 0,  0 <= x_j <= 1.
// KKT with the constraint active and the bounds inactive: w_j (x_j - t_j) + lambda g_j = 0, so
// x_j = t_j - lambda g_j / w_j; inserting in sum_j g_j x_j = V gives
//   lambda = (sum_j g_j t_j - V) / sum_j (g_j^2 / w_j),
// valid when lambda > 0 and every x_j lies in (0, 1), which the data below satisfy (checked).
// Runs MMA on that problem with n variables and the given barrier tolerance of the subproblem solver
// and checks the KKT conditions and the closed-form solution.
void ExpectClosedFormKktPoint(int n, double barrier) {
  Vector w(n), t(n), g(n);
  for (int j = 0; j < n; ++j) {
    w(j) = 1.0 + 2.0 * std::sin(0.7 * j) * std::sin(0.7 * j);
    t(j) = 0.6 + 0.3 * std::cos(1.3 * j) * std::cos(1.3 * j);
    g(j) = 0.5 + std::sin(0.4 * j + 1.0) * std::sin(0.4 * j + 1.0);
  }
  const double volume = 0.8 * g.dot(t);
  const double lambdaExact = (g.dot(t) - volume) / g.cwiseAbs2().cwiseQuotient(w).sum();
  const Vector xExact = t - lambdaExact * g.cwiseQuotient(w);
  ASSERT_GT(lambdaExact, 0.0);
  ASSERT_GT(xExact.minCoeff(), 0.0);
  ASSERT_LT(xExact.maxCoeff(), 1.0);

  Problem p;
  p.n = n;
  p.m = 1;
  p.xmin = Vector::Zero(n);
  p.xmax = Vector::Ones(n);
  p.x0 = Vector::Constant(n, 0.5);
  p.evaluate = [&](const Vector& x, double* f0, Vector* df0, Vector* f, Matrix* df) {
    *f0 = 0.5 * w.dot((x - t).cwiseAbs2());
    *df0 = w.cwiseProduct(x - t);
    (*f)(0) = g.dot(x) - volume;
    df->row(0) = g.transpose();
  };
  {
    MmaOptions options;
    options.subproblem_tolerance = barrier;
    Mma mma(n, 1, options);
    const RunResult r = Optimize(p, 100, 10 * barrier, &mma);
    const double lambda = mma.lastSubproblem().lambda(0);
    const Vector stationarity = w.cwiseProduct(r.x - t) + lambda * g;
    std::cout << "[ quadratic] n = " << n << ", barrier " << barrier << ": lambda = " << lambda << " (exact "
              << lambdaExact << ") after " << r.iterations
              << " iterations, max |x - x*| = " << (r.x - xExact).cwiseAbs().maxCoeff()
              << ", stationarity = " << stationarity.cwiseAbs().maxCoeff() << "\n";

    const double tolerance = 1e2 * barrier;
    EXPECT_LT(r.iterations, 100) << barrier;  // converged: the design change fell below 10 * barrier
    EXPECT_LT(stationarity.cwiseAbs().maxCoeff(), tolerance) << barrier;
    EXPECT_LT(std::max(r.constraints(0), 0.0), tolerance) << barrier;          // primal feasibility
    EXPECT_LT(std::abs(lambda * r.constraints(0)), 2.0 * barrier) << barrier;  // complementarity
    EXPECT_NEAR(lambda, lambdaExact, tolerance) << barrier;
    EXPECT_LT((r.x - xExact).cwiseAbs().maxCoeff(), tolerance) << barrier;
  }
}

// The subproblems are solved to the barrier parameter subproblem_tolerance, which bounds the accuracy
// of the KKT point (lambda s = epsilon for the slack s): check at the default 1e-7 and at 1e-11, where
// the errors must shrink accordingly.
TEST(Mma, SeparableQuadraticReachesClosedFormKktPoint) {
  ExpectClosedFormKktPoint(40, 1e-7);
  ExpectClosedFormKktPoint(40, 1e-11);
}

// The size the optimizer is meant for: 10^5 variables, one constraint.
// kktResidual is zero exactly at a KKT point and measures each violated condition elsewhere: the
// separable quadratic's closed-form point with its multiplier, then a moved design, a wrong
// multiplier, a violated constraint and the bound cases, each with the value the formula gives.
TEST(Mma, KktResidualVanishesAtTheKktPointAndMeasuresEachViolation) {
  const int n = 4;
  const Vector w = (Vector(n) << 1.0, 2.0, 3.0, 4.0).finished();
  const Vector t = (Vector(n) << 0.7, 0.6, 0.8, 0.5).finished();
  const Vector g = (Vector(n) << 1.0, 0.5, 2.0, 1.5).finished();
  const double volume = 0.9 * g.dot(t);
  const double lambda = (g.dot(t) - volume) / g.cwiseAbs2().cwiseQuotient(w).sum();
  const Vector x = t - lambda * g.cwiseQuotient(w);
  const Vector xmin = Vector::Zero(n), xmax = Vector::Ones(n);
  const auto residual = [&](const Vector& at, double multiplier) {
    const Vector gradient = w.cwiseProduct(at - t);
    const Vector constraint = Vector::Constant(1, g.dot(at) - volume);
    const Matrix jacobian = g.transpose();
    return kktResidual(at, gradient, constraint, jacobian, Vector::Constant(1, multiplier), xmin, xmax);
  };
  EXPECT_LT(residual(x, lambda), 1e-15);
  // Stationarity: moving x_2 by d leaves w_2 d in its Lagrangian gradient (and g_2 d in the
  // constraint, times lambda in the complementarity term, which is smaller here).
  Vector moved = x;
  moved(2) -= 1e-3;
  EXPECT_NEAR(residual(moved, lambda), w(2) * 1e-3, 1e-14);
  // A wrong multiplier leaves (lambda' - lambda) g_j in the gradient, largest for j = 2.
  EXPECT_NEAR(residual(x, 2.0 * lambda), lambda * g(2), 1e-14);
  // Infeasible by 0.01 in every variable: the constraint's value 0.01 sum g (0.05) exceeds the
  // gradient's 0.01 w_j and the complementarity lambda 0.05.
  ASSERT_LT(0.01 * w.maxCoeff(), 0.01 * g.sum());
  EXPECT_NEAR(residual(x + Vector::Constant(n, 0.01), lambda), 0.01 * g.sum(), 1e-14);
  // At a lower bound a positive gradient is stationary, a negative one is not (the projection
  // clips the step at the bound, so the residual is the distance to it, at most the gradient).
  const Vector at = (Vector(1) << 0.0).finished();
  const Matrix none(0, 1);
  EXPECT_EQ(
      kktResidual(at, Vector::Constant(1, 0.3), Vector(0), none, Vector(0), Vector::Zero(1), Vector::Ones(1)),
      0.0);
  EXPECT_EQ(kktResidual(at, Vector::Constant(1, -0.3), Vector(0), none, Vector(0), Vector::Zero(1),
                        Vector::Ones(1)),
            0.3);
  EXPECT_EQ(kktResidual(at, Vector::Constant(1, -3.0), Vector(0), none, Vector(0), Vector::Zero(1),
                        Vector::Ones(1)),
            1.0);
  EXPECT_THROW(
      kktResidual(x, Vector::Zero(n - 1), Vector::Zero(1), g.transpose(), Vector::Zero(1), xmin, xmax),
      std::invalid_argument);
}

// MMA's iterates drive the residual to zero on Svanberg's two-sphere problem: large at the start,
// below the barrier tolerance's reach at the end.
TEST(Mma, KktResidualOfMmaIteratesFallsToZeroOnTwoSpheres) {
  const Problem p = TwoSpheres();
  Mma mma(p.n, p.m);
  Vector x = p.x0, df0(p.n), f(p.m);
  Matrix df(p.m, p.n);
  double f0 = 0.0;
  std::vector<double> residuals;
  for (int k = 0; k < 60; ++k) {
    p.evaluate(x, &f0, &df0, &f, &df);
    const Vector current = x;
    mma.update(f0, df0, f, df, p.xmin, p.xmax, x);
    residuals.push_back(kktResidual(current, df0, f, df, mma.lastSubproblem().lambda, p.xmin, p.xmax));
  }
  EXPECT_GT(residuals.front(), 0.1);
  EXPECT_LT(residuals.back(), 1e-6);
}

// The adaptive move limit: halved after an update that found the objective raised between two
// feasible designs, grown 1.2x after one that found it lowered (capped at move_limit), untouched and
// the objective forgotten at an infeasible design; every step stays within the limit in force.
TEST(Mma, AdaptiveMoveLimitShrinksAfterARiseAndGrowsAfterADecrease) {
  MmaOptions options;
  options.adaptive_move_limit = true;
  options.move_limit = 0.4;
  Mma mma(2, 1, options);
  const Vector xmin = Vector::Zero(2), xmax = Vector::Ones(2);
  // A linear objective pulling both variables up; the constraint's value is given per call.
  const Vector gradient = (Vector(2) << -1.0, -0.5).finished();
  const Matrix jacobian = (Matrix(1, 2) << 0.1, 0.1).finished();
  Vector x = Vector::Constant(2, 0.05);
  const auto step = [&](double objective, double constraint) {
    const Vector before = x;
    mma.update(objective, gradient, Vector::Constant(1, constraint), jacobian, xmin, xmax, x);
    EXPECT_LE((x - before).cwiseAbs().maxCoeff(), mma.state().moveLimit * (1.0 + 1e-12));
    return mma.state().moveLimit;
  };
  EXPECT_DOUBLE_EQ(step(1.0, -0.5), 0.4);  // first update: the configured limit
  EXPECT_EQ(mma.state().objective, 1.0);
  EXPECT_DOUBLE_EQ(step(2.0, -0.5), 0.2);   // raised: halved
  EXPECT_DOUBLE_EQ(step(1.5, -0.5), 0.24);  // lowered: 1.2x
  EXPECT_DOUBLE_EQ(step(1.7, 0.3), 0.24);   // infeasible: unchanged, objective forgotten
  EXPECT_TRUE(std::isnan(mma.state().objective));
  EXPECT_DOUBLE_EQ(step(9.0, -0.5), 0.24);  // no feasible predecessor to compare with
  EXPECT_DOUBLE_EQ(step(1.0, -0.5), 0.288);
  EXPECT_DOUBLE_EQ(step(0.5, -0.5), 0.3456);
  EXPECT_DOUBLE_EQ(step(0.4, -0.5), 0.4);             // capped at move_limit
  for (int k = 0; k < 20; ++k) step(10.0 + k, -0.5);  // rising forever: down to the floor
  EXPECT_DOUBLE_EQ(mma.state().moveLimit, options.min_move_limit);

  // The limit and the objective carry over through state()/restore(), so a resumed run continues alike.
  Mma other(2, 1, options);
  other.restore(mma.state());
  EXPECT_EQ(other.state().moveLimit, mma.state().moveLimit);
  EXPECT_EQ(other.state().objective, mma.state().objective);

  // Without the option the limit never moves.
  Mma plain(2, 1);
  Vector y = Vector::Constant(2, 0.05);
  for (double objective : {1.0, 2.0, 3.0}) {
    plain.update(objective, gradient, Vector::Constant(1, -0.5), jacobian, xmin, xmax, y);
    EXPECT_EQ(plain.state().moveLimit, MmaOptions().move_limit);
  }
}

TEST(Mma, LargeSeparableQuadraticReachesClosedFormKktPoint) { ExpectClosedFormKktPoint(100000, 1e-7); }

// No constraints (m = 0): minimize sum_j (x_j - t_j)^2 over the box [0, 1]^n; the minimizer is t
// clipped to the box. Where the minimum is inside the box the gradient vanishes and MMA's step is
// about 0.9 min_asymptote_distance whatever the gradient, so with the 2007 floor of 0.01 those
// variables end in a limit cycle of amplitude near 0.0045 (the tolerance below allows for it); with
// the floor lowered they converge.
TEST(Mma, BoxConstrainedProblemWithoutConstraints) {
  const Vector t = (Vector(4) << -0.5, 0.3, 0.8, 1.7).finished();
  Problem p;
  p.n = 4;
  p.m = 0;
  p.xmin = Vector::Zero(4);
  p.xmax = Vector::Ones(4);
  p.x0 = Vector::Constant(4, 0.5);
  p.evaluate = [&t](const Vector& x, double* f0, Vector* df0, Vector*, Matrix*) {
    *f0 = (x - t).squaredNorm();
    *df0 = 2.0 * (x - t);
  };
  const Vector expected = t.cwiseMax(0.0).cwiseMin(1.0);

  Mma standard(4, 0);
  const RunResult cycling = Optimize(p, 100, 1e-9, &standard);
  EXPECT_LT(std::abs(cycling.x(0) - expected(0)), 1e-6);  // at a bound: converges
  EXPECT_LT(std::abs(cycling.x(3) - expected(3)), 1e-6);
  EXPECT_LT(std::abs(cycling.x(1) - expected(1)), 0.01 * 0.9);  // inside: within the limit cycle
  EXPECT_LT(std::abs(cycling.x(2) - expected(2)), 0.01 * 0.9);

  MmaOptions options;
  options.min_asymptote_distance = 1e-9;
  Mma refined(4, 0, options);
  const RunResult r = Optimize(p, 100, 1e-9, &refined);
  EXPECT_LT((r.x - expected).cwiseAbs().maxCoeff(), 1e-6) << r.x.transpose();
  EXPECT_LT(r.iterations, 100);
}

TEST(Mma, IteratesStayInsideBoundsAndMoveLimits) {
  const Problem p = CantileverBeam();
  MmaOptions options;
  options.move_limit = 0.05;
  Mma mma(p.n, p.m, options);
  Vector x = p.x0, df0(p.n), f(p.m), previous(p.n);
  Matrix df(p.m, p.n);
  double f0 = 0.0;
  for (int k = 0; k < 20; ++k) {
    p.evaluate(x, &f0, &df0, &f, &df);
    previous = x;
    mma.update(f0, df0, f, df, p.xmin, p.xmax, x);
    for (int j = 0; j < p.n; ++j) {
      EXPECT_GE(x(j), p.xmin(j));
      EXPECT_LE(x(j), p.xmax(j));
      EXPECT_LE(std::abs(x(j) - previous(j)), options.move_limit * (p.xmax(j) - p.xmin(j)) * (1 + 1e-12));
    }
    EXPECT_TRUE(mma.lastSubproblem().converged) << k;
  }
}

TEST(Mma, RestoredStateContinuesBitIdentically) {
  const Problem p = TwoSpheres();
  constexpr int kSplit = 5;
  constexpr int kTotal = 12;

  auto step = [&p](Mma& mma, Vector& x) {
    Vector df0(p.n), f(p.m);
    Matrix df(p.m, p.n);
    double f0 = 0.0;
    p.evaluate(x, &f0, &df0, &f, &df);
    mma.update(f0, df0, f, df, p.xmin, p.xmax, x);
  };

  Mma uninterrupted(p.n, p.m);
  Vector x = p.x0;
  MmaState saved;
  Vector xSaved;
  for (int k = 0; k < kTotal; ++k) {
    if (k == kSplit) {
      saved = uninterrupted.state();
      xSaved = x;
    }
    step(uninterrupted, x);
  }

  Mma resumed(p.n, p.m);
  resumed.restore(saved);
  EXPECT_EQ(resumed.state().iteration, kSplit);
  Vector xResumed = xSaved;
  for (int k = kSplit; k < kTotal; ++k) step(resumed, xResumed);
  EXPECT_TRUE(sameBits(x, xResumed)) << (x - xResumed).transpose();
  EXPECT_TRUE(sameBits(uninterrupted.state().low, resumed.state().low));
  EXPECT_TRUE(sameBits(uninterrupted.state().upp, resumed.state().upp));
  EXPECT_EQ(uninterrupted.state().iteration, resumed.state().iteration);

  // Without the state the continuation differs: the comparison above can fail.
  Mma fresh(p.n, p.m);
  Vector xFresh = xSaved;
  for (int k = kSplit; k < kTotal; ++k) step(fresh, xFresh);
  EXPECT_FALSE(sameBits(x, xFresh));
}

TEST(Mma, UpdateAllocatesNothing) {
  if (!testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counting unavailable";
  const int n = 1000;
  Mma mma(n, 2);
  Vector x = Vector::Constant(n, 0.5), df0 = Vector::LinSpaced(n, -1.0, 1.0), f(2), xmin = Vector::Zero(n),
         xmax = Vector::Ones(n);
  Matrix df = Matrix::Ones(2, n);
  df.row(1) = Vector::LinSpaced(n, 0.5, 2.0).transpose();
  f << 0.1, -0.2;
  {
    testing::AllocationCounter counter;
    for (int k = 0; k < 4; ++k) mma.update(0.0, df0, f, df, xmin, xmax, x);
    EXPECT_EQ(counter.count(), 0);
  }
  const MmaState state = mma.state();  // copying out allocates; restoring into the same sizes must not
  testing::AllocationCounter counter;
  mma.restore(state);
  mma.update(0.0, df0, f, df, xmin, xmax, x);
  EXPECT_EQ(counter.count(), 0);
}

// Messages must name the offending argument.
template <typename F>
void ExpectInvalidArgumentNaming(F&& call, const std::string& name) {
  try {
    call();
    ADD_FAILURE() << "no exception; expected one naming " << name;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
  }
}

TEST(Mma, BadArgumentsThrowNamingTheArgument) {
  ExpectInvalidArgumentNaming([] { Mma(0, 1); }, "n = 0");
  ExpectInvalidArgumentNaming([] { Mma(3, -1); }, "m = -1");

  std::string error;
  EXPECT_TRUE(MmaOptions().IsValid(&error));
  MmaOptions options;
  options.move_limit = 0.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("move_limit"), std::string::npos) << error;
  ExpectInvalidArgumentNaming([&] { Mma(3, 1, options); }, "move_limit");
  options = MmaOptions();
  options.min_asymptote_distance = 0.0;
  ExpectInvalidArgumentNaming([&] { Mma(3, 1, options); }, "min_asymptote_distance");
  options = MmaOptions();
  options.asymptote_contraction = std::nan("");
  ExpectInvalidArgumentNaming([&] { Mma(3, 1, options); }, "asymptote_contraction");
  options = MmaOptions();
  options.move_limit_shrink = 1.0;
  ExpectInvalidArgumentNaming([&] { Mma(3, 1, options); }, "move_limit_shrink");
  options = MmaOptions();
  options.move_limit_growth = 0.9;
  ExpectInvalidArgumentNaming([&] { Mma(3, 1, options); }, "move_limit_growth");
  options = MmaOptions();
  options.min_move_limit = 0.6;  // above move_limit 0.5
  ExpectInvalidArgumentNaming([&] { Mma(3, 1, options); }, "min_move_limit");

  Mma mma(3, 1);
  Vector x = Vector::Constant(3, 0.5), df0 = Vector::Ones(3), f = Vector::Zero(1), xmin = Vector::Zero(3),
         xmax = Vector::Ones(3);
  Matrix df = Matrix::Ones(1, 3);
  ExpectInvalidArgumentNaming([&] { mma.update(0.0, Vector::Ones(2), f, df, xmin, xmax, x); },
                              "objective_gradient");
  ExpectInvalidArgumentNaming([&] { mma.update(0.0, df0, Vector::Zero(2), df, xmin, xmax, x); },
                              "constraints");
  ExpectInvalidArgumentNaming([&] { mma.update(0.0, df0, f, Matrix::Ones(1, 2), xmin, xmax, x); },
                              "constraint_jacobian");
  Vector badMin = xmin;
  badMin(2) = 1.0;
  ExpectInvalidArgumentNaming([&] { mma.update(0.0, df0, f, df, badMin, xmax, x); }, "xmin(2)");
  Vector outside = x;
  outside(1) = 1.5;
  ExpectInvalidArgumentNaming([&] { mma.update(0.0, df0, f, df, xmin, xmax, outside); }, "x(1)");
  Vector nanConstraint = f;
  nanConstraint(0) = std::nan("");
  ExpectInvalidArgumentNaming([&] { mma.update(0.0, df0, nanConstraint, df, xmin, xmax, x); },
                              "constraints(0)");
  EXPECT_EQ(mma.state().iteration, 0);  // rejected calls leave the state alone

  MmaState state = mma.state();
  state.low.resize(2);
  ExpectInvalidArgumentNaming([&] { mma.restore(state); }, "state.low");
  state = mma.state();
  state.iteration = -1;
  ExpectInvalidArgumentNaming([&] { mma.restore(state); }, "state.iteration");
}

}  // namespace
}  // namespace hindsight
