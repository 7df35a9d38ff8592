// The full-order rod of docs/design.md §9: the frame kinematics, every derivative against finite
// differences (F_z, F_p, G_z, G_p with and without the coupling terms), the Newton solver and its
// transpose against the defining residual with the exact Jacobian, no allocation in the hot path,
// the discrete-adjoint dpsi/dx against finite differences of the computed psi for every element
// (rk4 and trbdf2), a modal-superposition check with the coupling dropped, and psi1,full against the
// reduced psi1 of PistonRod.
#include <hindsight/problems/app/full_order_evaluation.h>
#include <hindsight/problems/rod/full_order_rod.h>

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/engine/runge_kutta.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/rod/modal_reduction.h>
#include <hindsight/storage/storage_factory.h>
#include "support/allocation_counting.h"
#include "support/random_design.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <random>

namespace hindsight::rod {
namespace {

using testing::randomVector;

RodConfig coarseRod(int nx = 10, int ny = 2) {
  RodConfig config;
  config.elementsAlongLength = nx;
  config.elementsThroughHeight = ny;
  return config;
}

// A short ramp so that the frame rates and the coupling terms are large within a few milliseconds.
CrankMotion fastCrank() { return CrankMotion{0.15, 10.0 * M_PI, 0.05}; }

// A design with entries on both sides of the density-law kink at 0.1, off the kink by more than any
// finite-difference step.
Vector testDesign(const RodConfig& config, unsigned seed) {
  std::mt19937 generator(seed);
  Vector x = randomVector(config.designCount(), generator, 0.02, 1.0);
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (std::abs(x(i) - 0.1) < 1e-3) x(i) += 5e-3;
  }
  return x;
}

// A time inside the ramp, where beta', beta'' and R^T r_A'' are all non-zero.
constexpr double kTestTime = 0.031;

TEST(RigidFrameMotion, RatesAreTheDerivativesOfTheAngleAndTheClosureHolds) {
  const CrankMotion crank = fastCrank();
  const double length = 1.0;
  for (double t : {0.013, 0.031, 0.2, 1.3}) {
    const double h = 1e-5;
    const RigidFrameMotion m = rigidFrameMotion(crank, length, t);
    const RigidFrameMotion plus = rigidFrameMotion(crank, length, t + h);
    const RigidFrameMotion minus = rigidFrameMotion(crank, length, t - h);
    double phi, phiDot, phiDdot;
    crank.at(t, phi, phiDot, phiDdot);
    EXPECT_NEAR(crank.radius * std::sin(phi) + length * std::sin(m.angle), 0.0, 1e-15);
    EXPECT_NEAR(m.rate, (plus.angle - minus.angle) / (2 * h), 1e-6 * std::max(1.0, std::abs(m.rate)));
    EXPECT_NEAR(m.acceleration, (plus.rate - minus.rate) / (2 * h),
                1e-5 * std::max(1.0, std::abs(m.acceleration)));
    // R^T r_A'' from finite differences of r_A in the inertial frame.
    auto pin = [&](double s) {
      double a, b, c;
      crank.at(s, a, b, c);
      return Eigen::Vector2d(crank.radius * std::cos(a), crank.radius * std::sin(a));
    };
    const Eigen::Vector2d acc = (pin(t + 1e-4) - 2 * pin(t) + pin(t - 1e-4)) / 1e-8;
    const double cb = std::cos(m.angle), sb = std::sin(m.angle);
    const double scale = std::max(1.0, acc.norm());
    EXPECT_NEAR(m.pinAccelerationX, cb * acc.x() + sb * acc.y(), 1e-5 * scale);
    EXPECT_NEAR(m.pinAccelerationY, -sb * acc.x() + cb * acc.y(), 1e-5 * scale);
  }
}

TEST(FullOrderRod, RotatedMassIsSkewAndSizesMatchTheFreeDofs) {
  const RodConfig config = coarseRod();
  const FullOrderRodProblem problem(config, testDesign(config, 3), fastCrank(), true);
  EXPECT_EQ(problem.freeDofCount(), 2 * 11 * 3 - 3);
  EXPECT_EQ(problem.stateSize(), 2 * problem.freeDofCount());
  EXPECT_EQ(problem.parameterSize(), config.designCount());
  const Matrix ms = Matrix(problem.rotatedMass());
  EXPECT_GT(ms.norm(), 0.0);
  EXPECT_LT((ms + ms.transpose()).norm(), 1e-14 * ms.norm());  // skew: M_S^T = -M_S
}

TEST(FullOrderRod, RejectsParametersThatAreNotItsDesign) {
  const RodConfig config = coarseRod();
  const Vector x = testDesign(config, 3);
  const FullOrderRodProblem problem(config, x, fastCrank(), true);
  Vector z0(problem.stateSize());
  EXPECT_NO_THROW(problem.initialState(x, z0));
  EXPECT_THROW(problem.initialState(Vector(x.array() + 0.001), z0), std::invalid_argument);
}

// The right-hand side satisfies the second-order equations assembled independently (dense).
TEST(FullOrderRod, RhsSatisfiesTheEquationsOfMotion) {
  const RodConfig config = coarseRod();
  const Vector x = testDesign(config, 5);
  const FullOrderRodProblem problem(config, x, fastCrank(), true);
  const FeModel& model = problem.model();
  const int n = problem.freeDofCount();
  std::mt19937 generator(9);
  const Vector z = randomVector(2 * n, generator, -1e-4, 1e-4);
  auto ws = problem.createWorkspace();
  Vector f(2 * n);
  problem.rhs(kTestTime, z, x, f, ws.get());
  EXPECT_EQ((f.head(n) - z.tail(n)).norm(), 0.0);
  // M u'' + 2 b' M_S u' + (K - b'^2 M + b'' M_S) u = -P^T M_full a_full, with M_S and a_full built here
  // from rotateNodewise on full vectors.
  const RigidFrameMotion m = rigidFrameMotion(fastCrank(), config.length, kTestTime);
  const Matrix massFull = Matrix(model.massFull());
  const Vector X = model.referenceCoordinates();
  const Vector aFull = m.pinAccelerationX * model.unitTranslationX() +
                       m.pinAccelerationY * model.unitTranslationY() + m.acceleration * rotateNodewise(X) -
                       m.rate * m.rate * X;
  auto msTimes = [&](const Vector& free) {
    return model.restrictToFree(massFull * rotateNodewise(model.extendToFull(free)));
  };
  const Vector u = z.head(n), v = z.tail(n);
  const Vector residual = Matrix(model.mass()) * f.tail(n) + 2 * m.rate * msTimes(v) +
                          Matrix(model.stiffness()) * u - m.rate * m.rate * (Matrix(model.mass()) * u) +
                          m.acceleration * msTimes(u) + model.restrictToFree(massFull * aFull);
  const double scale = (Matrix(model.stiffness()) * u).norm() + model.restrictToFree(massFull * aFull).norm();
  EXPECT_LT(residual.norm(), 1e-12 * scale);
  Vector load(n);
  problem.inertialLoad(kTestTime, load);
  EXPECT_LT((load - model.restrictToFree(massFull * aFull)).norm(), 1e-13 * load.norm());
}

class FullOrderDerivatives : public ::testing::TestWithParam<bool> {
 protected:
  RodConfig config = coarseRod();
  Vector x = testDesign(config, 7);
  FullOrderRodProblem problem{config, x, fastCrank(), GetParam()};
  int n = problem.freeDofCount();
  std::mt19937 generator{21};
  Vector z = randomVector(2 * n, generator, -1e-4, 1e-4);
  Vector w = randomVector(2 * n, generator);
};

TEST_P(FullOrderDerivatives, StateProductMatchesFiniteDifferences) {
  auto ws = problem.createWorkspace();
  Vector analytic(2 * n);
  problem.rhsStateVjp(kTestTime, z, x, w, analytic, ws.get());
  Vector f(2 * n);
  const auto result = checkGradient(
      [&](const Vector& y) {
        problem.rhs(kTestTime, y, x, f, ws.get());
        return w.dot(f);
      },
      z, analytic, {1e-6, 1e-3, {}, 0.0});
  EXPECT_TRUE(result.passed) << result.message;
}

TEST_P(FullOrderDerivatives, ParameterProductMatchesFiniteDifferences) {
  auto ws = problem.createWorkspace();
  Vector analytic = Vector::Zero(x.size());
  problem.addRhsParameterVjp(kTestTime, z, x, w, analytic, ws.get());
  const auto result = checkGradient(
      [&](const Vector& y) {
        const FullOrderRodProblem other(config, y, fastCrank(), GetParam());
        auto otherWs = other.createWorkspace();
        Vector f(2 * n);
        other.rhs(kTestTime, z, y, f, otherWs.get());
        return w.dot(f);
      },
      x, analytic, {1e-6, 1e-3, {}, 0.0});
  EXPECT_TRUE(result.passed) << result.message;
  EXPECT_GT(analytic.cwiseAbs().minCoeff(), 0.0);
}

TEST_P(FullOrderDerivatives, IntegrandGradientsMatchFiniteDifferences) {
  auto ws = problem.createWorkspace();
  Vector gz = Vector::Zero(2 * n);
  problem.addIntegrandStateGradient(kTestTime, z, x, 1.0, gz, ws.get());
  auto byState = checkGradient([&](const Vector& y) { return problem.integrand(kTestTime, y, x, ws.get()); },
                               z, gz, {1e-6, 1e-3, {}, 0.0});
  EXPECT_TRUE(byState.passed) << byState.message;
  EXPECT_EQ(gz.tail(n).norm(), 0.0);
  Vector gp = Vector::Zero(x.size());
  problem.addIntegrandParameterGradient(kTestTime, z, x, 1.0, gp, ws.get());
  auto byDesign = checkGradient(
      [&](const Vector& y) {
        const FullOrderRodProblem other(config, y, fastCrank(), GetParam());
        auto otherWs = other.createWorkspace();
        return other.integrand(kTestTime, z, y, otherWs.get());
      },
      x, gp, {1e-6, 1e-3, {}, 0.0});
  EXPECT_TRUE(byDesign.passed) << byDesign.message;
}

// F is affine in z, so F_z d = F(t, d) - F(t, 0) exactly; the dense Jacobian built that way checks
// the Newton solver (I - alpha F_z) and its transpose by their defining residuals.
TEST_P(FullOrderDerivatives, NewtonSolverAndItsTransposeSolveTheExactNewtonMatrix) {
  auto ws = problem.createWorkspace();
  const int size = 2 * n;
  Matrix jacobian(size, size);
  Vector f0(size), f(size);
  problem.rhs(kTestTime, Vector::Zero(size), x, f0, ws.get());
  for (int j = 0; j < size; ++j) {
    problem.rhs(kTestTime, Vector::Unit(size, j), x, f, ws.get());
    jacobian.col(j) = f - f0;
  }
  // The Jacobian also agrees with the state product.
  Vector product(size);
  problem.rhsStateVjp(kTestTime, z, x, w, product, ws.get());
  EXPECT_LT((jacobian.transpose() * w - product).norm(), 1e-9 * product.norm());

  auto solver = problem.createNewtonSolver();
  for (double alpha : {1e-4, 1e-3}) {
    solver->factorize(kTestTime, z, x, alpha, ws.get());
    const Matrix newton = Matrix::Identity(size, size) - alpha * jacobian;
    Vector b = randomVector(size, generator);
    Vector solution = b;
    solver->solve(solution);
    // Backward errors: I - alpha F_z carries alpha omega_max^2 ~ 1e8, so the residual is judged against
    // ||N|| ||x|| (round-off level ~1e-16; a wrong term gives O(1)).
    const double norm = newton.lpNorm<Eigen::Infinity>();
    EXPECT_LT((newton * solution - b).lpNorm<Eigen::Infinity>(),
              1e-13 * (norm * solution.lpNorm<Eigen::Infinity>() + b.lpNorm<Eigen::Infinity>()))
        << "alpha " << alpha;
    Vector transposed = b;
    solver->solveTransposed(transposed);
    const double normT = newton.transpose().lpNorm<Eigen::Infinity>();
    EXPECT_LT((newton.transpose() * transposed - b).lpNorm<Eigen::Infinity>(),
              1e-13 * (normT * transposed.lpNorm<Eigen::Infinity>() + b.lpNorm<Eigen::Infinity>()))
        << "alpha " << alpha;
    if (GetParam()) EXPECT_GT((transposed - solution).norm(), 1e-6 * solution.norm());  // not symmetric
  }
}

TEST_P(FullOrderDerivatives, HotPathAllocatesNothing) {
  if (!testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counting unavailable";
  auto ws = problem.createWorkspace();
  auto solver = problem.createNewtonSolver();
  Vector f(2 * n), out(2 * n), gp = Vector::Zero(x.size()), b = w;
  solver->factorize(kTestTime, z, x, 1e-3, ws.get());  // first factorisation with this alpha allocates
  testing::AllocationCounter counter;
  problem.rhs(kTestTime, z, x, f, ws.get());
  problem.rhsStateVjp(kTestTime, z, x, w, out, ws.get());
  problem.addRhsParameterVjp(kTestTime, z, x, w, gp, ws.get());
  problem.integrand(kTestTime, z, x, ws.get());
  problem.addIntegrandStateGradient(kTestTime, z, x, 0.5, out, ws.get());
  problem.addIntegrandParameterGradient(kTestTime, z, x, 0.5, gp, ws.get());
  solver->factorize(kTestTime + 1e-3, z, x, 1e-3, ws.get());  // same alpha: no new factorisation
  solver->solve(b);
  solver->solveTransposed(b);
  EXPECT_EQ(counter.count(), 0);
}

INSTANTIATE_TEST_SUITE_P(Coupling, FullOrderDerivatives, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "WithCoupling" : "WithoutCoupling"; });

// dpsi/dx by the discrete adjoint against central differences of the computed psi, every element.
double simulatePsi(const RodConfig& config, const Vector& x, const IntegratorOptions& options,
                   bool coupling) {
  const FullOrderRodProblem problem(config, x, fastCrank(), coupling);
  return simulate(problem, x, options).objective;
}

// psi of the stiff full-order model carries round-off of ~1e-12 relative (the stage residuals are
// sums of terms omega_max^2 u ~ 1e8 larger than their result), so central differences with
// cbrt(eps) steps show errors of ~1e-5 from noise alone. A fourth-order stencil with steps
// h_i = 0.004 x_i keeps both the truncation (the density law c x^6 below 0.1 has relative curvature
// ~6/x) and the noise near 1e-7; a wrong term gives errors of 1e-3 and more.
Vector fourthOrderDifferences(const std::function<double(const Vector&)>& f, const Vector& x) {
  Vector fd(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double h = 0.004 * x(i);
    auto at = [&](double offset) {
      Vector y = x;
      y(i) += offset;
      return f(y);
    };
    fd(i) = (8.0 * (at(h) - at(-h)) - (at(2 * h) - at(-2 * h))) / (12.0 * h);
  }
  return fd;
}

void checkAdjointGradient(const std::string& method, double step, double endTime, bool coupling) {
  const RodConfig config = coarseRod();
  const Vector x = testDesign(config, 13);
  const FullOrderRodProblem problem(config, x, fastCrank(), coupling);
  IntegratorOptions options;
  options.method = method;
  options.t0 = 0.0;
  options.t1 = endTime;
  options.step = step;
  options.newtonTolerance = 1e-10;  // the stage residual's round-off floor (see evaluateFullOrderRod)
  FullStorage storage;
  const GradientResult result = computeGradient(problem, x, options, storage);
  EXPECT_GT(result.objective, 0.0);
  // Linear in the state: one Newton step per implicit stage (TR-BDF2 has two per step), in the forward
  // sweep and again when the backward sweep re-solves each step's stages.
  if (method == "trbdf2") EXPECT_EQ(result.summary.newtonIterations, 2 * 2 * result.summary.steps);
  const Vector fd =
      fourthOrderDifferences([&](const Vector& y) { return simulatePsi(config, y, options, coupling); }, x);
  const double floor = 1e-3 * fd.cwiseAbs().maxCoeff();
  double worst = 0.0;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double error = std::abs(result.gradient(i) - fd(i)) / std::max(std::abs(fd(i)), floor);
    EXPECT_LT(error, 2e-6) << method << " element " << i << ": adjoint " << result.gradient(i) << ", fd "
                           << fd(i);
    worst = std::max(worst, error);
  }
  std::cout << "[ adjoint ] " << method << " h = " << step << (coupling ? "" : " (no coupling)")
            << ": psi = " << result.objective << ", max relative error vs 4th-order differences " << worst
            << " (" << result.summary.steps << " steps)\n";
}

