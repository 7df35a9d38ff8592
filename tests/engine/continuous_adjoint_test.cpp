// The three adjoint routes behind the one entry point computeGradientByMethod(problem, p, GradientOptions):
// closed forms for the linear problems; convergence to the tight discrete gradient on the nonlinear
// pendulum as tolerances tighten; the continuous adjoint's two sources of forward states (storage
// interpolation and restored windows) agree; bad options are named.
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/app/gradient_routes.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/hermite_storage.h>
#include "support/engine_fixtures.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

namespace hindsight {
namespace {

using testing::complexStepGradient;

/// Tight settings for every route on [0, horizon].
GradientOptions tightOptions(AdjointMethod method, double horizon) {
  GradientOptions options;
  options.adjoint = method;
  options.integrator.t1 = horizon;
  if (method == AdjointMethod::Discrete) {
    options.integrator.method = "rk4";
    options.integrator.step = 1e-3;
  } else {
    options.integrator.method = "dopri5";
    options.integrator.adaptive = true;
    options.integrator.step = 1e-3;
    options.integrator.relativeTolerance = 1e-11;
    options.integrator.absoluteTolerance = 1e-13;
  }
  options.continuous.relativeTolerance = 1e-11;
  options.continuous.absoluteTolerance = 1e-13;
  options.cvodes.method = CvodesMethod::Adams;
  options.cvodes.interpolation = CvodesInterpolation::Polynomial;
  options.cvodes.relativeTolerance = 1e-11;
  options.cvodes.absoluteTolerance = 1e-13;
  return options;
}

struct Route {
  AdjointMethod method;
  std::string storage;
  std::string backward = "dopri5";  // the continuous route's backward integrator
};

/// Relative accuracy each route reaches with tightOptions on the linear problems.
double tolerance(const Route& route) {
  switch (route.method) {
    case AdjointMethod::Discrete:
      return 1e-9;  // rk4, h = 1e-3: O(h^4)
    case AdjointMethod::Continuous:
      // Forward and backward at rtol 1e-11 with O(h^4) interpolation between dopri5 steps; the
      // order-2 backward trbdf2 accumulates more global error at the same rtol (observed 2.7e-8).
      return route.backward == "trbdf2" ? 1e-7 : 1e-8;
    case AdjointMethod::Cvodes:
      return 1e-7;  // a variable-order multistep method's global error runs above rtol
  }
  return 0.0;
}

class EveryRoute : public ::testing::TestWithParam<Route> {};

INSTANTIATE_TEST_SUITE_P(Continuous, EveryRoute,
                         ::testing::Values(Route{AdjointMethod::Discrete, "full"},
                                           Route{AdjointMethod::Continuous, "full"},
                                           Route{AdjointMethod::Continuous, "hermite:every=1"},
                                           Route{AdjointMethod::Continuous, "full", "trbdf2"},
                                           Route{AdjointMethod::Cvodes, ""}),
                         [](const auto& info) {
                           std::string name = toString(info.param.method) + "_" + info.param.storage;
                           if (info.param.method == AdjointMethod::Continuous)
                             name += "_" + info.param.backward;
                           for (char& c : name) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return name;
                         });

TEST_P(EveryRoute, ExponentialDecayMatchesClosedForm) {
  ExponentialDecay problem;
  const Vector p = Eigen::Vector2d(1.3, 0.7);
  const double horizon = 2.0;
  GradientOptions options = tightOptions(GetParam().method, horizon);
  if (!GetParam().storage.empty()) options.storage = GetParam().storage;
  options.continuous.method = GetParam().backward;
  const GradientResult result = computeGradientByMethod(problem, p, options);
  EXPECT_EQ(result.summary.adjoint, toString(GetParam().method));
  const double exact = ExponentialDecay::exactObjective(p(0), p(1), horizon);
  const Vector exactGradient = complexStepGradient(
      [&](const Eigen::VectorXcd& x) { return ExponentialDecay::exactObjective(x(0), x(1), horizon); }, p);
  const double tol = tolerance(GetParam());
  EXPECT_NEAR(result.objective, exact, tol * std::abs(exact));
  EXPECT_LT((result.gradient - exactGradient).norm(), tol * exactGradient.norm())
      << result.gradient.transpose() << " vs " << exactGradient.transpose();
}

TEST_P(EveryRoute, OscillatorMatchesClosedFormUndampedAndDamped) {
  Oscillator problem;
  const double horizon = 3.0;
  for (double damping : {0.0, 0.4}) {
    const Vector p = Eigen::Vector3d(4.0, damping, 0.8);
    GradientOptions options = tightOptions(GetParam().method, horizon);
    if (!GetParam().storage.empty()) options.storage = GetParam().storage;
    options.continuous.method = GetParam().backward;
    const GradientResult result = computeGradientByMethod(problem, p, options);
    const double exact = Oscillator::exactObjective(p(0), p(1), p(2), horizon);
    const Vector exactGradient = complexStepGradient(
        [&](const Eigen::VectorXcd& x) { return Oscillator::exactObjective(x(0), x(1), x(2), horizon); }, p);
    const double tol = tolerance(GetParam());
    EXPECT_NEAR(result.objective, exact, tol * std::abs(exact)) << "damping " << damping;
    EXPECT_LT((result.gradient - exactGradient).norm(), tol * exactGradient.norm())
        << "damping " << damping << ": " << result.gradient.transpose() << " vs "
        << exactGradient.transpose();
  }
}

/// The pendulum's gradient by the discrete adjoint of rk4 at h = 1e-4: the derivative of a psi that
/// is itself accurate to ~1e-13, so a reference for the gradient of the exact psi.
Vector pendulumReference(const Pendulum& problem, const Vector& p, double horizon) {
  GradientOptions options = tightOptions(AdjointMethod::Discrete, horizon);
  options.integrator.step = 1e-4;
  return computeGradientByMethod(problem, p, options).gradient;
}

/// Relative gradient errors of a route at rtol = 1e-4, 1e-6, 1e-8, 1e-10 (atol = rtol / 100).
std::vector<double> pendulumErrors(AdjointMethod method, CvodesMethod cvodesMethod) {
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  const double horizon = 4.0;
  const Vector reference = pendulumReference(problem, p, horizon);
  std::vector<double> errors;
  std::cout << "[ pendulum ] " << toString(method)
            << (method == AdjointMethod::Cvodes ? "-" + toString(cvodesMethod) : std::string()) << ":";
  for (double rtol : {1e-4, 1e-6, 1e-8, 1e-10}) {
    GradientOptions options = tightOptions(method, horizon);
    options.integrator.relativeTolerance = rtol;
    options.integrator.absoluteTolerance = rtol / 100;
    options.continuous.relativeTolerance = rtol;
    options.continuous.absoluteTolerance = rtol / 100;
    options.cvodes.method = cvodesMethod;
    options.cvodes.relativeTolerance = rtol;
    options.cvodes.absoluteTolerance = rtol / 100;
    const GradientResult result = computeGradientByMethod(problem, p, options);
    errors.push_back((result.gradient - reference).norm() / reference.norm());
    std::cout << " rtol " << rtol << ": error " << errors.back();
    if (errors.size() > 1) {
      std::cout << " (order per decade " << std::log10(errors[errors.size() - 2] / errors.back()) / 2.0
                << ")";
    }
  }
  std::cout << "\n";
  return errors;
}

// Tolerance proportionality: the global error of a well-behaved adaptive solver scales like
// rtol^alpha with alpha near 1 (observed: continuous 0.82-0.90, CVODES Adams 0.51-1.11, BDF
// 0.63-1.22 per decade, printed as "order per decade"). Required: a factor of at least sqrt(10)
// per decade of rtol, checked over each two decades (>= 10x, alpha >= 0.5; a single decade is too
// noisy for a variable-order method), and at rtol = 1e-10 a gradient within 1e-7 of the reference.
void expectConvergence(const std::vector<double>& errors) {
  for (std::size_t i = 1; i < errors.size(); ++i) {
    EXPECT_GT(errors[i - 1] / errors[i], 10.0) << "from rtol 1e-" << 2 * i + 2 << " to 1e-" << 2 * i + 4;
  }
  EXPECT_LT(errors.back(), 1e-7);
}

TEST(ContinuousPendulum, ContinuousAdjointConvergesToTheDiscreteGradient) {
  expectConvergence(pendulumErrors(AdjointMethod::Continuous, CvodesMethod::Adams));
}

TEST(ContinuousPendulum, CvodesAdamsConvergesToTheDiscreteGradient) {
  expectConvergence(pendulumErrors(AdjointMethod::Cvodes, CvodesMethod::Adams));
}

TEST(ContinuousPendulum, CvodesBdfConvergesToTheDiscreteGradient) {
  expectConvergence(pendulumErrors(AdjointMethod::Cvodes, CvodesMethod::Bdf));
}

TEST(ContinuousStiff, RobertsonWithImplicitBackwardAgreesWithDiscreteAndCvodes) {
  // Robertson over t in [0, 1e5]: the backward trbdf2 takes steps over many decades, like the
  // forward one; the gradient agrees with the discrete adjoint of trbdf2 and with CVODES BDF within
  // the tolerances (log-scaled components k_i dpsi/dk_i, which span the parameters' magnitudes).
  const double horizon = 1e5;
  Robertson problem(horizon);
  const Vector p = Robertson::nominalParameters();
  GradientOptions options;
  options.integrator.method = "trbdf2";
  options.integrator.t1 = horizon;
  options.integrator.adaptive = true;
  options.integrator.step = 1e-6;
  options.integrator.relativeTolerance = 1e-9;
  options.integrator.absoluteTolerance = 1e-14;
  options.continuous.method = "trbdf2";
  options.continuous.relativeTolerance = 1e-9;
  options.continuous.absoluteTolerance = 1e-14;
  options.cvodes.relativeTolerance = 1e-9;
  options.cvodes.absoluteTolerance = 1e-14;
  options.adjoint = AdjointMethod::Continuous;
  const GradientResult continuous = computeGradientByMethod(problem, p, options);
  options.adjoint = AdjointMethod::Discrete;
  const GradientResult discrete = computeGradientByMethod(problem, p, options);
  options.adjoint = AdjointMethod::Cvodes;
  const GradientResult cvodes = computeGradientByMethod(problem, p, options);
  EXPECT_GT(continuous.summary.factorizations, discrete.summary.steps);  // the backward sweep factorised
  for (int i = 0; i < 3; ++i) {
    const double c = continuous.gradient(i) * p(i), d = discrete.gradient(i) * p(i),
                 v = cvodes.gradient(i) * p(i);
    std::cout << "[ robertson ] k" << i + 1 << " dpsi/dk: continuous " << c << ", discrete " << d
              << ", cvodes " << v << "\n";
    EXPECT_NEAR(c, d, 1e-5 * std::abs(d)) << "component " << i;
    EXPECT_NEAR(c, v, 1e-5 * std::abs(d)) << "component " << i;
  }
}

/// Robertson on [0, horizon] with adaptive trbdf2 forward (rtol, atol) and backward (rtol, atol).
GradientOptions robertsonTrbdf2(double horizon, double step, double forwardRtol, double forwardAtol,
                                double backwardRtol, double backwardAtol) {
  GradientOptions options;
  options.adjoint = AdjointMethod::Continuous;
  options.integrator.method = "trbdf2";
  options.integrator.t1 = horizon;
  options.integrator.adaptive = true;
  options.integrator.step = step;
  options.integrator.relativeTolerance = forwardRtol;
  options.integrator.absoluteTolerance = forwardAtol;
  options.continuous.method = "trbdf2";
  options.continuous.relativeTolerance = backwardRtol;
  options.continuous.absoluteTolerance = backwardAtol;
  return options;
}

/// Robertson over [0, 4e7] (hardening finding 9): forward rtol 1e-10, backward `backwardRtol`;
/// minStep lowered so that the layer at t1 is not cut off by the default bound.
GradientOptions stiffLongOptions(double backwardRtol) {
  GradientOptions options = robertsonTrbdf2(4e7, 1e-8, 1e-10, 1e-14, backwardRtol, 1e-14);
  options.continuous.minStep = 1e-18;
  options.continuous.maxSteps = 200'000;
  return options;
}

std::string numericalErrorMessage(const Problem& problem, ConstVectorRef p, const GradientOptions& options) {
  try {
    computeGradientByMethod(problem, p, options);
  } catch (const NumericalError& e) {
    return e.what();
  }
  return "<no NumericalError>";
}

TEST(ContinuousStiff, TightBackwardToleranceOnRobertsonTo4e7IsBoundedByTheFilteredEstimate) {
  // Unfiltered, the TR-BDF2 estimate of the stiff lambda_2 (eigenvalue ~ -1e4) is round-off in
  // k = F_z^T lambda amplified by h ||F_z||: at rtol 1e-12 it caps the step near 1 s on [0, 4e7]
  // and every attempt beyond is rejected; the sweep used up maxSteps before reaching t ~ 3.97e7
  // (1.18 M rejections at rtol 1e-11 without the bound). Filtered, the same run takes a few hundred
  // rejections and agrees with the discrete adjoint to the forward tolerance.
  Robertson problem(4e7);
  const Vector p = Robertson::nominalParameters();
  GradientOptions options = stiffLongOptions(1e-12);
  EXPECT_NE(numericalErrorMessage(problem, p, options).find("more than maxSteps = 200000"),
            std::string::npos);
  options.continuous.filterErrorEstimate = true;
  const GradientResult continuous = computeGradientByMethod(problem, p, options);
  options.adjoint = AdjointMethod::Discrete;
  const GradientResult discrete = computeGradientByMethod(problem, p, options);
  const std::int64_t backwardRejected = continuous.summary.rejectedSteps - discrete.summary.rejectedSteps;
  std::cout << "[ robertson 4e7 ] backward rejected " << backwardRejected << ", gradient "
            << continuous.gradient.transpose() << " (discrete " << discrete.gradient.transpose() << ")\n";
  EXPECT_LT(backwardRejected, 5000);  // observed 645
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(continuous.gradient(i), discrete.gradient(i), 1e-6 * std::abs(discrete.gradient(i))) << i;
  }
}

TEST(ContinuousStiff, ABackwardLayerBelowTheTimeResolutionStopsAtOnceWithTheReason) {
  // lambda(t1) = dphi/dz = (1, 0, 0) is off the adjoint's slow manifold: lambda_2 has a layer of
  // width ~1e-4 at t1 = 4e7, where times are 7.45e-9 apart. At rtol 1e-13 the layer needs steps
  // below that: once a one-ulp step is rejected the sweep stops and says why (before, a retry
  // rounded back onto the rejected step and was repeated unchanged until maxSteps).
  Robertson problem(4e7);
  const Vector p = Robertson::nominalParameters();
  GradientOptions options = stiffLongOptions(1e-13);
  options.continuous.filterErrorEstimate = true;
  options.continuous.absoluteTolerance = 1e-16;
  std::string message = numericalErrorMessage(problem, p, options);
  EXPECT_NE(message.find("one unit in the last place of t"), std::string::npos) << message;
  EXPECT_NE(message.find("ContinuousAdjointOptions.relativeTolerance = 1e-13"), std::string::npos) << message;
  // With the default minStep the same layer at rtol 1e-11 hits the underflow bound, which names the
  // fields too.
  options = stiffLongOptions(1e-11);
  options.continuous.minStep = ContinuousAdjointOptions{}.minStep;
  message = numericalErrorMessage(problem, p, options);
  EXPECT_NE(message.find("ContinuousAdjointOptions.minStep * max(1, |t|) = 4e-07"), std::string::npos)
      << message;
  EXPECT_NE(message.find("ContinuousAdjointOptions.relativeTolerance = 1e-11"), std::string::npos) << message;
}

TEST(ContinuousStiff, AStartingStepBelowTheBoundNoLongerFailsAtOnce) {
  // Hairer's starting step scales by atol where y(t1) is zero; with lambda_2's steep slope at t1 it
  // proposed 1e-12 at t1 = 4e7, below minStep |t1| = 4e-7, and every tolerance failed at once. The
  // start is now raised to 100 times the bound and the controller finds the layer's step.
  Robertson problem(4e7);
  const Vector p = Robertson::nominalParameters();
  GradientOptions options = stiffLongOptions(1e-6);
  options.continuous.minStep = ContinuousAdjointOptions{}.minStep;
  const GradientResult continuous = computeGradientByMethod(problem, p, options);
  options.adjoint = AdjointMethod::Discrete;
  const GradientResult discrete = computeGradientByMethod(problem, p, options);
  for (int i = 0; i < 3; ++i) {
    // Observed 1.1e-4 relative: the order-2 backward sweep at rtol 1e-6 over eleven decades.
    EXPECT_NEAR(continuous.gradient(i), discrete.gradient(i), 1e-3 * std::abs(discrete.gradient(i))) << i;
  }
}

TEST(ContinuousSources, RestoredWindowAndHermiteEveryStepGiveTheSameGradient) {
  // Both build the cubic Hermite interpolant from z_n and F(t_n, z_n) on every forward step, one
  // through storage.interpolate(), the other from restored states: the same numbers to round-off.
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  GradientOptions options = tightOptions(AdjointMethod::Continuous, 4.0);
  options.integrator.relativeTolerance = 1e-7;
  options.integrator.absoluteTolerance = 1e-9;
  options.storage = "full";
  const GradientResult window = computeGradientByMethod(problem, p, options);
  options.storage = "hermite:every=1";
  const GradientResult interpolated = computeGradientByMethod(problem, p, options);
  EXPECT_EQ(window.objective, interpolated.objective);
  EXPECT_LT((window.gradient - interpolated.gradient).norm(), 1e-12 * window.gradient.norm());
  EXPECT_EQ(window.summary.storage, "full");
  EXPECT_EQ(interpolated.summary.storage, "hermite:every=1");
}

TEST(ContinuousSources, CoarserHermiteStorageCostsAccuracy) {
  // Hermite kept every 8th step of a fixed rk4 grid: the continuous gradient moves away from the
  // every-step one by the O(H^4) interpolation error, and less so at every 4th step.
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  GradientOptions options = tightOptions(AdjointMethod::Continuous, 4.0);
  options.integrator.method = "rk4";
  options.integrator.adaptive = false;
  options.integrator.step = 4e-3;
  options.storage = "hermite:every=1";
  const Vector fine = computeGradientByMethod(problem, p, options).gradient;
  options.storage = "hermite:every=8";
  const double error8 = (computeGradientByMethod(problem, p, options).gradient - fine).norm() / fine.norm();
  options.storage = "hermite:every=4";
  const double error4 = (computeGradientByMethod(problem, p, options).gradient - fine).norm() / fine.norm();
  std::cout << "[ continuous ] hermite every=8: " << error8 << ", every=4: " << error4 << "\n";
  EXPECT_GT(error8 / error4, 8.0);
}

/// The oscillator seen through vector-Jacobian products only (a large-state problem's interface).
class MatrixFreeOscillator final : public Problem {
 public:
  std::string name() const override { return "matrix-free-oscillator"; }
  int stateSize() const override { return inner_.stateSize(); }
  int parameterSize() const override { return inner_.parameterSize(); }
  std::unique_ptr<ProblemWorkspace> createWorkspace() const override { return inner_.createWorkspace(); }
  void initialState(ConstVectorRef p, VectorRef z0) const override { inner_.initialState(p, z0); }
  void addInitialStateVjp(ConstVectorRef p, ConstVectorRef lambda0, VectorRef gradient) const override {
    inner_.addInitialStateVjp(p, lambda0, gradient);
  }
  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace* ws) const override {
    inner_.rhs(t, z, p, f, ws);
  }
  bool hasDenseJacobian() const override { return false; }
  void rhsStateVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                   ProblemWorkspace* ws) const override {
    Matrix jacobian(2, 2);
    inner_.rhsJacobian(t, z, p, jacobian, ws);
    out = jacobian.transpose() * w;
  }
  void addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace* ws) const override {
    inner_.addRhsParameterVjp(t, z, p, w, out, ws);
  }
  double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace* ws) const override {
    return inner_.integrand(t, z, p, ws);
  }
  void addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale, VectorRef out,
                                 ProblemWorkspace* ws) const override {
    inner_.addIntegrandStateGradient(t, z, p, scale, out, ws);
  }
  void addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                     VectorRef out, ProblemWorkspace* ws) const override {
    inner_.addIntegrandParameterGradient(t, z, p, scale, out, ws);
  }

 private:
  Oscillator oscillator_;
  const Problem& inner_ = oscillator_;  // its first-order interface (SecondOrderProblem overloads it)
};

