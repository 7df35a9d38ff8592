// The described slider-crank against the closed form (tests/support/slider_crank.h, itself checked
// against Lagrange's equations of the nodal kinetic energy), and every derivative of the generic
// mechanism equations against finite differences, on a synthetic member (tests/support/synthetic_rod.h).
#include <hindsight/problems/mechanism/mechanism_problem.h>

#include <hindsight/problems/mechanism/mechanism_json.h>

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/engine/integrator.h>
#include "support/slider_crank.h"

#include "support/allocation_counting.h"
#include "support/synthetic_rod.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <cmath>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <tuple>

namespace hindsight::mechanism {
namespace {

using testing::SyntheticRod;

struct State {
  State(int f, unsigned seed, int freeCount = 0) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    y = Vector::NullaryExpr(f, [&] { return 0.01 * u(rng); });
    v = Vector::NullaryExpr(f, [&] { return 0.5 * u(rng); });
    a = Vector::NullaryExpr(f, [&] { return 20.0 * u(rng); });
    mu = Vector::NullaryExpr(f, [&] { return u(rng); });
    for (int i = 0; i < freeCount; ++i) y(i) = 0.3 + 0.2 * u(rng);
  }
  Vector y, v, a, mu;
};

Vector residualOf(const MechanismProblem& problem, ProblemWorkspace* ws, double t, const Vector& y,
                  const Vector& v, const Vector& a, const Vector& p) {
  Vector r(y.size());
  problem.residual(t, y, v, a, p, r, ws);
  return r;
}

TEST(MechanismSliderCrank, EqualsTheBuiltInModelTermByTerm) {
  const int n = 4;
  const SyntheticRod body(n, 1.0, 7);
  const Vector p = body.invariants();
  const rod::CrankMotion crank;
  const rod::SliderCrankProblem builtIn(n, 1.0, crank);
  const MechanismProblem described(sliderCrank(crank.radius, 1.0, crank.omega, crank.rampTime), n);
  ASSERT_EQ(described.coordinateCount(), n);
  ASSERT_EQ(described.parameterSize(), builtIn.parameterSize());
  auto wb = builtIn.createModelWorkspace();
  auto wd = described.createModelWorkspace();
  const State s(n, 8);
  for (double t : {0.37, 1.3, 2.6, 2.95}) {
    Vector rb(n), rd(n);
    builtIn.residual(t, s.y, s.v, s.a, p, rb, wb.get());
    described.residual(t, s.y, s.v, s.a, p, rd, wd.get());
    EXPECT_LT((rb - rd).norm(), 1e-12 * rb.norm()) << "t = " << t << "\n"
                                                   << rb.transpose() << "\n"
                                                   << rd.transpose();
    Matrix mb(n, n), md(n, n);
    Vector fb(n), fd(n);
    builtIn.massMatrixAndForce(t, s.y, s.v, p, mb, fb, wb.get());
    described.massMatrixAndForce(t, s.y, s.v, p, md, fd, wd.get());
    EXPECT_LT((mb - md).norm(), 1e-12 * mb.norm()) << "t = " << t;
    EXPECT_LT((fb - fd).norm(), 1e-12 * fb.norm()) << "t = " << t;
    Matrix ryb(n, n), rvb(n, n), ryd(n, n), rvd(n, n);
    builtIn.residualJacobians(t, s.y, s.v, s.a, p, ryb, rvb, wb.get());
    described.residualJacobians(t, s.y, s.v, s.a, p, ryd, rvd, wd.get());
    EXPECT_LT((ryb - ryd).norm(), 1e-10 * ryb.norm()) << "t = " << t;
    EXPECT_LT((rvb - rvd).norm(), 1e-10 * rvb.norm()) << "t = " << t;
    Vector gb = Vector::Zero(p.size()), gd = Vector::Zero(p.size());
    builtIn.addResidualParameterVjp(t, s.y, s.v, s.a, p, s.mu, gb, wb.get());
    described.addResidualParameterVjp(t, s.y, s.v, s.a, p, s.mu, gd, wd.get());
    EXPECT_LT((gb - gd).norm(), 1e-10 * gb.norm()) << "t = " << t;
    EXPECT_DOUBLE_EQ(builtIn.integrand(t, s.y, s.v, p, wb.get()),
                     described.integrand(t, s.y, s.v, p, wd.get()));
  }
}

TEST(MechanismSliderCrank, SimulationAndAdjointGradientEqualTheBuiltInModel) {
  const int n = 3;
  const SyntheticRod body(n, 1.0, 7);
  const Vector p = body.invariants();
  const rod::CrankMotion crank;
  const rod::SliderCrankProblem builtIn(n, 1.0, crank);
  const MechanismProblem described(sliderCrank(crank.radius, 1.0, crank.omega, crank.rampTime), n);
  IntegratorOptions options;
  options.method = "generalized-alpha";
  options.t1 = 1.0;
  options.step = 2e-3;
  FullStorage sb, sd;
  const GradientResult b = computeGradient(builtIn, p, options, sb);
  const GradientResult d = computeGradient(described, p, options, sd);
  EXPECT_NEAR(d.objective, b.objective, 1e-11 * b.objective);
  EXPECT_LT((d.gradient - b.gradient).norm(), 1e-10 * b.gradient.norm());
}

}  // namespace
}  // namespace hindsight::mechanism

