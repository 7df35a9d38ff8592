// Small problems with known answers that exercise the engine: closed-form linear ODEs, a nonlinear
// pendulum whose mass matrix depends on the parameters, and Robertson's stiff chemical kinetics.
// They serve the tests, the benchmarks and the engine demo of the command-line tool.
#pragma once

#include <hindsight/engine/autodiff_problem.h>
#include <hindsight/engine/deterministic_math.h>
#include <hindsight/engine/second_order_problem.h>

#include <complex>

namespace hindsight {

/// z' = -k z, z(0) = a; psi = int_0^T z^2 dt. p = (k, a).
/// Closed form: psi = a^2 (1 - exp(-2kT)) / (2k).
class ExponentialDecay final : public Problem {
 public:
  std::string name() const override { return "exponential-decay"; }
  int stateSize() const override { return 1; }
  int parameterSize() const override { return 2; }
  void initialState(ConstVectorRef p, VectorRef z0) const override { z0(0) = p(1); }
  void addInitialStateVjp(ConstVectorRef, ConstVectorRef lambda0, VectorRef gradient) const override {
    gradient(1) += lambda0(0);
  }
  void rhs(double, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
    f(0) = -p(0) * z(0);
  }
  void rhsJacobian(double, ConstVectorRef, ConstVectorRef p, MatrixRef j, ProblemWorkspace*) const override {
    j(0, 0) = -p(0);
  }
  void addRhsParameterVjp(double, ConstVectorRef z, ConstVectorRef, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace*) const override {
    out(0) -= z(0) * w(0);
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

  /// The exact psi over [0, T]; templated so that complex-step differentiation gives the exact gradient.
  template <typename T>
  static T exactObjective(const T& k, const T& a, double horizon) {
    return a * a * (1.0 - std::exp(-2.0 * k * horizon)) / (2.0 * k);
  }
};

/// y'' + c y' + k y = 0, y(0) = y0, y'(0) = 0; psi = int_0^T y^2 dt. p = (k, c, y0); k > c^2/4.
/// Written as a SecondOrderProblem (M = 1) so it also tests the adapter.
class Oscillator final : public SecondOrderProblem {
 public:
  std::string name() const override { return "oscillator"; }
  int coordinateCount() const override { return 1; }
  int parameterSize() const override { return 3; }
  void initialCoordinates(ConstVectorRef p, VectorRef y0, VectorRef v0) const override {
    y0(0) = p(2);
    v0(0) = 0.0;
  }
  void addInitialCoordinatesVjp(ConstVectorRef, ConstVectorRef lambdaY, ConstVectorRef,
                                VectorRef gradient) const override {
    gradient(2) += lambdaY(0);
  }
  void massMatrix(double, ConstVectorRef, ConstVectorRef, MatrixRef mass, ProblemWorkspace*) const override {
    mass(0, 0) = 1.0;
  }
  void force(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef f,
             ProblemWorkspace*) const override {
    f(0) = -p(0) * y(0) - p(1) * v(0);
  }
  void residualJacobians(double, ConstVectorRef, ConstVectorRef, ConstVectorRef, ConstVectorRef p,
                         MatrixRef ry, MatrixRef rv, ProblemWorkspace*) const override {
    ry(0, 0) = p(0);
    rv(0, 0) = p(1);
  }
  void addResidualParameterVjp(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef, ConstVectorRef,
                               ConstVectorRef mu, VectorRef out, ProblemWorkspace*) const override {
    out(0) += y(0) * mu(0);
    out(1) += v(0) * mu(0);
  }
  double integrand(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef,
                   ProblemWorkspace*) const override {
    return y(0) * y(0);
  }
  void addIntegrandStateGradient(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef, double scale,
                                 VectorRef gy, VectorRef, ProblemWorkspace*) const override {
    gy(0) += scale * 2.0 * y(0);
  }
  void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, ConstVectorRef, double,
                                     VectorRef, ProblemWorkspace*) const override {}