TEST(ContinuousMatrixFree, VectorJacobianProductsGiveTheDenseGradient) {
  const Vector p = Eigen::Vector3d(4.0, 0.4, 0.8);
  GradientOptions options = tightOptions(AdjointMethod::Continuous, 3.0);
  options.integrator.relativeTolerance = 1e-8;
  options.integrator.absoluteTolerance = 1e-10;
  const GradientResult dense = computeGradientByMethod(Oscillator(), p, options);
  const GradientResult matrixFree = computeGradientByMethod(MatrixFreeOscillator(), p, options);
  EXPECT_EQ(dense.objective, matrixFree.objective);
  EXPECT_LT((dense.gradient - matrixFree.gradient).norm(), 1e-13 * dense.gradient.norm());
  // The implicit backward method and CVODES' dense direct solver need the Jacobian: refused.
  options.continuous.method = "trbdf2";
  EXPECT_THROW(computeGradientByMethod(MatrixFreeOscillator(), p, options), std::invalid_argument);
  // CVODES runs it matrix-free: Adams by fixed-point iteration, BDF by Newton-GMRES, the
  // backward rhs by the VJP; the same gradient as with the dense Jacobian, within the tolerance.
  options.adjoint = AdjointMethod::Cvodes;
  for (CvodesMethod method : {CvodesMethod::Adams, CvodesMethod::Bdf}) {
    options.cvodes.method = method;
    const GradientResult cvodesDense = computeGradientByMethod(Oscillator(), p, options);
    const GradientResult cvodesMatrixFree = computeGradientByMethod(MatrixFreeOscillator(), p, options);
    EXPECT_LT((cvodesMatrixFree.gradient - cvodesDense.gradient).norm(), 1e-9 * cvodesDense.gradient.norm())
        << toString(method);
    // CVODES' own global error at rtol 1e-11 (polynomial interpolation) is ~1e-7 relative here.
    EXPECT_LT((cvodesMatrixFree.gradient - dense.gradient).norm(), 1e-6 * dense.gradient.norm())
        << toString(method);
    EXPECT_EQ(cvodesMatrixFree.summary.jacobianEvaluations, 0) << toString(method);
  }
  options.cvodes.linearSolver = CvodesLinearSolver::Dense;
  try {
    computeGradientByMethod(MatrixFreeOscillator(), p, options);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("hasDenseJacobian"), std::string::npos) << e.what();
  }
}