TEST(FullOrderRodGradient, Rk4MatchesFiniteDifferencesForEveryElement) {
  const RodConfig config = coarseRod();
  const FullOrderRodProblem problem(config, testDesign(config, 13), fastCrank(), true);
  // RK4 is stable for h omega_max < 2.83; stay well inside.
  const double omegaMax = std::sqrt(problem.largestEigenvalue(400));
  const double step = 0.03 / std::ceil(0.03 / (1.5 / omegaMax));
  checkAdjointGradient("rk4", step, 0.03, true);
}

TEST(FullOrderRodGradient, Trbdf2MatchesFiniteDifferencesForEveryElement) {
  checkAdjointGradient("trbdf2", 1e-3, 0.04, true);
  checkAdjointGradient("trbdf2", 1e-3, 0.04, false);
}

// An integrator step beyond RK4's stability limit is refused with a message naming the remedy.
TEST(FullOrderRodEvaluation, RefusesAnUnstableExplicitStep) {
  Config config;
  config.rod = coarseRod(20, 4);
  config.simulation.integrator = "rk4";
  config.simulation.step = 1e-4;
  const Vector x = Vector::Constant(config.rod.designCount(), 0.5);
  try {
    evaluateFullOrderRod(config, x, false);
    FAIL() << "an unstable step was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("trbdf2"), std::string::npos) << error.what();
  }
}

