// Tests of GCMMA (problems/topopt/gcmma.h): Svanberg's published problems (the 1987 cantilever beam,
// whose optimum is on the nonlinear deflection constraint, and the two spheres of the 2007 note, two
// active nonlinear constraints), conservativeness (feasible, never-worse accepted iterates), a
// nonconvex objective where the first approximations are not conservative, bit-exact restart and
// argument checking.
#include <hindsight/problems/topopt/gcmma.h>

#include "support/same_bits.h"
#include "support/svanberg_problems.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

using testing::sameBits;

using Problem = testing::OptimizationProblem;
using testing::CantileverBeam;
using testing::kBeamCompliance;
using testing::kBeamWeight;
using testing::kSphereCenters;
using testing::TwoSpheres;

struct History {
  std::vector<double> objective;   // f0 of every accepted iterate, x0 first
  std::vector<double> constraint;  // max_i f_i of every accepted iterate
  std::vector<int> inner;          // trials per outer iteration
  Vector x;
  Vector constraints;
  int iterations = 0;
};

History RunGcmma(const Problem& p, int maxIterations, double tolerance, Gcmma& gcmma, Vector x) {
  History h;
  Vector df0(p.n), f(p.m), previous(p.n);
  Matrix df(p.m, p.n);
  double f0 = 0.0;
  int trialCalls = 0;
  const Gcmma::Evaluate evaluate = [&](const Vector& trial, double& objective, Vector& constraints) {
    ++trialCalls;
    p.evaluate(trial, &objective, nullptr, &constraints, nullptr);
    return true;
  };
  for (int k = 0; k < maxIterations; ++k) {
    p.evaluate(x, &f0, &df0, &f, &df);
    h.objective.push_back(f0);
    h.constraint.push_back(f.maxCoeff());
    previous = x;
    trialCalls = 0;
    gcmma.update(f0, df0, f, df, p.xmin, p.xmax, x, evaluate);
    EXPECT_EQ(trialCalls, gcmma.lastUpdate().inner_iterations);
    h.inner.push_back(gcmma.lastUpdate().inner_iterations);
    h.iterations = k + 1;
    if ((x - previous).cwiseAbs().maxCoeff() < tolerance) break;
  }
  p.evaluate(x, &f0, &df0, &f, &df);
  h.objective.push_back(f0);
  h.constraint.push_back(f.maxCoeff());
  h.x = x;
  h.constraints = f;
  return h;
}

// Every accepted iterate of a run from a feasible start is feasible (to the conservativeness
// tolerance) and no worse than the previous one.
// The accepted iterates approach a KKT point only to about sqrt(barrier): from a feasible design a trial
// may not increase the objective, and the subproblem's interior point keeps an active constraint
// epsilon / lambda inside, which costs about epsilon in the objective. The KKT checks therefore run
// with a tighter barrier (and the matching conservativeness tolerance, as in Svanberg's note).
GcmmaOptions TightOptions() {
  GcmmaOptions options;
  options.mma.subproblem_tolerance = 1e-11;
  options.conservative_tolerance = 0.5e-11;
  return options;
}

void ExpectConservative(const History& h, double tolerance) {
  for (std::size_t k = 0; k < h.objective.size(); ++k) {
    EXPECT_LE(h.constraint[k], tolerance) << "iterate " << k;
    if (k > 0) EXPECT_LE(h.objective[k], h.objective[k - 1]) << "iterate " << k;
  }
}

// Svanberg (1987), sec. 6: the cantilever beam (tests/support/svanberg_problems.h); x0 = 5 lies on
// the deflection constraint (f1(x0) = 0).
TEST(Gcmma, CantileverBeamOfSvanberg1987IsFeasibleAndMonotoneAllTheWay) {
  const Problem p = CantileverBeam();
  Gcmma gcmma(p.n, p.m, TightOptions());
  const History h = RunGcmma(p, 200, 1e-9, gcmma, p.x0);
  EXPECT_LT(h.iterations, 200);
  double rootSum = 0.0;
  for (double c : kBeamCompliance) rootSum += std::pow(c, 0.25);
  const double t = std::cbrt(rootSum);
  const double exact = kBeamWeight * t * rootSum;
  int trials = 0;
  for (int n : h.inner) trials += n;
  std::cout << "[ beam     ] GCMMA f = " << h.objective.back() << " (exact " << exact << ") after "
            << h.iterations << " outer, " << trials << " inner iterations\n";
  EXPECT_NEAR(h.objective.back(), exact, 1e-6 * exact);
  for (int j = 0; j < 5; ++j) EXPECT_NEAR(h.x(j), t * std::pow(kBeamCompliance[j], 0.25), 1e-5) << j;
  ExpectConservative(h, TightOptions().conservative_tolerance);
}