namespace hindsight::mechanism {
namespace {

Mechanism fromExample(const std::string& file, double length = 1.0) {
  std::ifstream in(std::string(HINDSIGHT_EXAMPLES_DIR) + "/mechanisms/" + file);
  const nlohmann::json j = nlohmann::json::parse(in);
  return mechanismFromJson(j.at("mechanism"), length);
}

/// The slider-crank with a free crank (no driver): a crank with inertia, the slider with mass held
/// by a spring-damper to the ground, gravity. Exercises free coordinates, springs and gravity.
Mechanism freeSliderCrank() {
  Mechanism m = fromExample("slider_crank_mass.json");
  m.drivers.clear();
  m.rigidBodies[0].inertia = 0.05;
  m.rigidBodies[0].mass = 0.5;
  m.addFree("crank", CoordinateKind::Angle, 2.0);
  m.addGroundPoint("anchor", Vec2(2.0, 0.3));
  m.addSpring(Spring{"return", "ground", "anchor", "slider", "center", 400.0, 0.5, 3.0});
  m.gravity = Vec2(0.0, -9.81);
  return m;
}

/// Nodal kinetic energy of the synthetic member plus the rigid bodies' (independent of the model's
/// invariants and inertia forces), and the potential energy from the nodal masses.
struct NodalEnergy {
  const SyntheticRod& body;
  const MechanismProblem& problem;
  double kinetic(const Vector& z, const Vector& zd) const {
    const int o = problem.memberOffset(), n = problem.modeCount();
    const double c = std::cos(z(o + 2)), s = std::sin(z(o + 2));
    const Eigen::Vector2d local(c * zd(o) + s * zd(o + 1), -s * zd(o) + c * zd(o + 1));
    const Vector w = body.X + body.phi * z.segment(o + 3, n);
    const Vector W = body.ex * local(0) + body.ey * local(1) + zd(o + 2) * SyntheticRod::rotateNodewise(w) +
                     body.phi * zd.segment(o + 3, n);
    double t = 0.5 * W.dot(body.mass * W);
    const auto& bodies = problem.mechanism().rigidBodies;
    for (std::size_t k = 0; k < bodies.size(); ++k) {
      t += 0.5 * bodies[k].mass * zd.segment<2>(3 * k).squaredNorm() +
           0.5 * bodies[k].inertia * zd(3 * k + 2) * zd(3 * k + 2);
    }
    return t;
  }
  double potential(const Vector& z) const {
    const int o = problem.memberOffset(), n = problem.modeCount();
    const Vector q = z.segment(o + 3, n);
    double v = 0.5 * q.dot(body.kee * q);
    const Vec2 g = problem.mechanism().gravity;
    const double c = std::cos(z(o + 2)), s = std::sin(z(o + 2));
    const Vector w = body.X + body.phi * q;
    Vector r(w.size());
    for (int k = 0; k < w.size() / 2; ++k) {
      r(2 * k) = z(o) + c * w(2 * k) - s * w(2 * k + 1);
      r(2 * k + 1) = z(o + 1) + s * w(2 * k) + c * w(2 * k + 1);
    }
    const Vector gravity = body.ex * g(0) + body.ey * g(1);
    v -= gravity.dot(body.mass * r);
    const auto& bodies = problem.mechanism().rigidBodies;
    for (std::size_t k = 0; k < bodies.size(); ++k) v -= bodies[k].mass * g.dot(z.segment<2>(3 * k));
    for (const Spring& sp : problem.mechanism().springs) {
      // Only ground-to-rigid-body springs in these tests.
      const auto& ground = problem.mechanism().groundPoints;
      int k = 0;
      for (std::size_t i = 0; i < bodies.size(); ++i) {
        if (bodies[i].name == sp.body2) k = static_cast<int>(i);
      }
      const double a = z(3 * k + 2);
      const Vec2 local = bodies[k].points.at(sp.point2);
      const Vec2 p2 = z.segment<2>(3 * k) + Eigen::Rotation2Dd(a) * local;
      const double l = (p2 - ground.at(sp.point1)).norm();
      v += 0.5 * sp.stiffness * (l - sp.restLength) * (l - sp.restLength);
    }
    return v;
  }
};

/// p of a member that deforms in 3-D (problems/rod/invariants.h): the plate layout and the rotation's
/// modal mass M_ee^xy after b, here 0.7 M_ee plus a symmetric perturbation, so that a term that takes
/// M_ee where M_ee^xy belongs (or the reverse) changes the residual.
Vector withRotationalModalMass(const Vector& plate, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  Vector p(plate.size() + n * n);
  p.head(plate.size()) = plate;
  const int mee = 4 + 4 * n + n * n;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i <= j; ++i) {
      const double v = 0.7 * plate(mee + i + n * j) + u(rng);
      p(plate.size() + i + n * j) = v;
      p(plate.size() + j + n * i) = v;
    }
  }
  return p;
}

struct Case {
  Case(const Mechanism& m, int modes, unsigned seed, bool spatial = false)
      : body(modes, 1.0, seed),
        problem(m, modes, spatial),
        p(spatial ? withRotationalModalMass(body.invariants(), modes, seed + 7) : body.invariants()),
        ws(problem.createModelWorkspace()),
        s(problem.coordinateCount(), seed + 1, problem.freeCount()) {}
  Vector residual(double t, const Vector& y, const Vector& v, const Vector& a, const Vector& pp) const {
    return residualOf(problem, ws.get(), t, y, v, a, pp);
  }
  SyntheticRod body;
  MechanismProblem problem;
  Vector p;
  std::unique_ptr<ProblemWorkspace> ws;
  State s;
};