// Without the coupling terms the equations are M u'' + K u = -f(t); in the mass-normalised modes
// (Phi^T M Phi = I, Phi^T K Phi = Lambda) every modal coordinate eta_i = phi_i^T M u obeys
// eta_i'' + omega_i^2 eta_i = -phi_i^T f(t) exactly. Runge-Kutta methods commute with linear changes
// of variables, so RK4 on the full system, projected, equals RK4 on the modal equations to round-off.
class ModalEquations final : public Problem {
 public:
  ModalEquations(const FullOrderRodProblem& full, const ModalBasis& basis)
      : full_(full),
        modes_(basis.modesFree.leftCols(basis.eigenmodeCount)),
        eigenvalues_(basis.eigenvalues.head(basis.eigenmodeCount)),
        load_(full.freeDofCount()) {}
  std::string name() const override { return "modal"; }
  int stateSize() const override { return 2 * static_cast<int>(eigenvalues_.size()); }
  int parameterSize() const override { return 0; }
  void initialState(ConstVectorRef, VectorRef z0) const override { z0.setZero(); }
  void rhs(double t, ConstVectorRef z, ConstVectorRef, VectorRef f, ProblemWorkspace*) const override {
    const Eigen::Index k = eigenvalues_.size();
    full_.inertialLoad(t, load_);
    f.head(k) = z.tail(k);
    f.tail(k) = -eigenvalues_.cwiseProduct(z.head(k)) - modes_.transpose() * load_;
  }
  void addRhsParameterVjp(double, ConstVectorRef, ConstVectorRef, ConstVectorRef, VectorRef,
                          ProblemWorkspace*) const override {}
  double integrand(double, ConstVectorRef, ConstVectorRef, ProblemWorkspace*) const override { return 0.0; }
  void addIntegrandStateGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                 ProblemWorkspace*) const override {}
  void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                     ProblemWorkspace*) const override {}

 private:
  const FullOrderRodProblem& full_;
  Matrix modes_;
  Vector eigenvalues_;
  mutable Vector load_;
};