TEST(AdjointMethodOption, ParsesTheThreeNamesAndListsThemOnError) {
  EXPECT_EQ(parseAdjointMethod("discrete"), AdjointMethod::Discrete);
  EXPECT_EQ(parseAdjointMethod("continuous"), AdjointMethod::Continuous);
  EXPECT_EQ(parseAdjointMethod("cvodes"), AdjointMethod::Cvodes);
  for (const auto& name : adjointMethodNames()) EXPECT_EQ(toString(parseAdjointMethod(name)), name);
  try {
    parseAdjointMethod("backward");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("discrete, continuous, cvodes"), std::string::npos) << e.what();
  }
}

TEST(ContinuousTolerances, PerComponentAndQuadratureTolerancesReachTheBackwardErrorTest) {
  // Robertson over [0, 1e5] with the backward trbdf2: per-component atol equal to the scalar gives
  // the scalar run's bits; a loose quadrature tolerance on mu, or a loose atol on lambda_2 alone,
  // changes the backward step sequence (visible in the rejected steps and the gradient's bits).
  Robertson problem(1e5);
  const Vector p = Robertson::nominalParameters();
  GradientOptions options = robertsonTrbdf2(1e5, 1e-6, 1e-8, 1e-12, 1e-8, 1e-12);
  const GradientResult scalar = computeGradientByMethod(problem, p, options);
  options.continuous.absoluteTolerances = {1e-12, 1e-12, 1e-12};
  const GradientResult same = computeGradientByMethod(problem, p, options);
  EXPECT_EQ(scalar.gradient, same.gradient);
  EXPECT_EQ(scalar.summary.rejectedSteps, same.summary.rejectedSteps);
  options.continuous.quadratureRelativeTolerance = 1e-3;
  options.continuous.quadratureAbsoluteTolerance = 1e-3;
  const GradientResult looseQuadrature = computeGradientByMethod(problem, p, options);
  EXPECT_NE(scalar.gradient, looseQuadrature.gradient);
  options.continuous.quadratureRelativeTolerance = 0.0;
  options.continuous.quadratureAbsoluteTolerance = 0.0;
  options.continuous.absoluteTolerances = {1e-12, 1e-3, 1e-12};
  const GradientResult looseLambda2 = computeGradientByMethod(problem, p, options);
  EXPECT_NE(scalar.gradient, looseLambda2.gradient);
  // All of them still the same gradient to the loosest tolerance asked for.
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(looseQuadrature.gradient(i), scalar.gradient(i), 1e-2 * std::abs(scalar.gradient(i)));
  }
}