// Svanberg (2007): minimize |x|^2 subject to two spheres of radius 3; both nonlinear constraints are
// active at the optimum (2.0175, 1.7800, 1.2375).
TEST(Gcmma, TwoSpheresOfSvanberg2007ReachTheKktPointThroughFeasibleIterates) {
  const Problem p = TwoSpheres();
  Gcmma gcmma(p.n, p.m, TightOptions());
  const History h = RunGcmma(p, 300, 1e-10, gcmma, p.x0);
  EXPECT_LT(h.iterations, 300);
  const Vector& lambda = gcmma.lastSubproblem().lambda;
  std::cout << "[ spheres  ] GCMMA f = " << h.objective.back() << " after " << h.iterations
            << " iterations, x = " << h.x.transpose() << ", lambda = " << lambda.transpose() << "\n";
  Vector stationarity = 2.0 * h.x;
  for (int i = 0; i < 2; ++i) {
    EXPECT_GT(lambda(i), 0.0) << i;
    EXPECT_NEAR(h.constraints(i), 0.0, 1e-6) << i;
    for (int j = 0; j < 3; ++j) stationarity(j) += lambda(i) * 2.0 * (h.x(j) - kSphereCenters[i][j]);
  }
  EXPECT_LT(stationarity.cwiseAbs().maxCoeff(), 1e-6) << stationarity.transpose();
  EXPECT_NEAR(h.x(0), 2.0175, 1e-4);
  EXPECT_NEAR(h.x(1), 1.7800, 1e-4);
  EXPECT_NEAR(h.x(2), 1.2375, 1e-4);
  ExpectConservative(h, TightOptions().conservative_tolerance);
}

// A nonconvex objective (a sum of cosines, concave near x0) with a nonlinear constraint that is
// active at the solution: MMA's convex approximations underestimate it, so GCMMA needs inner
// iterations, and the objective history must still never increase.
Problem WavyDisk() {
  Problem p;
  p.n = 4;
  p.m = 1;
  p.xmin = Vector::Constant(4, -2.0);
  p.xmax = Vector::Constant(4, 2.0);
  p.x0 = Vector::Constant(4, 0.1);
  p.evaluate = [](const Vector& x, double* f0, Vector* df0, Vector* f, Matrix* df) {
    *f0 = 0.0;
    for (int j = 0; j < 4; ++j) {
      *f0 += std::cos(3.0 * x(j)) + 0.5 * x(j);
      if (df0 != nullptr) (*df0)(j) = -3.0 * std::sin(3.0 * x(j)) + 0.5;
    }
    (*f)(0) = x.squaredNorm() - 2.0;
    if (df != nullptr) df->row(0) = 2.0 * x.transpose();
  };
  return p;
}

TEST(Gcmma, NonconvexObjectiveNeedsInnerIterationsAndNeverIncreases) {
  const Problem p = WavyDisk();
  Gcmma gcmma(p.n, p.m, TightOptions());
  const History h = RunGcmma(p, 200, 1e-9, gcmma, p.x0);
  int maxInner = 0;
  for (int n : h.inner) maxInner = std::max(maxInner, n);
  std::cout << "[ wavy     ] GCMMA f = " << h.objective.front() << " -> " << h.objective.back() << " after "
            << h.iterations << " iterations (at most " << maxInner << " trials), x = " << h.x.transpose()
            << "\n";
  EXPECT_GT(maxInner, 1);  // some approximation was not conservative
  ExpectConservative(h, TightOptions().conservative_tolerance);
  EXPECT_LT(h.objective.back(), h.objective.front() - 1.0);
  EXPECT_LT(h.iterations, 200);
  // A KKT point: the gradient of the Lagrangian vanishes with the last multiplier.
  const double lambda = gcmma.lastSubproblem().lambda(0);
  for (int j = 0; j < 4; ++j) {
    const double g = -3.0 * std::sin(3.0 * h.x(j)) + 0.5 + lambda * 2.0 * h.x(j);
    const bool atBound = h.x(j) <= p.xmin(j) + 1e-6 || h.x(j) >= p.xmax(j) - 1e-6;
    if (!atBound) EXPECT_NEAR(g, 0.0, 1e-4) << j;
  }
}