TEST(FullOrderRod, WithoutCouplingTheModalProjectionFollowsTheModalEquations) {
  const RodConfig config = coarseRod(20, 4);
  const Vector x = testDesign(config, 17);
  const FullOrderRodProblem problem(config, x, fastCrank(), false);
  ModalReductionOptions modal;
  modal.modeCount = 6;
  const ModalBasis basis = computeModalBasis(problem.model(), modal);
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 0.06;
  options.step = options.t1 / std::ceil(options.t1 / (1.5 / std::sqrt(problem.largestEigenvalue(400))));
  const Vector uEnd = simulate(problem, x, options).finalState.head(problem.freeDofCount());
  const ModalEquations modalProblem(problem, basis);
  const Vector etaEnd = simulate(modalProblem, Vector(0), options).finalState.head(modal.modeCount);
  const Vector projected =
      basis.modesFree.leftCols(modal.modeCount).transpose() * (problem.model().mass() * uEnd);
  std::cout << "[ modal ] eta(t1) = " << etaEnd.transpose() << "\n          projection error "
            << (projected - etaEnd).norm() / etaEnd.norm() << '\n';
  EXPECT_GT(etaEnd.norm(), 0.0);
  // The eigensolver's residual (~1e-10) bounds the agreement; a wrong load or a stray coupling term
  // gives O(1) differences.
  EXPECT_LT((projected - etaEnd).norm(), 1e-7 * etaEnd.norm());
  // The first modes carry nearly all of the response: the rest of u is small in the M-norm.
  const Vector modalPart = basis.modesFree.leftCols(modal.modeCount) * projected;
  const Vector remainder = uEnd - modalPart;
  const Matrix mass = Matrix(problem.model().mass());
  EXPECT_LT(std::sqrt(remainder.dot(mass * remainder)), 0.2 * std::sqrt(uEnd.dot(mass * uEnd)));
}

}  // namespace
}  // namespace hindsight::rod

