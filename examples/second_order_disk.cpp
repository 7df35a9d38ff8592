// A two-mass chain, wall -k1- m1 -k2- m2, with a hardening spring k1 (1 + 100 y1^2) and a damper c
// on m2, integrated with generalized-alpha; dpsi/dp of psi = int y2^2 dt by the discrete adjoint,
// with the trajectory (y, v, d, a per step) kept in a compressed file on disk, checked against central
// differences of the computed psi. p = (m1, m2, k1, k2, c).
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/engine/second_order_problem.h>
#include <hindsight/storage/storage_factory.h>

#include <cstdio>
#include <filesystem>

using namespace hindsight;

class TwoMassChain final : public SecondOrderProblem {
 public:
  std::string name() const override { return "two-mass-chain"; }
  int coordinateCount() const override { return 2; }
  int parameterSize() const override { return 5; }
  void initialCoordinates(ConstVectorRef, VectorRef y0, VectorRef v0) const override {
    y0 << 0.1, 0.0;
    v0.setZero();
  }
  void massMatrix(double, ConstVectorRef, ConstVectorRef p, MatrixRef m, ProblemWorkspace*) const override {
    m << p(0), 0.0, 0.0, p(1);
  }
  void force(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef f,
             ProblemWorkspace*) const override {
    f << -p(2) * y(0) * (1.0 + 100.0 * y(0) * y(0)) - p(3) * (y(0) - y(1)),
        -p(3) * (y(1) - y(0)) - p(4) * v(1);
  }
  void residualJacobians(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef, ConstVectorRef p,
                         MatrixRef ry, MatrixRef rv, ProblemWorkspace*) const override {
    ry << p(2) * (1.0 + 300.0 * y(0) * y(0)) + p(3), -p(3), -p(3), p(3);
    rv << 0.0, 0.0, 0.0, p(4);
  }
  void addResidualParameterVjp(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef,
                               ConstVectorRef mu, VectorRef out, ProblemWorkspace*) const override {
    out(0) += a(0) * mu(0);
    out(1) += a(1) * mu(1);
    out(2) += y(0) * (1.0 + 100.0 * y(0) * y(0)) * mu(0);
    out(3) += (y(0) - y(1)) * (mu(0) - mu(1));
    out(4) += v(1) * mu(1);
  }
  double integrand(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef,
                   ProblemWorkspace*) const override {
    return y(1) * y(1);
  }
  void addIntegrandStateGradient(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef, double scale,
                                 VectorRef gy, VectorRef, ProblemWorkspace*) const override {
    gy(1) += 2.0 * scale * y(1);
  }
  void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, ConstVectorRef, double,
                                     VectorRef, ProblemWorkspace*) const override {}
};

int main() {
  TwoMassChain problem;
  const Vector p{{1.0, 0.5, 40.0, 20.0, 0.3}};
  IntegratorOptions options;
  options.method = "generalized-alpha";
  options.rhoInfinity = 0.8;
  options.t1 = 5.0;
  options.step = 1e-3;
  auto storage = createStorage("disk:dir=" + std::filesystem::temp_directory_path().string() + ",level=3");
  const GradientResult result = computeGradient(problem, p, options, *storage);
  std::printf("psi = %.12g\ndpsi/dp =", result.objective);
  for (Eigen::Index i = 0; i < result.gradient.size(); ++i) std::printf(" %.9g", result.gradient(i));
  std::printf("\nsteps: %lld, bytes on disk: %lld\n", static_cast<long long>(result.summary.steps),
              static_cast<long long>(result.summary.bytesOnDisk));
  // The adjoint is the derivative of the psi computed: central differences of that psi confirm it.
  const auto psi = [&](const Vector& q) { return simulate(problem, q, options).objective; };
  const GradientCheckResult check = checkGradient(psi, p, result.gradient, {1e-6});
  std::printf("finite-difference check: %s, %s\n", check.passed ? "passed" : "FAILED", check.message.c_str());
  return check.passed ? 0 : 1;
}