TEST(Gcmma, DescentAcceptanceKeepsFeasibleNeverWorseIteratesWithNoMoreTrials) {
  const Problem p = WavyDisk();
  GcmmaOptions options = TightOptions();
  Gcmma strict(p.n, p.m, options);
  options.accept_descent = true;
  Gcmma descent(p.n, p.m, options);
  const History a = RunGcmma(p, 200, 1e-9, strict, p.x0);
  const History b = RunGcmma(p, 200, 1e-9, descent, p.x0);
  int trialsA = 0, trialsB = 0;
  for (int n : a.inner) trialsA += n;
  for (int n : b.inner) trialsB += n;
  std::cout << "[ wavy     ] trials: conservative " << trialsA << ", with descent acceptance " << trialsB
            << "; f = " << b.objective.back() << "\n";
  ExpectConservative(b, options.conservative_tolerance);
  EXPECT_LE(trialsB, trialsA);
  EXPECT_NEAR(b.objective.back(), a.objective.back(), 1e-6);
}

TEST(Gcmma, FailedTrialEvaluationsRaiseEveryRhoAndTheStepStaysShort) {
  const Problem p = TwoSpheres();
  Gcmma gcmma(p.n, p.m);
  Vector x = p.x0;
  double f0 = 0.0;
  Vector df0(3), f(2);
  Matrix df(2, 3);
  p.evaluate(x, &f0, &df0, &f, &df);
  int calls = 0;
  // The first two trials "diverge" (false), as a failed simulation does in the rod optimizer.
  gcmma.update(f0, df0, f, df, p.xmin, p.xmax, x, [&](const Vector& t, double& o, Vector& c) {
    ++calls;
    p.evaluate(t, &o, nullptr, &c, nullptr);
    return calls > 2;
  });
  EXPECT_EQ(gcmma.lastUpdate().failed_evaluations, 2);
  EXPECT_GE(gcmma.lastUpdate().inner_iterations, 3);
  EXPECT_TRUE(gcmma.lastUpdate().accepted);
  double fNew = 0.0;
  Vector fc(2);
  p.evaluate(x, &fNew, nullptr, &fc, nullptr);
  EXPECT_LT(fNew, f0);
  EXPECT_LE(fc.maxCoeff(), 0.0);
}

TEST(Gcmma, RestoredStateContinuesBitIdentically) {
  const Problem p = TwoSpheres();
  Gcmma first(p.n, p.m);
  const History head = RunGcmma(p, 6, 0.0, first, p.x0);
  const MmaState stored = first.state();
  const History tail = RunGcmma(p, 6, 0.0, first, head.x);

  Gcmma resumed(p.n, p.m);
  resumed.restore(stored);
  const History again = RunGcmma(p, 6, 0.0, resumed, head.x);
  EXPECT_TRUE(sameBits(tail.x, again.x));
  EXPECT_EQ(tail.inner, again.inner);
  EXPECT_TRUE(sameBits(first.state().low, resumed.state().low));
}

TEST(Gcmma, BadOptionsThrowNamingTheField) {
  GcmmaOptions options;
  options.max_inner_iterations = 0;
  try {
    Gcmma gcmma(3, 1, options);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_inner_iterations"), std::string::npos) << e.what();
  }
  options = GcmmaOptions();
  options.mma.move_limit = 2.0;
  EXPECT_THROW(Gcmma(3, 1, options), std::invalid_argument);
  options = GcmmaOptions();
  options.min_regularization = 0.0;
  EXPECT_THROW(Gcmma(3, 1, options), std::invalid_argument);
}

}  // namespace
}  // namespace hindsight