TEST(ContinuousBadInput, ToleranceFieldsAreNamed) {
  ExponentialDecay problem;
  GradientOptions options = tightOptions(AdjointMethod::Continuous, 1.0);
  const auto message = [&]() -> std::string {
    try {
      computeGradientByMethod(problem, Eigen::Vector2d(1.0, 1.0), options);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "<no exception>";
  };
  options.continuous.quadratureRelativeTolerance = 2.0;
  EXPECT_NE(message().find("ContinuousAdjointOptions.quadratureRelativeTolerance = 2 must be 0"),
            std::string::npos)
      << message();
  options.continuous.quadratureRelativeTolerance = 0.0;
  options.continuous.quadratureAbsoluteTolerance = -1.0;
  EXPECT_NE(message().find("ContinuousAdjointOptions.quadratureAbsoluteTolerance = -1"), std::string::npos)
      << message();
  options.continuous.quadratureAbsoluteTolerance = 0.0;
  options.continuous.absoluteTolerances = {-1.0};
  EXPECT_NE(message().find("ContinuousAdjointOptions.absoluteTolerances[0] = -1 must be positive"),
            std::string::npos)
      << message();
  options.continuous.absoluteTolerances = {1e-8, 1e-8};
  EXPECT_NE(message().find("ContinuousAdjointOptions.absoluteTolerances has 2 entries"), std::string::npos)
      << message();
}

TEST(ContinuousBadInput, BadOptionsNameTheField) {
  ExponentialDecay problem;
  GradientOptions options = tightOptions(AdjointMethod::Continuous, 1.0);
  options.continuous.relativeTolerance = 0.0;
  try {
    computeGradientByMethod(problem, Eigen::Vector2d(1.0, 1.0), options);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ContinuousAdjointOptions.relativeTolerance"), std::string::npos)
        << e.what();
  }
  options.continuous.relativeTolerance = 1e-6;
  options.continuous.initialStep = 2.0;
  EXPECT_THROW(computeGradientByMethod(problem, Eigen::Vector2d(1.0, 1.0), options), std::invalid_argument);
  options.continuous.initialStep = 0.0;
  options.continuous.method = "rk4";
  try {
    computeGradientByMethod(problem, Eigen::Vector2d(1.0, 1.0), options);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ContinuousAdjointOptions.method = 'rk4'"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("dopri5, trbdf2"), std::string::npos) << e.what();
  }
  options.continuous.method = "dopri5";
  options.storage = "nonsense";
  EXPECT_THROW(computeGradientByMethod(problem, Eigen::Vector2d(1.0, 1.0), options), std::invalid_argument);
}

TEST(ContinuousFailure, TooFewBackwardStepsGiveNumericalErrorWithTheTime) {
  Pendulum problem;
  GradientOptions options = tightOptions(AdjointMethod::Continuous, 4.0);
  options.continuous.maxSteps = 5;
  try {
    computeGradientByMethod(problem, Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), options);
    FAIL() << "no exception";
  } catch (const NumericalError& e) {
    EXPECT_NE(std::string(e.what()).find("maxSteps = 5"), std::string::npos) << e.what();
    EXPECT_GT(e.time(), 0.0);
    EXPECT_LT(e.time(), 4.0);
  }
}

}  // namespace
}  // namespace hindsight