  /// Exact psi: y = e^{st}(a cos wt + b sin wt), s = -c/2, w = sqrt(k - c^2/4), b = -s a / w, and
  /// y^2 = e^{2st}((a^2+b^2)/2 + (a^2-b^2)/2 cos 2wt + ab sin 2wt), integrated term by term.
  template <typename T>
  static T exactObjective(const T& k, const T& c, const T& y0, double horizon) {
    const T s = -c / 2.0;
    const T w = std::sqrt(k - c * c / 4.0);
    const T a = y0;
    const T b = -s * a / w;
    const T alpha = 2.0 * s;
    const T beta = 2.0 * w;
    const T e = std::exp(alpha * horizon);
    // int_0^T e^{alpha t} dt, with its series near alpha = 0.
    const T i0 =
        std::abs(alpha * horizon) < 1e-8 ? T(horizon) + alpha * horizon * horizon / 2.0 : (e - 1.0) / alpha;
    const T denominator = alpha * alpha + beta * beta;
    const T ic =
        (e * (alpha * std::cos(beta * horizon) + beta * std::sin(beta * horizon)) - alpha) / denominator;
    const T is =
        (e * (alpha * std::sin(beta * horizon) - beta * std::cos(beta * horizon)) + beta) / denominator;
    return (a * a + b * b) / 2.0 * i0 + (a * a - b * b) / 2.0 * ic + a * b * is;
  }
};

/// A damped pendulum m L^2 th'' = -m g L sin(th) - c th', th(0) = th0, th'(0) = 0;
/// psi = int th^2 dt + (1/2) th'(T)^2. p = (m, L, c, th0); g = 9.81. The mass matrix depends on p,
/// so the adapter's parameter path is exercised.
class Pendulum final : public SecondOrderProblem {
 public:
  static constexpr double kGravity = 9.81;
  std::string name() const override { return "pendulum"; }
  int coordinateCount() const override { return 1; }
  int parameterSize() const override { return 4; }
  void initialCoordinates(ConstVectorRef p, VectorRef y0, VectorRef v0) const override;
  void addInitialCoordinatesVjp(ConstVectorRef p, ConstVectorRef lambdaY, ConstVectorRef lambdaV,
                                VectorRef gradient) const override;
  void massMatrix(double t, ConstVectorRef y, ConstVectorRef p, MatrixRef mass,
                  ProblemWorkspace* ws) const override;
  void force(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef f,
             ProblemWorkspace* ws) const override;
  void residualJacobians(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                         MatrixRef ry, MatrixRef rv, ProblemWorkspace* ws) const override;
  void addResidualParameterVjp(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                               ConstVectorRef p, ConstVectorRef mu, VectorRef out,
                               ProblemWorkspace* ws) const override;
  double integrand(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                   ProblemWorkspace* ws) const override;
  void addIntegrandStateGradient(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, double scale,
                                 VectorRef gy, VectorRef gv, ProblemWorkspace* ws) const override;
  void addIntegrandParameterGradient(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                     double scale, VectorRef gp, ProblemWorkspace* ws) const override;
  double terminal(ConstVectorRef z, ConstVectorRef p) const override;
  void addTerminalGradient(ConstVectorRef z, ConstVectorRef p, VectorRef gz, VectorRef gp) const override;
};

/// The pendulum above in first-order form z = (th, v), written once for AutoDiffProblem:
/// F = (v, -(m g L sin(th) + c v) / (m L^2)), G = th^2, phi = v^2 / 2, z0 = (th0, 0). The same
/// problem as Pendulum with every derivative derived instead of written by hand; the tests compare
/// the two and the benchmarks measure what the derivation costs.
struct PendulumEquations {
  template <class T>
  void rhs(double, const T* z, const T* p, T* f) const {
    f[0] = z[1];
    f[1] = -(p[0] * Pendulum::kGravity * p[1] * dmath::sin(z[0]) + p[2] * z[1]) / (p[0] * p[1] * p[1]);
  }
  template <class T>
  T integrand(double, const T* z, const T*) const {
    return z[0] * z[0];
  }
  template <class T>
  T terminal(const T* z, const T*) const {
    return 0.5 * z[1] * z[1];
  }
  template <class T>
  void initialState(const T* p, T* z0) const {
    z0[0] = p[3];
    z0[1] = T(0.0);
  }
};
using AutoDiffPendulum = AutoDiffProblem<PendulumEquations, 2, 4>;

/// Robertson's stiff chemical kinetics (Robertson 1966; Hairer & Wanner, problem ROBER):
/// y1' = -k1 y1 + k3 y2 y3, y2' = k1 y1 - k2 y2^2 - k3 y2 y3, y3' = k2 y2^2, y(0) = (1, 0, 0).
/// psi = int_0^T y3 dt / T + y1(T). p = (k1, k2, k3), nominally (0.04, 3e7, 1e4). Its time scales
/// span from 1e-8 s to 1e5 s and more.
class Robertson final : public Problem {
 public:
  std::string name() const override { return "robertson"; }
  explicit Robertson(double horizon = 1e5) : horizon_(horizon) {}
  int stateSize() const override { return 3; }
  int parameterSize() const override { return 3; }
  static Vector nominalParameters() { return Eigen::Vector3d(0.04, 3e7, 1e4); }
  void initialState(ConstVectorRef p, VectorRef z0) const override;
  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace* ws) const override;
  void rhsJacobian(double t, ConstVectorRef z, ConstVectorRef p, MatrixRef j,
                   ProblemWorkspace* ws) const override;
  void addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace* ws) const override;
  double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace* ws) const override;
  void addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale, VectorRef out,
                                 ProblemWorkspace* ws) const override;
  void addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                     VectorRef out, ProblemWorkspace* ws) const override;
  double terminal(ConstVectorRef z, ConstVectorRef) const override { return z(0); }
  void addTerminalGradient(ConstVectorRef, ConstVectorRef, VectorRef gz, VectorRef) const override {
    gz(0) += 1.0;
  }

 private:
  double horizon_;
};

}  // namespace hindsight