/// linearInvariants: check the entries of p that r is linear in (all but b) with unit central differences,
/// exact up to round-off, and b with the small steps: a spatial member's M_ee^xy enters through products
/// with the modal coordinates, small at these states, where a step of 1e-6 leaves the round-off of mu . r
/// near the derivative.
void checkDerivatives(Case& c, const std::vector<double>& times, bool linearInvariants = false) {
  const int f = c.problem.coordinateCount();
  for (double t : times) {
    Matrix ry(f, f), rv(f, f);
    c.problem.residualJacobians(t, c.s.y, c.s.v, c.s.a, c.p, ry, rv, c.ws.get());
    for (int i = 0; i < f; ++i) {
      const auto yCheck =
          checkGradient([&](const Vector& x) { return c.residual(t, x, c.s.v, c.s.a, c.p)(i); }, c.s.y,
                        ry.row(i).transpose(), {1e-6});
      EXPECT_TRUE(yCheck.passed) << "t = " << t << ", row " << i << " of r_y: " << yCheck.message;
      // r is quadratic in y' (z' is linear in it, zeta quadratic), so a large central-difference step is
      // exact and avoids round-off (a step of 1e-2 left 6e-13 of round-off in a component of 2e-6).
      GradientCheckOptions quadratic;
      quadratic.tolerance = 1e-7;
      quadratic.relativeStep = 1e-1;
      const auto vCheck =
          checkGradient([&](const Vector& x) { return c.residual(t, c.s.y, x, c.s.a, c.p)(i); }, c.s.v,
                        rv.row(i).transpose(), quadratic);
      EXPECT_TRUE(vCheck.passed) << "t = " << t << ", row " << i << " of r_v: " << vCheck.message;
    }
    Vector vjp = Vector::Zero(c.p.size());
    c.problem.addResidualParameterVjp(t, c.s.y, c.s.v, c.s.a, c.p, c.s.mu, vjp, c.ws.get());
    auto muR = [&](const Vector& x) { return c.s.mu.dot(c.residual(t, c.s.y, c.s.v, c.s.a, x)); };
    if (!linearInvariants) {
      const auto pCheck = checkGradient(muR, c.p, vjp, {1e-6, 1e-6});
      EXPECT_TRUE(pCheck.passed) << "t = " << t << ": " << pCheck.message;
    } else {
      const int n = c.problem.modeCount(), b = 4 + 4 * n + 3 * n * n;  // b's offset (invariants.h)
      const auto bCheck = checkGradient(
          [&](const Vector& x) {
            Vector full = c.p;
            full.segment(b, n) = x;
            return muR(full);
          },
          c.p.segment(b, n), vjp.segment(b, n), {1e-6, 1e-6});
      EXPECT_TRUE(bCheck.passed) << "t = " << t << ": " << bCheck.message;
      const double largest = vjp.cwiseAbs().maxCoeff(), scale = std::abs(muR(c.p));
      for (Eigen::Index k = 0; k < c.p.size(); ++k) {
        if (k >= b && k < b + n) continue;
        Vector plus = c.p, minus = c.p;
        plus(k) += 1.0;
        minus(k) -= 1.0;
        const double fd = 0.5 * (muR(plus) - muR(minus));
        EXPECT_NEAR(vjp(k), fd, 1e-9 * largest + 1e-13 * scale) << "t = " << t << ", p(" << k << ")";
      }
    }
    // The mass matrix is the acceleration part of the residual, the force minus its rest.
    Matrix mass(f, f);
    Vector force(f);
    c.problem.massMatrixAndForce(t, c.s.y, c.s.v, c.p, mass, force, c.ws.get());
    const Vector r = c.residual(t, c.s.y, c.s.v, c.s.a, c.p);
    EXPECT_LT((mass * c.s.a - force - r).norm(), 1e-11 * r.norm()) << "t = " << t;
    EXPECT_LT((mass - mass.transpose()).norm(), 1e-14 * mass.norm());
  }
}

/// Lagrange's equations of L = T - V in the minimal coordinates, T and V from the nodal masses, by
/// finite differences; z(t, y) and z'(t, y, y') from the model's position and velocity kinematics.
double lagrangeResidual(Case& c, double t) {
  const int f = c.problem.coordinateCount(), nz = c.problem.fullCoordinateCount();
  const NodalEnergy energy{c.body, c.problem};
  auto T = [&](double tt, const Vector& y, const Vector& v) {
    Vector z(nz), zd(nz);
    c.problem.coordinates(tt, y, v, c.p, z, zd, c.ws.get());
    return energy.kinetic(z, zd);
  };
  auto V = [&](double tt, const Vector& y) {
    Vector z(nz), zd(nz);
    c.problem.coordinates(tt, y, Vector::Zero(f), c.p, z, zd, c.ws.get());
    return energy.potential(z);
  };
  auto dTdv = [&](double tt, const Vector& y, const Vector& v) {
    Vector g(f);
    for (int i = 0; i < f; ++i) {
      Vector plus = v, minus = v;
      plus(i) += 1e-3;
      minus(i) -= 1e-3;
      g(i) = (T(tt, y, plus) - T(tt, y, minus)) / 2e-3;
    }
    return g;
  };
  const Vector &y = c.s.y, &v = c.s.v, &a = c.s.a;
  Vector dLdy(f);
  for (int i = 0; i < f; ++i) {
    Vector plus = y, minus = y;
    plus(i) += 1e-6;
    minus(i) -= 1e-6;
    dLdy(i) = (T(t, plus, v) - V(t, plus) - T(t, minus, v) + V(t, minus)) / 2e-6;
  }
  const double d = 1e-4;
  const Vector ddt = (dTdv(t + d, y + d * v + 0.5 * d * d * a, v + d * a) -
                      dTdv(t - d, y - d * v + 0.5 * d * d * a, v - d * a)) /
                     (2 * d);
  const Vector lagrange = ddt - dLdy;
  const Vector r = c.residual(t, y, v, a, c.p);
  return (lagrange - r).norm() / r.norm();
}