namespace hindsight::rod {
namespace {

TEST(FullOrderRodConfig, ModelAndCouplingFieldsAreCheckedStrictly) {
  Config config;
  EXPECT_EQ(config.simulation.model, RodModel::Reduced);
  EXPECT_TRUE(config.simulation.fullOrderCoupling);
  applySetting(config, "simulation.model=full");
  applySetting(config, "simulation.fullOrderCoupling=false");
  EXPECT_EQ(config.simulation.model, RodModel::Full);
  EXPECT_FALSE(config.simulation.fullOrderCoupling);
  EXPECT_EQ(configFromJson(toJson(config)).simulation.model, RodModel::Full);
  try {
    applySetting(config, "simulation.model=half");
    FAIL() << "an unknown model was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("simulation.model"), std::string::npos) << error.what();
  }
  EXPECT_THROW(applySetting(config, "simulation.fullOrderCoupling=1"), std::invalid_argument);
}

// psi1,full against the reduced psi1 (PistonRod: 10 modes, frame from the closure with b q, the default
// integration, within 1e-4 of RK4 at 1e-4) at x0 on the full 3 s horizon. Measured: relative difference
// -1.7e-4 on 40 x 4 and -1.6e-4 on 200 x 12 (trbdf2, h = 1e-3; halving h changes psi1,full by 4e-6 relative).
// The response is quasi-static in the first bending mode, which both models carry exactly; the rest is the
// reduced model's modal truncation (static contribution of the dropped modes) and its frame feedback through
// b q, which the full model's rigid frame lacks. The band 2e-3 covers those with a margin; a
// modelling error in the loads (a wrong sign or factor in a_P) changes psi1 by far more. The coupling
// terms themselves change psi1,full by ~1e-4; they are checked by the equation and derivative tests.
TEST(FullOrderRodEvaluation, Psi1AgreesWithTheReducedModelAtTheInitialDesign) {
  Config config;
  config.rod.elementsAlongLength = 40;
  config.rod.elementsThroughHeight = 4;
  const PistonRod reduced(config);
  const Vector x = reduced.initialDesign();
  const double psiReduced = reduced.evaluate(x, {false, false, false}).psi1;
  config.simulation.integrator = "trbdf2";
  config.simulation.step = 1e-3;
  const FullOrderRodEvaluation full = evaluateFullOrderRod(config, x, false);
  config.simulation.fullOrderCoupling = false;
  const FullOrderRodEvaluation uncoupled = evaluateFullOrderRod(config, x, false);
  const double difference = (full.psi1 - psiReduced) / psiReduced;
  const double couplingEffect = (full.psi1 - uncoupled.psi1) / full.psi1;
  std::cout << "[ reduced vs full ] 40x4: psi1 reduced " << psiReduced << ", full " << full.psi1
            << " (relative difference " << difference << "), without coupling " << uncoupled.psi1
            << " (coupling effect " << couplingEffect << ")\n";
  EXPECT_LT(std::abs(difference), 2e-3);
  EXPECT_GT(std::abs(couplingEffect), 1e-6);  // the coupling terms act
  EXPECT_LT(std::abs(couplingEffect), 2e-3);
  EXPECT_NEAR(full.volumeFraction, 0.5 + 0.5 * 2.0 / 40.0, 1e-12);
  EXPECT_EQ(full.stateSize, 2 * (2 * 41 * 5 - 3));
}

}  // namespace
}  // namespace hindsight::rod

