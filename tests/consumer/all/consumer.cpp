// Computes dpsi/dp of z' = -k z, psi = int z^2 dt, through the installed package, and checks it
// against the closed form: exit code 0 only when they agree.
#include <hindsight/engine/adjoint.h>
#include <hindsight/storage/storage_factory.h>

#include <cmath>
#include <cstdio>

class Decay final : public hindsight::Problem {
 public:
  std::string name() const override { return "decay"; }
  int stateSize() const override { return 1; }
  int parameterSize() const override { return 1; }
  void initialState(hindsight::ConstVectorRef, hindsight::VectorRef z0) const override { z0(0) = 1.0; }
  void rhs(double, hindsight::ConstVectorRef z, hindsight::ConstVectorRef p, hindsight::VectorRef f,
           hindsight::ProblemWorkspace*) const override {
    f(0) = -p(0) * z(0);
  }
  void rhsJacobian(double, hindsight::ConstVectorRef, hindsight::ConstVectorRef p, hindsight::MatrixRef j,
                   hindsight::ProblemWorkspace*) const override {
    j(0, 0) = -p(0);
  }
  void addRhsParameterVjp(double, hindsight::ConstVectorRef z, hindsight::ConstVectorRef,
                          hindsight::ConstVectorRef w, hindsight::VectorRef out,
                          hindsight::ProblemWorkspace*) const override {
    out(0) -= z(0) * w(0);
  }
  double integrand(double, hindsight::ConstVectorRef z, hindsight::ConstVectorRef,
                   hindsight::ProblemWorkspace*) const override {
    return z(0) * z(0);
  }
  void addIntegrandStateGradient(double, hindsight::ConstVectorRef z, hindsight::ConstVectorRef, double scale,
                                 hindsight::VectorRef out, hindsight::ProblemWorkspace*) const override {
    out(0) += 2.0 * scale * z(0);
  }
  void addIntegrandParameterGradient(double, hindsight::ConstVectorRef, hindsight::ConstVectorRef, double,
                                     hindsight::VectorRef, hindsight::ProblemWorkspace*) const override {}
};

int main() {
  Decay problem;
  hindsight::IntegratorOptions options;
  options.t1 = 1.0;
  options.step = 1e-3;
  auto storage = hindsight::createStorage("full");
  const double k = 2.0;
  const auto result = hindsight::computeGradient(problem, Eigen::VectorXd::Constant(1, k), options, *storage);
  // psi = (1 - e^{-2k}) / (2k); dpsi/dk = e^{-2k}/k - (1 - e^{-2k}) / (2k^2).
  const double exact = std::exp(-2 * k) / k - (1 - std::exp(-2 * k)) / (2 * k * k);
  const double error = std::abs(result.gradient(0) - exact) / std::abs(exact);
  std::printf("hindsight %s: dpsi/dk = %.12g, exact %.12g, relative error %.2e\n", hindsight::version(),
              result.gradient(0), exact, error);
  return error < 1e-10 ? 0 : 1;
}