TEST(MechanismFourBar, RigidLimitFollowsTheClosedFormKinematics) {
  Case c(fromExample("four_bar.json"), 3, 11);
  const int nz = c.problem.fullCoordinateCount(), o = c.problem.memberOffset();
  const double a = 0.15, L = 1.0, rocker = 0.6, ground = 0.9;
  const DriverLaw law = c.problem.mechanism().drivers[0].law;
  for (double t : {0.0, 0.7, 1.6, 2.3, 2.9}) {
    Vector z(nz), zd(nz);
    const Vector y = Vector::Zero(3), v = Vector::Zero(3);
    c.problem.coordinates(t, y, v, c.p, z, zd, c.ws.get());
    double phi, phiDot, phiDdot;
    law.at(t, phi, phiDot, phiDdot);
    // Circle intersection of |B - A| = L and |B - O4| = rocker, on the upper branch.
    auto closed = [&](double angle, double& beta, double& psi) {
      const Eigen::Vector2d A(a * std::cos(angle), a * std::sin(angle)), O4(ground, 0.0);
      const Eigen::Vector2d e = O4 - A;
      const double dist = e.norm();
      const double along = (L * L - rocker * rocker + dist * dist) / (2 * dist);
      const double across = std::sqrt(L * L - along * along);
      const Eigen::Vector2d B = A + along * e / dist + across * Eigen::Vector2d(-e(1), e(0)) / dist;
      beta = std::atan2(B(1) - A(1), B(0) - A(0));
      psi = std::atan2(B(1) - O4(1), B(0) - O4(0));
    };
    double beta, psi;
    closed(phi, beta, psi);
    const double wrap = 2 * M_PI;
    EXPECT_NEAR(std::remainder(z(o + 2) - beta, wrap), 0.0, 1e-12) << "t = " << t;
    EXPECT_NEAR(std::remainder(z(5) - psi, wrap), 0.0, 1e-12) << "t = " << t;
    // Velocities by central differences of the closed form in the crank angle.
    double bp, pp, bm, pm;
    closed(phi + 1e-6, bp, pp);
    closed(phi - 1e-6, bm, pm);
    EXPECT_NEAR(zd(o + 2), (bp - bm) / 2e-6 * phiDot, 1e-7 * (1.0 + std::abs(phiDot))) << "t = " << t;
    EXPECT_NEAR(zd(5), (pp - pm) / 2e-6 * phiDot, 1e-7 * (1.0 + std::abs(phiDot))) << "t = " << t;
  }
}

// The open chain (examples/mechanisms/flexible_pendulum.json): a driven crank, the member pinned to its
// pin at A, a bob fixed to the member at B; the bob's angle is the free coordinate. In the rigid limit
// (q = 0) the member's chord is the bob's angle and B = A + L (cos theta, sin theta), A on the crank.
TEST(MechanismOpenChain, RigidLimitFollowsTheClosedFormKinematics) {
  Case c(fromExample("flexible_pendulum.json"), 3, 51);
  ASSERT_EQ(c.problem.freeCount(), 1);
  const int nz = c.problem.fullCoordinateCount(), o = c.problem.memberOffset(),
            f = c.problem.coordinateCount();
  const double r = 0.15, L = 1.0;
  const DriverLaw law = c.problem.mechanism().drivers[0].law;
  for (double t : {0.0, 0.4, 1.3, 2.7}) {
    const double theta = -1.2 + 0.9 * t, thetaDot = 0.7 - 0.3 * t;
    Vector y = Vector::Zero(f), v = Vector::Zero(f);
    y(0) = theta;
    v(0) = thetaDot;
    Vector z(nz), zd(nz);
    c.problem.coordinates(t, y, v, c.p, z, zd, c.ws.get());
    double phi, phiDot, phiDdot;
    law.at(t, phi, phiDot, phiDdot);
    const Eigen::Vector2d A(r * std::cos(phi), r * std::sin(phi)),
        Ad(-r * std::sin(phi) * phiDot, r * std::cos(phi) * phiDot);
    const Eigen::Vector2d B = A + L * Eigen::Vector2d(std::cos(theta), std::sin(theta));
    const Eigen::Vector2d Bd = Ad + L * thetaDot * Eigen::Vector2d(-std::sin(theta), std::cos(theta));
    EXPECT_NEAR(std::remainder(z(o + 2) - theta, 2 * M_PI), 0.0, 1e-12) << "t = " << t;
    EXPECT_LT((z.segment<2>(o) - A).norm(), 1e-12) << "t = " << t;
    EXPECT_LT((z.segment<2>(3) - B).norm(), 1e-12) << "t = " << t;  // the bob, the second rigid body
    EXPECT_NEAR(zd(o + 2), thetaDot, 1e-12) << "t = " << t;
    EXPECT_LT((zd.segment<2>(o) - Ad).norm(), 1e-12 * (1.0 + Ad.norm())) << "t = " << t;
    EXPECT_LT((zd.segment<2>(3) - Bd).norm(), 1e-12 * (1.0 + Bd.norm())) << "t = " << t;
  }
}

TEST(MechanismOpenChain, DerivativesMatchFiniteDifferences) {
  Case c(fromExample("flexible_pendulum.json"), 3, 52);
  checkDerivatives(c, {0.5, 2.2});
}

TEST(MechanismFourBar, DerivativesMatchFiniteDifferences) {
  Case c(fromExample("four_bar.json"), 3, 12);
  checkDerivatives(c, {0.6, 2.4});
}

TEST(MechanismFreeSliderCrank, DerivativesMatchFiniteDifferences) {
  Case c(freeSliderCrank(), 3, 13);
  ASSERT_EQ(c.problem.freeCount(), 1);
  checkDerivatives(c, {0.3, 1.1});
}

TEST(MechanismFourBar, ResidualSatisfiesLagrangesEquationsOfTheNodalEnergies) {
  Case c(fromExample("four_bar.json"), 3, 14);
  for (double t : {0.5, 2.5}) {
    const double relative = lagrangeResidual(c, t);
    std::cout << "[ Lagrange four-bar ] t = " << t << ": relative residual " << relative << "\n";
    EXPECT_LT(relative, 1e-5) << "t = " << t;
  }
}

TEST(MechanismFreeSliderCrank, ResidualSatisfiesLagrangesEquationsOfTheNodalEnergies) {
  Mechanism m = freeSliderCrank();
  m.springs[0].damping = 0.0;  // Lagrange's equations of T - V (a damper is not in V)
  Case c(m, 3, 15);
  for (double t : {0.4, 1.9}) {
    const double relative = lagrangeResidual(c, t);
    std::cout << "[ Lagrange free slider-crank ] t = " << t << ": relative residual " << relative << "\n";
    EXPECT_LT(relative, 1e-5) << "t = " << t;
  }
}

TEST(MechanismOpenChain, ResidualSatisfiesLagrangesEquationsOfTheNodalEnergies) {
  Case c(fromExample("flexible_pendulum.json"), 3, 53);
  for (double t : {0.6, 2.1}) {
    const double relative = lagrangeResidual(c, t);
    std::cout << "[ Lagrange open chain ] t = " << t << ": relative residual " << relative << "\n";
    EXPECT_LT(relative, 1e-5) << "t = " << t;
  }
}

