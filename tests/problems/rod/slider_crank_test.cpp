// The reduced slider-crank equations against Lagrange's equations built from the nodal kinetic
// energy, and every derivative the adjoint uses against finite differences.
#include "support/slider_crank.h"

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/engine/integrator.h>
#include "support/allocation_counting.h"
#include "support/synthetic_rod.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <iostream>

namespace hindsight::rod {
namespace {

using testing::SyntheticRod;

struct Fixture {
  explicit Fixture(int modes, unsigned seed = 7)
      : body(modes, 1.0, seed),
        problem(modes, 1.0, CrankMotion{}),
        p(body.invariants()),
        workspace(problem.createModelWorkspace()) {
    std::mt19937 rng(seed + 1);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    q = Vector::NullaryExpr(modes, [&] { return 0.01 * u(rng); });
    qd = Vector::NullaryExpr(modes, [&] { return 0.5 * u(rng); });
    a = Vector::NullaryExpr(modes, [&] { return 20.0 * u(rng); });
  }
  Vector residual(double t, const Vector& qq, const Vector& vv, const Vector& aa, const Vector& pp) const {
    Vector r(qq.size());
    problem.residual(t, qq, vv, aa, pp, r, workspace.get());
    return r;
  }
  SyntheticRod body;
  SliderCrankProblem problem;
  Vector p, q, qd, a;
  std::unique_ptr<ProblemWorkspace> workspace;
};

TEST(SliderCrank, ResidualSatisfiesLagrangesEquationsOfTheNodalKineticEnergy) {
  for (double t : {0.37, 1.3, 2.6}) {  // in the ramp and at constant speed
    Fixture f(4);
    const CrankMotion crank;
    const int n = 4;
    const auto T = [&](double tt, const Vector& qq, const Vector& vv) {
      return f.body.kineticEnergy(crank, 1.0, tt, qq, vv);
    };
    // dT/dq' is exact by central differences (T is quadratic in q'); dT/dq with a small step.
    const auto dTdv = [&](double tt, const Vector& qq, const Vector& vv) {
      Vector g(n);
      for (int i = 0; i < n; ++i) {
        Vector plus = vv, minus = vv;
        plus(i) += 1e-3;
        minus(i) -= 1e-3;
        g(i) = (T(tt, qq, plus) - T(tt, qq, minus)) / 2e-3;
      }
      return g;
    };
    Vector dTdq(n);
    for (int i = 0; i < n; ++i) {
      Vector plus = f.q, minus = f.q;
      plus(i) += 1e-6;
      minus(i) -= 1e-6;
      dTdq(i) = (T(t, plus, f.qd) - T(t, minus, f.qd)) / 2e-6;
    }
    // d/dt along the path q(t +- d) = q +- d q' + d^2/2 q'', q'(t +- d) = q' +- d q''.
    const double d = 1e-4;
    const Vector ddt = (dTdv(t + d, f.q + d * f.qd + 0.5 * d * d * f.a, f.qd + d * f.a) -
                        dTdv(t - d, f.q - d * f.qd + 0.5 * d * d * f.a, f.qd - d * f.a)) /
                       (2 * d);
    const Vector lagrange = ddt - dTdq + f.body.kee * f.q;
    const Vector r = f.residual(t, f.q, f.qd, f.a, f.p);
    const double relative = (lagrange - r).norm() / r.norm();
    std::cout << "[ Lagrange ] t = " << t << ": relative residual " << relative << "\n";
    EXPECT_LT(relative, 1e-6) << "model " << r.transpose() << "\nLagrange " << lagrange.transpose();
  }
}

TEST(SliderCrank, MassMatrixIsTheAccelerationPartOfTheResidual) {
  Fixture f(5);
  const double t = 1.1;
  Matrix mass(5, 5);
  f.problem.massMatrix(t, f.q, f.p, mass, f.workspace.get());
  const Vector r0 = f.residual(t, f.q, f.qd, Vector::Zero(5), f.p);
  const Vector r1 = f.residual(t, f.q, f.qd, f.a, f.p);
  EXPECT_LT((mass * f.a - (r1 - r0)).norm(), 1e-12 * (r1 - r0).norm());
  EXPECT_LT((mass - mass.transpose()).norm(), 1e-14 * mass.norm());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix>(mass).eigenvalues().minCoeff(), 0.0);
}

TEST(SliderCrank, MassMatrixAndForceInOnePassEqualTheResidual) {
  // The one-pass kernel (M and f with one frame kinematics) against the separately written residual:
  // f = -r(a = 0) and M a = r(a) - r(0); with a workspace made for p (M_ee's symmetric part kept for the
  // solve) the bits are those of a plain workspace.
  Fixture f(5);
  const auto fixed = f.problem.createModelWorkspaceFor(f.p);
  for (double t : {0.0, 0.9, 2.0, 2.7}) {
    Matrix mass(5, 5), massFixed(5, 5), massAlone(5, 5);
    Vector force(5), forceFixed(5), forceAlone(5);
    f.problem.massMatrixAndForce(t, f.q, f.qd, f.p, mass, force, f.workspace.get());
    f.problem.massMatrixAndForce(t, f.q, f.qd, f.p, massFixed, forceFixed, fixed.get());
    f.problem.massMatrix(t, f.q, f.p, massAlone, f.workspace.get());
    f.problem.force(t, f.q, f.qd, f.p, forceAlone, f.workspace.get());
    const Vector r0 = f.residual(t, f.q, f.qd, Vector::Zero(5), f.p);
    const Vector r1 = f.residual(t, f.q, f.qd, f.a, f.p);
    EXPECT_LT((force + r0).norm(), 1e-13 * r0.norm()) << "t = " << t;
    EXPECT_LT((mass * f.a - (r1 - r0)).norm(), 1e-12 * (r1 - r0).norm()) << "t = " << t;
    EXPECT_EQ(mass, massFixed);
    EXPECT_EQ(force, forceFixed);
    EXPECT_EQ(mass, massAlone);
    EXPECT_EQ(force, forceAlone);
  }
}

TEST(SliderCrank, CombinedProductsEqualTheSeparateOnes) {
  // residualVjps (one set of product scalars for the adjoint stage) has the bits of the two separate
  // products, with a plain workspace and with one made for p.
  Fixture f(6);
  const auto fixed = f.problem.createModelWorkspaceFor(f.p);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Vector mu = Vector::NullaryExpr(6, [&] { return u(rng); });
  for (double t : {0.3, 1.9, 2.4}) {
    Vector outQ(6), outV(6), gradient = Vector::Constant(f.p.size(), 0.25);
    f.problem.residualStateVjp(t, f.q, f.qd, f.a, f.p, mu, outQ, outV, f.workspace.get());
    f.problem.addResidualParameterVjp(t, f.q, f.qd, f.a, f.p, mu, gradient, f.workspace.get());
    for (ProblemWorkspace* ws : {f.workspace.get(), fixed.get()}) {
      Vector q2(6), v2(6), gradient2 = Vector::Constant(f.p.size(), 0.25);
      f.problem.residualVjps(t, f.q, f.qd, f.a, f.p, mu, q2, v2, gradient2, ws);
      EXPECT_EQ(q2, outQ) << "t = " << t;
      EXPECT_EQ(v2, outV) << "t = " << t;
      EXPECT_EQ(gradient2, gradient) << "t = " << t;
    }
  }
}

TEST(SliderCrank, StepsAndAdjointStepsAllocateNothing) {
  // The kernels' scratch (the symmetric M_ee, the crank's last two times, the AD buffers) lives in the
  // workspace made once per solve.
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  Fixture f(8);
  for (const char* method : {"rk4", "generalized-alpha"}) {
    IntegratorOptions options;
    options.method = method;
    const std::unique_ptr<Integrator> integrator = createIntegrator(f.problem, f.p, options);
    const int m = integrator->stateSize();
    Vector z(m), zStart(m), lambda = Vector::Ones(m), gradient = Vector::Zero(f.p.size());
    integrator->initialState(0.0, z);
    zStart = z;
    long forward = 0, adjoint = 0;
    {
      testing::AllocationCounter counter;
      for (int i = 0; i < 10; ++i) integrator->step(0.3 + 1e-3 * i, 1e-3, z, nullptr);
      forward = counter.count();
    }
    {
      testing::AllocationCounter counter;
      for (int i = 0; i < 10; ++i) integrator->adjointStep(0.3 + 1e-3 * i, 1e-3, zStart, lambda, gradient);
      adjoint = counter.count();
    }
    EXPECT_EQ(forward, 0) << method;
    EXPECT_EQ(adjoint, 0) << method;
  }
}

TEST(SliderCrank, StateJacobiansMatchFiniteDifferences) {
  Fixture f(5);
  for (double t : {0.4, 2.5}) {
    Matrix rq(5, 5), rv(5, 5);
    f.problem.residualJacobians(t, f.q, f.qd, f.a, f.p, rq, rv, f.workspace.get());
    for (int i = 0; i < 5; ++i) {
      const auto qCheck = checkGradient([&](const Vector& x) { return f.residual(t, x, f.qd, f.a, f.p)(i); },
                                        f.q, rq.row(i).transpose(), {1e-7});
      EXPECT_TRUE(qCheck.passed) << "row " << i << " of r_q: " << qCheck.message;
      // r is quadratic in q', so a large central-difference step is exact and avoids round-off.
      GradientCheckOptions quadratic;
      quadratic.tolerance = 1e-7;
      quadratic.relativeStep = 1e-2;
      const auto vCheck = checkGradient([&](const Vector& x) { return f.residual(t, f.q, x, f.a, f.p)(i); },
                                        f.qd, rv.row(i).transpose(), quadratic);
      EXPECT_TRUE(vCheck.passed) << "row " << i << " of r_v: " << vCheck.message;
    }
  }
}

// The O(n^2) Jacobians by hand through the channels c = b q, c' = b q' against forward AD through the
// whole residual (2n directions), in the ramp and after it, for a small and a large mode count (the AD
// route has two capacities). A missing or transposed term is off by far more than round-off.
TEST(SliderCrank, ChannelJacobiansEqualTheAutoDiffJacobians) {
  for (int modes : {5, 13}) {
    Fixture f(modes);
    for (double t : {0.1, 0.4, 1.7, 2.5}) {
      Matrix rq(modes, modes), rv(modes, modes), rqAd(modes, modes), rvAd(modes, modes);
      f.problem.residualJacobians(t, f.q, f.qd, f.a, f.p, rq, rv, f.workspace.get());
      f.problem.residualJacobiansByAutoDiff(t, f.q, f.qd, f.a, f.p, rqAd, rvAd, f.workspace.get());
      EXPECT_LT((rq - rqAd).norm(), 1e-13 * rqAd.norm()) << modes << " modes, t = " << t;
      EXPECT_LT((rv - rvAd).norm(), 1e-13 * rvAd.norm()) << modes << " modes, t = " << t;
      EXPECT_GT(rvAd.norm(), 0.0);
    }
  }
}

TEST(SliderCrank, StateProductEqualsTheTransposedJacobians) {
  Fixture f(5);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Vector mu = Vector::NullaryExpr(5, [&] { return u(rng); });
  for (double t : {0.4, 1.7, 2.5}) {
    Matrix rq(5, 5), rv(5, 5);
    // The AD Jacobians: the channel Jacobians are the state product's transposed form.
    f.problem.residualJacobiansByAutoDiff(t, f.q, f.qd, f.a, f.p, rq, rv, f.workspace.get());
    Vector outQ(5), outV(5);
    f.problem.residualStateVjp(t, f.q, f.qd, f.a, f.p, mu, outQ, outV, f.workspace.get());
    EXPECT_LT((outQ - rq.transpose() * mu).norm(), 1e-12 * (rq.transpose() * mu).norm()) << "t = " << t;
    EXPECT_LT((outV - rv.transpose() * mu).norm(), 1e-12 * (rv.transpose() * mu).norm()) << "t = " << t;
  }
}

TEST(SliderCrank, ParameterProductMatchesFiniteDifferencesForEveryInvariant) {
  Fixture f(4);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Vector mu = Vector::NullaryExpr(4, [&] { return u(rng); });
  for (double t : {0.8, 2.2}) {
    Vector vjp = Vector::Zero(f.p.size());
    f.problem.addResidualParameterVjp(t, f.q, f.qd, f.a, f.p, mu, vjp, f.workspace.get());
    const auto check = checkGradient(
        [&](const Vector& x) { return mu.dot(f.residual(t, f.q, f.qd, f.a, x)); }, f.p, vjp, {1e-6, 1e-6});
    EXPECT_TRUE(check.passed) << "t = " << t << ": " << check.message;
  }
}

TEST(SliderCrank, ObjectiveGradientsMatchFiniteDifferences) {
  Fixture f(4);
  const auto G = [&](const Vector& qq, const Vector& pp) {
    return f.problem.integrand(0.0, qq, f.qd, pp, f.workspace.get());
  };
  Vector gq = Vector::Zero(4), gv = Vector::Zero(4), gp = Vector::Zero(f.p.size());
  f.problem.addIntegrandStateGradient(0.0, f.q, f.qd, f.p, 1.0, gq, gv, f.workspace.get());
  f.problem.addIntegrandParameterGradient(0.0, f.q, f.qd, f.p, 1.0, gp, f.workspace.get());
  const auto stateCheck = checkGradient([&](const Vector& x) { return G(x, f.p); }, f.q, gq, {1e-7});
  EXPECT_TRUE(stateCheck.passed) << stateCheck.message;
  const auto parameterCheck =
      checkGradient([&](const Vector& x) { return G(f.q, x); }, f.p, gp, {1e-7, 1e-6});
  EXPECT_TRUE(parameterCheck.passed) << parameterCheck.message;
  EXPECT_EQ(gv.norm(), 0.0);
}

TEST(SliderCrank, DiscreteAdjointIsTheDerivativeOfTheComputedObjective) {
  // One second of the ramp, 3 modes: every one of the 46 invariants is checked. Components below
  // 1e-3 of the largest are judged against that scale (central differences of psi ~ 1e-7 cannot
  // resolve them better); trbdf2 carries its Newton residual (1e-13 relative) on top.
  Fixture f(3);
  for (const std::string method : {"rk4", "trbdf2"}) {
    IntegratorOptions options;
    options.method = method;
    options.t1 = 1.0;
    options.step = 1e-3;
    FullStorage storage;
    const GradientResult result = computeGradient(f.problem, f.p, options, storage);
    EXPECT_GT(result.objective, 0.0);
    const auto check =
        checkGradient([&](const Vector& x) { return simulate(f.problem, x, options).objective; }, f.p,
                      result.gradient, {method == "rk4" ? 1e-6 : 5e-6, 1e-3});
    EXPECT_TRUE(check.passed) << method << ": " << check.message;
    // A wrong term would show: the gradient is far from zero in every invariant group.
    EXPECT_GT(result.gradient.cwiseAbs().maxCoeff(), 1e3 * result.gradient.cwiseAbs().minCoeff());
  }
}

TEST(SliderCrank, CrankRampIsCycloidal) {
  const CrankMotion crank;
  double phi, phiDot, phiDdot;
  crank.at(0.0, phi, phiDot, phiDdot);
  EXPECT_EQ(phi, 0.0);
  EXPECT_EQ(phiDot, 0.0);
  EXPECT_NEAR(phiDdot, 0.0, 1e-14);
  crank.at(2.0, phi, phiDot, phiDdot);
  EXPECT_NEAR(phiDot, 10 * M_PI, 1e-12);
  EXPECT_NEAR(phiDdot, 0.0, 1e-12);
  EXPECT_NEAR(phi, 10 * M_PI, 1e-12);  // Omega T / 2
  // phi' is the derivative of phi, phi'' of phi' (central differences).
  for (double t : {0.3, 1.0, 1.7, 2.5}) {
    double p1, d1, a1, p2, d2, a2;
    crank.at(t + 1e-6, p1, d1, a1);
    crank.at(t - 1e-6, p2, d2, a2);
    crank.at(t, phi, phiDot, phiDdot);
    EXPECT_NEAR((p1 - p2) / 2e-6, phiDot, 1e-6 * (1 + phiDot));
    EXPECT_NEAR((d1 - d2) / 2e-6, phiDdot, 1e-6 * (1 + std::abs(phiDdot)));
  }
}

TEST(SliderCrank, BadConstructionArgumentsAreNamed) {
  EXPECT_THROW(SliderCrankProblem(0, 1.0, CrankMotion{}), std::invalid_argument);
  EXPECT_THROW(SliderCrankProblem(41, 1.0, CrankMotion{}), std::invalid_argument);
  CrankMotion tooLong;
  tooLong.radius = 1.5;
  try {
    SliderCrankProblem(4, 1.0, tooLong);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("crank radius"), std::string::npos);
  }
}

}  // namespace
}  // namespace hindsight::rod
