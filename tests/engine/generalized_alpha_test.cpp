// Generalized-alpha and HHT-alpha (engine/generalized_alpha.h): order 2 against the oscillator's
// closed form, energy behaviour on the undamped oscillator, the discrete adjoint against central
// differences of the computed psi on a nonlinear problem with a configuration-dependent mass matrix,
// the integrator state in the storage, and the option checks.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/continuous_adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/generalized_alpha.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/storage_factory.h>
#include "support/engine_fixtures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace hindsight {
namespace {

using testing::computedObjective;
using testing::gradientWithFullStorage;
using testing::invalidArgumentMessage;

/// An elastic pendulum in polar coordinates y = (r, th): a mass m on a spring of stiffness k and rest
/// length L, with damping c on both coordinates. M(y) = diag(m, m r^2) depends on the configuration
/// and on p; the forces are nonlinear in y and v; r(0) = L + 0.1 and th(0) = th0 depend on p; G
/// depends on p through L and the weight w:
///   psi = int (r - L)^2 + w th^2 dt + (1/2) thd(T)^2,   p = (m, k, c, L, th0, w).
class ElasticPendulum final : public SecondOrderProblem {
 public:
  static constexpr double kGravity = 9.81;
  std::string name() const override { return "elastic-pendulum"; }
  int coordinateCount() const override { return 2; }
  int parameterSize() const override { return 6; }
  static Vector nominalParameters() {
    Vector p(6);
    p << 1.2, 40.0, 0.15, 1.0, 0.9, 0.5;
    return p;
  }
  void initialCoordinates(ConstVectorRef p, VectorRef y0, VectorRef v0) const override {
    y0 << p(3) + 0.1, p(4);
    v0.setZero();
  }
  void addInitialCoordinatesVjp(ConstVectorRef, ConstVectorRef lambdaY, ConstVectorRef,
                                VectorRef gradient) const override {
    gradient(3) += lambdaY(0);
    gradient(4) += lambdaY(1);
  }
  void massMatrix(double, ConstVectorRef y, ConstVectorRef p, MatrixRef mass,
                  ProblemWorkspace*) const override {
    mass.setZero();
    mass(0, 0) = p(0);
    mass(1, 1) = p(0) * y(0) * y(0);
  }
  void force(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef f,
             ProblemWorkspace*) const override {
    const double m = p(0), k = p(1), c = p(2), length = p(3);
    const double r = y(0), th = y(1), rd = v(0), thd = v(1);
    f(0) = m * r * thd * thd + m * kGravity * std::cos(th) - k * (r - length) - c * rd;
    f(1) = -2.0 * m * r * rd * thd - m * kGravity * r * std::sin(th) - c * thd;
  }
  void residualJacobians(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                         MatrixRef ry, MatrixRef rv, ProblemWorkspace*) const override {
    const double m = p(0), k = p(1), c = p(2);
    const double r = y(0), th = y(1), rd = v(0), thd = v(1);
    ry(0, 0) = -m * thd * thd + k;
    ry(0, 1) = m * kGravity * std::sin(th);
    ry(1, 0) = 2.0 * m * r * a(1) + 2.0 * m * rd * thd + m * kGravity * std::sin(th);
    ry(1, 1) = m * kGravity * r * std::cos(th);
    rv(0, 0) = c;
    rv(0, 1) = -2.0 * m * r * thd;
    rv(1, 0) = 2.0 * m * r * thd;
    rv(1, 1) = 2.0 * m * r * rd + c;
  }
  void addResidualParameterVjp(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                               ConstVectorRef mu, VectorRef out, ProblemWorkspace*) const override {
    const double k = p(1), length = p(3);
    const double r = y(0), th = y(1), rd = v(0), thd = v(1);
    out(0) += (a(0) - r * thd * thd - kGravity * std::cos(th)) * mu(0) +
              (r * r * a(1) + 2.0 * r * rd * thd + kGravity * r * std::sin(th)) * mu(1);
    out(1) += (r - length) * mu(0);
    out(2) += rd * mu(0) + thd * mu(1);
    out(3) += -k * mu(0);
  }
  double integrand(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef p,
                   ProblemWorkspace*) const override {
    const double stretch = y(0) - p(3);
    return stretch * stretch + p(5) * y(1) * y(1);
  }
  void addIntegrandStateGradient(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef p, double scale,
                                 VectorRef gy, VectorRef, ProblemWorkspace*) const override {
    gy(0) += scale * 2.0 * (y(0) - p(3));
    gy(1) += scale * 2.0 * p(5) * y(1);
  }
  void addIntegrandParameterGradient(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef p, double scale,
                                     VectorRef gp, ProblemWorkspace*) const override {
    gp(3) -= scale * 2.0 * (y(0) - p(3));
    gp(5) += scale * y(1) * y(1);
  }
  double terminal(ConstVectorRef z, ConstVectorRef) const override { return 0.5 * z(3) * z(3); }
  void addTerminalGradient(ConstVectorRef z, ConstVectorRef, VectorRef gz, VectorRef) const override {
    gz(3) += z(3);
  }
};

IntegratorOptions alphaOptions(const std::string& method, double rho, double t1, double h) {
  IntegratorOptions options;
  options.method = method;
  options.rhoInfinity = rho;
  options.t1 = t1;
  options.step = h;
  return options;
}

struct Variant {
  std::string method;
  double rho;
};

std::string variantName(const Variant& v) {
  std::string name = v.method + "_rho" + std::to_string(static_cast<int>(std::lround(100 * v.rho)));
  for (char& c : name) c = c == '-' ? '_' : c;
  return name;
}

class AlphaMethod : public ::testing::TestWithParam<Variant> {};

INSTANTIATE_TEST_SUITE_P(Variants, AlphaMethod,
                         ::testing::Values(Variant{"generalized-alpha", 1.0},
                                           Variant{"generalized-alpha", 0.8},
                                           Variant{"generalized-alpha", 0.0}, Variant{"hht-alpha", 0.7}),
                         [](const auto& info) { return variantName(info.param); });

/// y(t) of the damped oscillator y'' + c y' + k y = 0, y(0) = y0, y'(0) = 0 (k > c^2/4).
double oscillatorPosition(double k, double c, double y0, double t) {
  const double s = -c / 2.0, w = std::sqrt(k - c * c / 4.0);
  return std::exp(s * t) * (y0 * std::cos(w * t) - s * y0 / w * std::sin(w * t));
}

TEST_P(AlphaMethod, ConvergesWithOrderTwoOnTheOscillator) {
  Oscillator problem;
  for (double damping : {0.0, 0.4}) {
    const Vector p = Eigen::Vector3d(4.0, damping, 0.8);
    const double horizon = 3.0;
    const double exact = oscillatorPosition(p(0), p(1), p(2), horizon);
    double errors[3];
    for (int level = 0; level < 3; ++level) {
      const double h = 0.01 / std::pow(2.0, level);
      const ForwardResult result =
          simulate(problem, p, alphaOptions(GetParam().method, GetParam().rho, horizon, h));
      errors[level] = std::abs(result.finalState(0) - exact);
    }
    for (int level = 0; level + 1 < 3; ++level) {
      const double observed = std::log2(errors[level] / errors[level + 1]);
      // rho_inf = 0 approaches order 2 from above (2.15 from h = 0.01 to 0.005): a large third-order term.
      EXPECT_NEAR(observed, 2.0, 0.2)
          << "damping " << damping << ", errors " << errors[level] << " -> " << errors[level + 1];
    }
  }
}

/// The energies E_n = (v_n^2 + k y_n^2)/2 of the undamped oscillator at every grid point.
std::vector<double> oscillatorEnergies(double k, const IntegratorOptions& options) {
  Oscillator problem;
  std::vector<double> energies;
  simulate(problem, Eigen::Vector3d(k, 0.0, 1.0), options, [&](std::int64_t, double, ConstVectorRef z) {
    energies.push_back(0.5 * (z(1) * z(1) + k * z(0) * z(0)));
  });
  return energies;
}

TEST(GeneralizedAlpha, WithoutNumericalDampingConservesTheOscillatorsEnergy) {
  // rho_inf = 1 is the trapezoidal rule on a linear problem: the energy is conserved to round-off,
  // at resolved (omega h = 0.1) and unresolved (omega h = 50) frequencies alike, over 100 periods.
  for (const std::string method : {"generalized-alpha", "hht-alpha"}) {
    for (double k : {4.0, 1e6}) {
      const double period = 2.0 * M_PI / std::sqrt(k);
      const std::vector<double> energies =
          oscillatorEnergies(k, alphaOptions(method, 1.0, 100 * period, 0.05));
      double drift = 0.0;
      for (double e : energies) drift = std::max(drift, std::abs(e - energies.front()) / energies.front());
      EXPECT_LT(drift, 1e-10) << method << ", k = " << k;
    }
  }
}

TEST(GeneralizedAlpha, WithNumericalDampingLosesEnergyAndDampsHighFrequencies) {
  // With rho_inf < 1 the step map has spectral radius below 1, but it is not normal: the energy in
  // (y, v) is not monotone from step to step. What holds, and is checked: at a resolved frequency
  // (omega h = 0.1) the energy's envelope (its maximum over each period) never grows and little
  // energy is lost over 20 periods; at an unresolved one (omega h = 50), after a start-up overshoot
  // of the velocity in the first steps (Hilber & Hughes 1978) the energy oscillates under a decaying
  // envelope: it never again reaches the start-up peak and falls by orders of magnitude within 40
  // steps, while rho_inf = 1 keeps it (test above).
  for (const std::string method : {"generalized-alpha", "hht-alpha"}) {
    for (double rho : {0.5, 0.8}) {
      const std::vector<double> low = oscillatorEnergies(4.0, alphaOptions(method, rho, 20 * M_PI, 0.05));
      const std::size_t perPeriod = 63;  // period pi, h = 0.05
      double previousPeak = low.front();
      for (std::size_t start = 0; start + perPeriod <= low.size(); start += perPeriod) {
        const double peak = *std::max_element(low.begin() + start, low.begin() + start + perPeriod);
        EXPECT_LE(peak, previousPeak * (1.0 + 1e-12))
            << method << ", rho " << rho << ", period from step " << start;
        previousPeak = peak;
      }
      EXPECT_LT(low.back(), low.front()) << method << ", rho " << rho;
      EXPECT_GT(low.back(), 0.99 * low.front()) << method << ", rho " << rho;
      const std::vector<double> high = oscillatorEnergies(1e6, alphaOptions(method, rho, 2.0, 0.05));
      const double startUpPeak = *std::max_element(high.begin(), high.begin() + 10);
      for (std::size_t n = 10; n < high.size(); ++n) {
        EXPECT_LE(high[n], startUpPeak) << method << ", rho " << rho << ", step " << n;
      }
      EXPECT_LT(high.back(), 1e-2 * high.front()) << method << ", rho " << rho;
    }
  }
}

TEST(ElasticPendulumProblem, RungeKuttaGradientMatchesFiniteDifferences) {
  // The test problem's hand-written derivatives, checked through an independent integrator.
  ElasticPendulum problem;
  const Vector p = ElasticPendulum::nominalParameters();
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 2.0;
  options.step = 2e-3;
  const GradientResult result = gradientWithFullStorage(problem, p, options);
  const auto check = checkGradient(computedObjective(problem, options), p, result.gradient, {1e-7});
  EXPECT_TRUE(check.passed) << check.message;
}

TEST_P(AlphaMethod, GradientIsTheDerivativeOfTheComputedObjective) {
  ElasticPendulum problem;
  const Vector p = ElasticPendulum::nominalParameters();
  const IntegratorOptions options = alphaOptions(GetParam().method, GetParam().rho, 2.0, 1e-2);
  const GradientResult result = gradientWithFullStorage(problem, p, options);
  EXPECT_EQ(result.objective, simulate(problem, p, options).objective);
  // Every parameter enters: M and f (m, k, c, L), the initial conditions (L, th0) and G (L, w).
  for (Eigen::Index i = 0; i < p.size(); ++i) EXPECT_NE(result.gradient(i), 0.0) << "component " << i;
  const auto check = checkGradient(computedObjective(problem, options), p, result.gradient, {1e-7});
  EXPECT_TRUE(check.passed) << check.message;
}

// The backward step that reads d_{n+1} from x_{n+1} (what the sweep of an exact storage does) is the
// backward step that solves for it again, bit for bit, over a whole trajectory; and the sweep takes it
// (one Jacobian per backward step, no Newton iteration).
TEST_P(AlphaMethod, BackwardStepFromTheStepsEndEqualsTheSolvingOneBitwise) {
  ElasticPendulum problem;
  const Vector p = ElasticPendulum::nominalParameters();
  const IntegratorOptions options = alphaOptions(GetParam().method, GetParam().rho, 0.5, 1e-2);
  auto solving = createIntegrator(problem, p, options);
  auto reading = createIntegrator(problem, p, options);
  ASSERT_TRUE(reading->usesStepEnd());
  Vector x(solving->stateSize());
  solving->initialState(0.0, x);
  std::vector<Vector> states{x};
  for (int n = 0; n < 50; ++n) {
    solving->step(0.01 * n, 0.01, x);
    states.push_back(x);
  }
  Vector lambdaSolving = Vector::LinSpaced(x.size(), 0.3, -1.1), lambdaReading = lambdaSolving;
  Vector gradientSolving = Vector::Zero(p.size()), gradientReading = gradientSolving;
  for (int n = 49; n >= 0; --n) {
    solving->adjointStep(0.01 * n, 0.01, states[n], lambdaSolving, gradientSolving);
    reading->adjointStepWithEnd(0.01 * n, 0.01, states[n], states[n + 1], lambdaReading, gradientReading);
  }
  EXPECT_TRUE(lambdaSolving.cwiseEqual(lambdaReading).all());
  EXPECT_TRUE(gradientSolving.cwiseEqual(gradientReading).all());
  EXPECT_EQ(reading->counters().newtonIterations, 0);
  EXPECT_EQ(reading->counters().jacobianEvaluations, 50);
  const GradientResult swept = gradientWithFullStorage(problem, p, options);
  // One per forward step, one per backward step, one for d_0 in the initial state's product.
  EXPECT_EQ(swept.summary.jacobianEvaluations, 2 * 50 + 1);
}

TEST_P(AlphaMethod, StorageRecordsTheIntegratorState) {
  // (y, v, d, a): the storage holds 4f values per step, and psi matches the trapezoidal rule.
  ElasticPendulum problem;
  FullStorage storage;
  const IntegratorOptions options = alphaOptions(GetParam().method, GetParam().rho, 0.5, 1e-2);
  const GradientResult result =
      computeGradient(problem, ElasticPendulum::nominalParameters(), options, storage);
  EXPECT_EQ(storage.info().stateSize, 8);
  EXPECT_EQ(result.summary.method, GetParam().method);
  EXPECT_EQ(result.summary.steps, 50);
}

TEST(GeneralizedAlpha, CoefficientsFollowChungHulbertAndHht) {
  const auto ga = GeneralizedAlphaIntegrator::coefficients(IntegratorMethod::GeneralizedAlpha, 0.5);
  EXPECT_DOUBLE_EQ(ga.alphaM, 0.0);
  EXPECT_DOUBLE_EQ(ga.alphaF, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(ga.gamma, 0.5 + 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(ga.beta, 0.25 * (4.0 / 3.0) * (4.0 / 3.0));
  const auto hht = GeneralizedAlphaIntegrator::coefficients(IntegratorMethod::HhtAlpha, 0.5);
  EXPECT_DOUBLE_EQ(hht.alphaM, 0.0);
  EXPECT_DOUBLE_EQ(hht.alphaF, 1.0 / 3.0);  // HHT's alpha = -1/3: the most damped HHT
  const auto trapezoidal = GeneralizedAlphaIntegrator::coefficients(IntegratorMethod::GeneralizedAlpha, 1.0);
  EXPECT_DOUBLE_EQ(trapezoidal.alphaM, 0.5);
  EXPECT_DOUBLE_EQ(trapezoidal.alphaF, 0.5);
  EXPECT_DOUBLE_EQ(trapezoidal.gamma, 0.5);
  EXPECT_DOUBLE_EQ(trapezoidal.beta, 0.25);
}

TEST(GeneralizedAlpha, RejectsBadOptionsAndProblemsNamingTheCause) {
  Oscillator oscillator;
  const Vector p = Eigen::Vector3d(4.0, 0.1, 1.0);
  IntegratorOptions options = alphaOptions("generalized-alpha", 1.5, 1.0, 1e-2);
  std::string message = invalidArgumentMessage([&] { simulate(oscillator, p, options); });
  EXPECT_NE(message.find("IntegratorOptions.rhoInfinity = 1.5 must be in [0, 1]"), std::string::npos)
      << message;
  options = alphaOptions("hht-alpha", 0.3, 1.0, 1e-2);
  message = invalidArgumentMessage([&] { simulate(oscillator, p, options); });
  EXPECT_NE(message.find("[0.5, 1] for hht-alpha"), std::string::npos) << message;
  options = alphaOptions("generalized-alpha", 0.8, 1.0, 1e-2);
  options.adaptive = true;
  message = invalidArgumentMessage([&] { simulate(oscillator, p, options); });
  EXPECT_NE(message.find("no embedded error estimate"), std::string::npos) << message;
  ExponentialDecay firstOrder;
  message = invalidArgumentMessage(
      [&] { simulate(firstOrder, Eigen::Vector2d(1.0, 1.0), alphaOptions("hht-alpha", 0.8, 1.0, 1e-2)); });
  EXPECT_NE(message.find("SecondOrderProblem"), std::string::npos) << message;
  // Hermite interpolates with dx/dt, which generalized-alpha's (y, v, d, a) does not have.
  const std::unique_ptr<TrajectoryStorage> hermite = createStorage("hermite:every=4");
  message = invalidArgumentMessage(
      [&] { computeGradient(oscillator, p, alphaOptions("generalized-alpha", 0.8, 1.0, 1e-2), *hermite); });
  EXPECT_NE(message.find("needs the state derivative"), std::string::npos) << message;
  // The continuous adjoint records the problem state only; generalized-alpha carries more.
  FullStorage storage;
  message = invalidArgumentMessage([&] {
    computeGradientContinuous(oscillator, p, alphaOptions("generalized-alpha", 0.8, 1.0, 1e-2), storage);
  });
  EXPECT_NE(message.find("use the discrete adjoint"), std::string::npos) << message;
}

}  // namespace
}  // namespace hindsight