/// Driver work = change of kinetic + potential energy + dissipated energy along an rk4 trajectory
/// (trapezoidal rule on the powers).
void checkEnergyBalance(Case& c, double t1, double tolerance) {
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = t1;
  options.step = 2.5e-4;
  const int f = c.problem.coordinateCount();
  std::vector<std::pair<double, Vector>> states;
  simulate(c.problem, c.p, options,
           [&](std::int64_t, double t, ConstVectorRef z) { states.emplace_back(t, z); });
  double work = 0.0, dissipated = 0.0, e0 = 0.0, e1 = 0.0, previousPower = 0.0, previousLoss = 0.0,
         scale = 0.0;
  Matrix mass(f, f);
  Vector force(f);
  for (std::size_t k = 0; k < states.size(); ++k) {
    const double t = states[k].first;
    const Vector y = states[k].second.head(f), v = states[k].second.tail(f);
    c.problem.massMatrixAndForce(t, y, v, c.p, mass, force, c.ws.get());
    const Vector a = mass.llt().solve(force);
    const auto e = c.problem.energies(t, y, v, a, c.p, c.ws.get());
    if (k == 0) e0 = e.kinetic + e.potential;
    e1 = e.kinetic + e.potential;
    scale = std::max(scale, e.kinetic);
    if (k > 0) {
      const double h = t - states[k - 1].first;
      work += 0.5 * h * (previousPower + e.drivePower);
      dissipated += 0.5 * h * (previousLoss + e.dissipation);
    }
    previousPower = e.drivePower;
    previousLoss = e.dissipation;
  }
  std::cout << "[ energy ] work " << work << ", dE " << e1 - e0 << ", dissipated " << dissipated << "\n";
  EXPECT_GT(scale, 0.0);
  EXPECT_NEAR(work, e1 - e0 + dissipated, tolerance * scale);
}

TEST(MechanismFourBar, DriverWorkEqualsTheEnergyChange) {
  Case c(fromExample("four_bar.json"), 3, 16);
  checkEnergyBalance(c, 1.0, 1e-5);
}

TEST(MechanismSliderCrankMass, DriverWorkEqualsTheEnergyChange) {
  Case c(fromExample("slider_crank_mass.json"), 3, 17);
  checkEnergyBalance(c, 1.0, 1e-5);
}

TEST(MechanismOpenChain, DriverWorkEqualsTheEnergyChange) {
  Case c(fromExample("flexible_pendulum.json"), 3, 54);
  checkEnergyBalance(c, 1.5, 1e-5);
}

TEST(MechanismFreeSliderCrank, EnergyIsConservedUpToTheDamping) {
  Case c(freeSliderCrank(), 3, 18);
  checkEnergyBalance(c, 0.5, 1e-5);
}

}  // namespace
}  // namespace hindsight::mechanism