namespace hindsight::rod {
namespace {

// Recomputation from binomial checkpoints runs the Newton solver with a different history of
// factorisations; the preconditioner depends on alpha only, so the gradient is bitwise that of full
// storage (docs/design.md §6: lossless strategies give identical gradients).
TEST(FullOrderRodGradient, BinomialCheckpointingGivesTheBitsOfFullStorage) {
  const RodConfig config = coarseRod();
  const Vector x = testDesign(config, 19);
  const FullOrderRodProblem problem(config, x, fastCrank(), true);
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 0.05;
  options.step = 1e-3;
  options.newtonTolerance = 1e-10;
  auto full = createStorage("full");
  auto binomial = createStorage("binomial:checkpoints=4");
  const GradientResult a = computeGradient(problem, x, options, *full);
  const GradientResult b = computeGradient(problem, x, options, *binomial);
  EXPECT_GT(b.summary.recomputedSteps, 0);
  EXPECT_EQ(a.objective, b.objective);
  EXPECT_EQ((a.gradient - b.gradient).cwiseAbs().maxCoeff(), 0.0);
}

}  // namespace
}  // namespace hindsight::rod

namespace hindsight::rod {
namespace {

// Through the engine: after the first step has factorised M + alpha0^2 K, TR-BDF2 forward and adjoint
// steps allocate nothing.
TEST(FullOrderRodGradient, Trbdf2StepsAllocateNothingAfterTheFirstFactorisation) {
  if (!testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counting unavailable";
  const RodConfig config = coarseRod();
  const Vector x = testDesign(config, 23);
  const FullOrderRodProblem problem(config, x, fastCrank(), true);
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 0.01;
  options.step = 1e-3;
  options.newtonTolerance = 1e-10;
  RungeKuttaIntegrator integrator(problem, x, options);
  Vector z = Vector::Zero(problem.stateSize());
  integrator.step(0.0, 1e-3, z);
  const Vector start = z;
  Vector lambda = Vector::Ones(problem.stateSize()), gradient = Vector::Zero(problem.parameterSize());
  testing::AllocationCounter counter;
  integrator.step(1e-3, 1e-3, z);
  integrator.adjointStep(1e-3, 1e-3, start, lambda, gradient);
  EXPECT_EQ(counter.count(), 0);
  EXPECT_GT(gradient.cwiseAbs().maxCoeff(), 0.0);
}

}  // namespace
}  // namespace hindsight::rod