namespace hindsight::mechanism {
namespace {

/// The chord path (production) against the reference path in full coordinates: the residual, the
/// mass matrix and force by projection, the Jacobians and the b part of the parameter product by dual
/// numbers in all directions.
void checkAgainstReference(Case& c, const std::vector<double>& times) {
  const int f = c.problem.coordinateCount();
  auto reference = c.problem.createModelWorkspace();
  for (double t : times) {
    Vector r(f), rr(f);
    c.problem.residual(t, c.s.y, c.s.v, c.s.a, c.p, r, c.ws.get());
    c.problem.residualByProjection(t, c.s.y, c.s.v, c.s.a, c.p, rr, reference.get());
    EXPECT_LT((r - rr).norm(), 1e-13 * rr.norm()) << "t = " << t;
    Matrix mass(f, f), massReference(f, f);
    Vector force(f), forceReference(f);
    c.problem.massMatrixAndForce(t, c.s.y, c.s.v, c.p, mass, force, c.ws.get());
    c.problem.massMatrixAndForceByProjection(t, c.s.y, c.s.v, c.p, massReference, forceReference,
                                             reference.get());
    EXPECT_LT((mass - massReference).norm(), 1e-13 * massReference.norm()) << "t = " << t;
    EXPECT_LT((force - forceReference).norm(), 1e-13 * forceReference.norm()) << "t = " << t;
    Matrix ry(f, f), rv(f, f), ryReference(f, f), rvReference(f, f);
    c.problem.residualJacobians(t, c.s.y, c.s.v, c.s.a, c.p, ry, rv, c.ws.get());
    c.problem.residualJacobiansByAutoDiff(t, c.s.y, c.s.v, c.s.a, c.p, ryReference, rvReference,
                                          reference.get());
    for (int i = 0; i < f; ++i) {
      EXPECT_LT((ry.row(i) - ryReference.row(i)).norm(), 1e-12 * ryReference.norm())
          << "t = " << t << " row " << i;
      EXPECT_LT((rv.row(i) - rvReference.row(i)).norm(), 1e-12 * rvReference.norm())
          << "t = " << t << " row " << i;
    }
    Vector g = Vector::Zero(c.p.size()), gReference = Vector::Zero(c.p.size());
    c.problem.addResidualParameterVjp(t, c.s.y, c.s.v, c.s.a, c.p, c.s.mu, g, c.ws.get());
    c.problem.addResidualParameterVjpByAutoDiff(t, c.s.y, c.s.v, c.s.a, c.p, c.s.mu, gReference,
                                                reference.get());
    EXPECT_LT((g - gReference).norm(), 1e-13 * gReference.norm()) << "t = " << t;
    // The state products without the Jacobians (the transposed chord path) against the reference's
    // Jacobians transposed, entry by entry: a missing or wrong term of a row shows in its column.
    ASSERT_TRUE(c.problem.hasResidualStateVjp());
    Vector outY(f), outV(f);
    c.problem.residualStateVjp(t, c.s.y, c.s.v, c.s.a, c.p, c.s.mu, outY, outV, c.ws.get());
    const Vector outYReference = ryReference.transpose() * c.s.mu;
    const Vector outVReference = rvReference.transpose() * c.s.mu;
    // Each entry's scale: the sum of the magnitudes of its terms.
    const Vector yScale = ryReference.cwiseAbs().transpose() * c.s.mu.cwiseAbs();
    const Vector vScale = rvReference.cwiseAbs().transpose() * c.s.mu.cwiseAbs();
    for (int j = 0; j < f; ++j) {
      EXPECT_LE(std::abs(outY(j) - outYReference(j)), 1e-12 * yScale(j)) << "t = " << t << " column " << j;
      EXPECT_LE(std::abs(outV(j) - outVReference(j)), 1e-12 * vScale(j)) << "t = " << t << " column " << j;
    }
    // Both products at once (an explicit adjoint stage) equal the two taken one by one, bit for bit.
    Vector bothY(f), bothV(f), bothG = Vector::Zero(c.p.size());
    c.problem.residualVjps(t, c.s.y, c.s.v, c.s.a, c.p, c.s.mu, bothY, bothV, bothG, c.ws.get());
    EXPECT_TRUE(bothY == outY && bothV == outV) << "t = " << t;
    EXPECT_TRUE(bothG == g) << "t = " << t;
  }
}

TEST(MechanismChordPath, FourBarEqualsTheFullCoordinateReference) {
  Case c(fromExample("four_bar.json"), 4, 21);
  checkAgainstReference(c, {0.3, 1.2, 2.4});
}

TEST(MechanismChordPath, FreeSliderCrankEqualsTheFullCoordinateReference) {
  Case c(freeSliderCrank(), 4, 22);
  checkAgainstReference(c, {0.3, 1.1});
}

TEST(MechanismChordPath, SliderCrankMassEqualsTheFullCoordinateReference) {
  Case c(fromExample("slider_crank_mass.json"), 5, 23);
  checkAgainstReference(c, {0.5, 2.5});
}

// A spatial member (the solid, problems/rod/solid_member.h): M_ee^xy in J_w and the centrifugal terms, M_ee
// in the modal mass. The chord path against the full-coordinate reference and every derivative against
// finite differences, on a mechanism with a closed loop and one with a free coordinate.
TEST(MechanismSpatialMember, FourBarEqualsTheReferenceAndItsDerivativesTheFiniteDifferences) {
  Case c(fromExample("four_bar.json"), 4, 31, true);
  ASSERT_EQ(c.p.size(), 4 + 5 * 4 + 4 * 4 * 4);
  ASSERT_EQ(c.problem.parameterSize(), c.p.size());
  checkAgainstReference(c, {0.3, 1.2});
  checkDerivatives(c, {0.6, 2.4}, true);
}

TEST(MechanismSpatialMember, FreeSliderCrankEqualsTheReferenceAndItsDerivativesTheFiniteDifferences) {
  Case c(freeSliderCrank(), 3, 32, true);
  checkAgainstReference(c, {0.3, 1.1});
  checkDerivatives(c, {0.3, 1.1}, true);
}

// A spatial member whose M_ee^xy equals M_ee is the plate (the same residual to round-off), and one whose
// M_ee^xy differs has another residual, by far more than round-off: the block is read (through J_w and
// h, products with the modal coordinates, which are small at these states).
TEST(MechanismSpatialMember, WithTheRotationalModalMassEqualToTheModalMassItIsThePlate) {
  const Mechanism m = fromExample("four_bar.json");
  Case plate(m, 4, 33);
  Case spatial(m, 4, 33, true);
  const int n = 4, mee = 4 + 4 * n + n * n;
  Vector same = spatial.p;
  same.tail(n * n) = plate.p.segment(mee, n * n);
  for (double t : {0.4, 1.9}) {
    const Vector r = plate.residual(t, plate.s.y, plate.s.v, plate.s.a, plate.p);
    const Vector rs = spatial.residual(t, plate.s.y, plate.s.v, plate.s.a, same);
    EXPECT_LT((r - rs).norm(), 1e-14 * r.norm()) << "t = " << t;
    const Vector rd = spatial.residual(t, plate.s.y, plate.s.v, plate.s.a, spatial.p);
    EXPECT_GT((r - rd).norm(), 1e-10 * r.norm()) << "t = " << t;
  }
}

TEST(MechanismChordPath, OpenChainEqualsTheFullCoordinateReference) {
  Case c(fromExample("flexible_pendulum.json"), 4, 24);
  checkAgainstReference(c, {0.4, 1.7});
}

TEST(MechanismChordPath, StepsAndAdjointStepsAllocateNothing) {
  // Newton's buffers, the dual numbers (fixed capacity) and the kept kinematics live in the workspace.
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  for (const Mechanism& m :
       {fromExample("four_bar.json"), freeSliderCrank(), fromExample("flexible_pendulum.json")}) {
    const SyntheticRod body(4, 1.0, 31);
    const MechanismProblem problem(m, 4);
    const Vector p = body.invariants();
    for (const char* method : {"rk4", "generalized-alpha"}) {
      IntegratorOptions options;
      options.method = method;
      const std::unique_ptr<Integrator> integrator = createIntegrator(problem, p, options);
      const int size = integrator->stateSize();
      Vector z(size), zStart(size), lambda = Vector::Ones(size), gradient = Vector::Zero(p.size());
      integrator->initialState(0.0, z);
      integrator->step(0.0, 1e-3, z, nullptr);
      zStart = z;
      long forward = 0, adjoint = 0;
      {
        testing::AllocationCounter counter;
        for (int i = 0; i < 10; ++i) integrator->step(1e-3 * (i + 1), 1e-3, z, nullptr);
        forward = counter.count();
      }
      {
        testing::AllocationCounter counter;
        for (int i = 0; i < 10; ++i) integrator->adjointStep(1e-3 * (i + 1), 1e-3, zStart, lambda, gradient);
        adjoint = counter.count();
      }
      EXPECT_EQ(forward, 0) << method << ", " << problem.freeCount() << " free";
      EXPECT_EQ(adjoint, 0) << method << ", " << problem.freeCount() << " free";
    }
  }
}

TEST(MechanismChordPath, RecomputationGivesTheSameBits) {
  // The positions are a function of (t, sigma) (rounded and polished Newton) and a workspace reuses the
  // kinematics of its last point only when the point is bitwise the same: a gradient whose forward
  // states are recomputed from checkpoints (other warm starts, other call orders) has the same bits as
  // one that stored them all.
  for (const Mechanism& m : {fromExample("slider_crank.json"), fromExample("four_bar.json"),
                             freeSliderCrank(), fromExample("flexible_pendulum.json")}) {
    const SyntheticRod body(3, 1.0, 41);
    const MechanismProblem problem(m, 3);
    const Vector p = body.invariants();
    // Generalized-alpha asks for the mass matrix and the Jacobians together; RK4 for the force at its
    // stages and, in the backward sweep, for the Jacobians at stored and recomputed stage states.
    for (const char* method : {"generalized-alpha", "rk4"}) {
      IntegratorOptions options;
      options.method = method;
      options.t1 = std::string(method) == "rk4" ? 0.05 : 0.4;
      options.step = std::string(method) == "rk4" ? 2e-4 : 2e-3;
      FullStorage full;
      BinomialCheckpointing binomial(6);
      const GradientResult a = computeGradient(problem, p, options, full);
      const GradientResult b = computeGradient(problem, p, options, binomial);
      EXPECT_GT(b.summary.recomputedSteps, 0);
      EXPECT_EQ(a.objective, b.objective) << method;
      EXPECT_TRUE(a.gradient == b.gradient)
          << method << ": largest difference " << (a.gradient - b.gradient).cwiseAbs().maxCoeff();
    }
  }
}

}  // namespace
}  // namespace hindsight::mechanism

namespace hindsight::mechanism {
namespace {

// ---- The block-triangular order of the position constraints (problems/mechanism/mechanism_problem.h). ----

std::string describe(const std::vector<MechanismProblem::ConstraintBlock>& blocks) {
  std::string s;
  for (const auto& b : blocks) {
    s += "[";
    for (std::size_t i = 0; i < b.equations.size(); ++i)
      s += (i ? ", " : "") + b.equations[i] + " -> " + b.unknowns[i];
    s += b.affine ? "] affine" : "]";
    s += b.timeOnly ? " time\n" : "\n";
  }
  return s;
}

TEST(MechanismBlocks, TheExamplesSolveOneEquationAtATimeExceptTheFourBarsLoop) {
  // The slider-crank: the crank's angle from its driver, the crank pin, the member's A, the slider's y
  // from its guide, the closure (the only equation that is not affine in its unknown: the member's
  // angle from the wrist pin's y), the slider's x, the slider's angle. The four-bar's loop couples the
  // coupler's and the rocker's angles and the rocker's position: one 4 x 4 block. "time": the block's
  // unknowns depend on time alone (the driven crank, the member's A, the guided slider's y and angle);
  // only the member's angle and what follows from it move with the modal coordinates (through c).
  const std::string sliderCrank =
      "[bearing.x -> crank.x] affine time\n"
      "[bearing.y -> crank.y] affine time\n"
      "[motor -> crank.angle] affine time\n"
      "[crankPin.x -> rod.x] affine time\n"
      "[crankPin.y -> rod.y] affine time\n"
      "[guide.line -> slider.y] affine time\n"
      "[wristPin.y -> rod.angle]\n"
      "[wristPin.x -> slider.x] affine\n"
      "[guide.angle -> slider.angle] affine time\n";
  EXPECT_EQ(describe(MechanismProblem(fromExample("slider_crank.json"), 3).constraintBlocks()), sliderCrank);
  EXPECT_EQ(describe(MechanismProblem(fromExample("slider_crank_mass.json"), 3).constraintBlocks()),
            sliderCrank);
  EXPECT_EQ(describe(MechanismProblem(fromExample("four_bar.json"), 3).constraintBlocks()),
            "[crankBearing.x -> crank.x] affine time\n"
            "[crankBearing.y -> crank.y] affine time\n"
            "[motor -> crank.angle] affine time\n"
            "[crankPin.x -> coupler.x] affine time\n"
            "[crankPin.y -> coupler.y] affine time\n"
            "[rockerPin.x -> coupler.angle, rockerPin.y -> rocker.angle, rockerBearing.x -> rocker.x, "
            "rockerBearing.y -> rocker.y]\n");
  // The open chain needs no Newton at all: the member's angle follows from the bob's (the free
  // coordinate) through the fixed joint, the bob's position from the member's B.
  EXPECT_EQ(describe(MechanismProblem(fromExample("flexible_pendulum.json"), 3).constraintBlocks()),
            "[bearing.x -> crank.x] affine time\n"
            "[bearing.y -> crank.y] affine time\n"
            "[motor -> crank.angle] affine time\n"
            "[crankPin.x -> rod.x] affine time\n"
            "[crankPin.y -> rod.y] affine time\n"
            "[bobMount.angle -> rod.angle] affine\n"
            "[bobMount.x -> bob.x] affine\n"
            "[bobMount.y -> bob.y] affine\n");
  // A guide that is not along a coordinate axis couples the slider's x and y with the member's angle.
  Mechanism oblique = fromExample("slider_crank.json");
  oblique.joints[3].axis = Vec2(1.0, 0.1);
  const auto blocks = MechanismProblem(oblique, 3).constraintBlocks();
  ASSERT_EQ(blocks.size(), 7u) << describe(blocks);
  EXPECT_EQ(blocks[5].unknowns.size(), 3u) << describe(blocks);
  EXPECT_FALSE(blocks[5].affine);
}

/// The examples, a free crank with a spring, and the slider-crank on an oblique guide.
std::vector<Mechanism> blockCases() {
  Mechanism oblique = fromExample("slider_crank.json");
  oblique.joints[3].axis = Vec2(1.0, 0.1);
  // Assemblable on the oblique guide: the slider starts on it.
  oblique.rigidBodies[1].position = Vec2(1.15, 0.115);
  return {fromExample("slider_crank.json"),
          fromExample("slider_crank_mass.json"),
          fromExample("four_bar.json"),
          fromExample("flexible_pendulum.json"),
          freeSliderCrank(),
          oblique};
}

TEST(MechanismBlocks, ThePatternIsTheJacobiansAndBlockTriangular) {
  // The structural pattern read off the rows' formulas holds every nonzero of Phi_u (a missing entry
  // would make the block solves wrong) and no entry that is zero at a generic point (a padded pattern
  // would merge blocks); Phi_u in the block order has nothing above its diagonal blocks.
  for (const Mechanism& m : blockCases()) {
    Case c(m, 3, 61);
    const Eigen::MatrixXi pattern = c.problem.constraintPattern();
    const int nm = static_cast<int>(pattern.rows());
    const auto blocks = c.problem.constraintBlocks();
    for (double t : {0.37, 1.3, 2.6}) {
      Matrix phiU(nm, nm);
      c.problem.constraintJacobian(t, c.s.y, c.p, phiU, c.ws.get());
      for (int i = 0; i < nm; ++i) {
        for (int j = 0; j < nm; ++j) {
          EXPECT_EQ(phiU(i, j) != 0.0, pattern(i, j) == 1)
              << "t = " << t << " (" << i << ", " << j << ") = " << phiU(i, j) << "\n"
              << describe(blocks);
        }
      }
      std::vector<int> later;
      for (auto b = blocks.rbegin(); b != blocks.rend(); ++b) {
        for (int i : b->rows) {
          for (int j : later) EXPECT_EQ(phiU(i, j), 0.0) << "t = " << t << " (" << i << ", " << j << ")";
        }
        later.insert(later.end(), b->columns.begin(), b->columns.end());
      }
    }
  }
}

TEST(MechanismBlocks, BlockSolveEqualsDenseNewtonOnAllConstraints) {
  for (const Mechanism& m : blockCases()) {
    Case c(m, 3, 62);
    const int nz = c.problem.fullCoordinateCount() - c.problem.modeCount() + 1;
    for (double t : {0.0, 0.37, 1.3, 2.6, 2.95}) {
      Vector z(nz), zDense(nz);
      c.problem.positionsBlockAndDense(t, c.s.y, c.p, z, zDense, c.ws.get());
      EXPECT_LT((z - zDense).cwiseAbs().maxCoeff(), 4e-16 * z.cwiseAbs().maxCoeff()) << "t = " << t << "\n"
                                                                                     << z.transpose() << "\n"
                                                                                     << zDense.transpose();
    }
  }
}

TEST(MechanismBlocks, AnUnconstrainedBodyIsRefusedAsSingular) {
  // A body that no joint holds, with the count of constraints made up by a redundant fixed joint: no
  // equation can fix its coordinates.
  Mechanism m = fromExample("slider_crank.json");
  RigidBody loose;
  loose.name = "loose";
  loose.mass = 1.0;
  loose.points = {{"c", Vec2::Zero()}};
  m.addRigidBody(loose);
  m.addFixed("weld", "crank", "O", "slider", "center");
  try {
    const MechanismProblem problem(m, 3);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("singular"), std::string::npos) << e.what();
  }
}

TEST(MechanismChordPath, WhatDependsOnTimeAloneIsKeptWithTheSameBits) {
  // A workspace keeps the blocks and rows that depend on time alone for the last time it evaluated
  // (a step's predictor and Newton iterates share it). Taken from there or computed anew, they give the
  // same bits: a workspace that has seen other points at this time and at another one answers as a
  // fresh one does, for every quantity the integrators ask for.
  for (const Mechanism& m : blockCases()) {
    Case c(m, 3, 73);
    const int f = c.problem.coordinateCount();
    const double t0 = 0.21, t1 = 0.37;
    const Vector y2 = c.s.y + 0.003 * Vector::Ones(f), v2 = c.s.v - 0.2 * Vector::Ones(f);
    auto answers = [&](ProblemWorkspace* ws) {
      Matrix mass(f, f), ry(f, f), rv(f, f);
      Vector force(f), gradient = Vector::Zero(c.p.size());
      c.problem.massMatrix(t1, y2, c.p, mass, ws);
      c.problem.residualJacobians(t1, y2, v2, c.s.a, c.p, ry, rv, ws);
      c.problem.force(t1, y2, v2, c.p, force, ws);
      c.problem.addResidualParameterVjp(t1, y2, v2, c.s.a, c.p, c.s.mu, gradient, ws);
      return std::make_tuple(mass, ry, rv, force, gradient);
    };
    const auto fresh = answers(c.problem.createModelWorkspace().get());
    // Histories: other positions at both times; and new velocities at the same positions first (the
    // velocity level alone taken from the kept rows).
    for (int history = 0; history < 2; ++history) {
      const auto seen = c.problem.createModelWorkspace();
      Matrix mass(f, f);
      Vector force(f);
      if (history == 0) {
        c.problem.massMatrixAndForce(t0, c.s.y, c.s.v, c.p, mass, force, seen.get());
        c.problem.massMatrixAndForce(t1, c.s.y, c.s.v, c.p, mass, force, seen.get());
      } else {
        c.problem.massMatrixAndForce(t1, y2, c.s.v, c.p, mass, force, seen.get());
      }
      const auto kept = answers(seen.get());
      EXPECT_TRUE(std::get<0>(kept) == std::get<0>(fresh)) << "mass matrix, history " << history;
      EXPECT_TRUE(std::get<1>(kept) == std::get<1>(fresh)) << "r_y, history " << history;
      EXPECT_TRUE(std::get<2>(kept) == std::get<2>(fresh)) << "r_y', history " << history;
      EXPECT_TRUE(std::get<3>(kept) == std::get<3>(fresh)) << "force, history " << history;
      EXPECT_TRUE(std::get<4>(kept) == std::get<4>(fresh)) << "parameter product, history " << history;
    }
  }
}

}  // namespace
}  // namespace hindsight::mechanism
