// Your own ODE: write F, G and z0 once; AutoDiffProblem derives every derivative, the discrete adjoint
// runs over binomial checkpointing (20 checkpoints), and central differences confirm the gradient.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/autodiff_problem.h>
#include <hindsight/engine/gradient_checker.h>
#include <hindsight/storage/storage_factory.h>

#include <iostream>

// Lotka-Volterra, prey z0, predators z1, p = (a, b, c, d); psi = int_0^10 (z0 - c/d)^2 dt (c/d: equilibrium).
struct PredatorPrey {
  template <class T>
  void rhs(double, const T* z, const T* p, T* f) const {
    f[0] = p[0] * z[0] - p[1] * z[0] * z[1];
    f[1] = p[3] * z[0] * z[1] - p[2] * z[1];
  }
  template <class T>
  T integrand(double, const T* z, const T* p) const {
    return (z[0] - p[2] / p[3]) * (z[0] - p[2] / p[3]);
  }
  void initialState(const double*, double* z0) const { z0[0] = 2.0, z0[1] = 1.0; }
};

int main() {
  using namespace hindsight;
  const AutoDiffProblem<PredatorPrey, 2, 4> problem("predator-prey");
  const Vector p = Eigen::Vector4d(1.0, 0.5, 1.0, 1.0);
  IntegratorOptions options;  // rk4 with a fixed step of 1e-3
  options.t1 = 10.0;
  const auto storage = createStorage("binomial:checkpoints=20");
  const GradientResult result = computeGradient(problem, p, options, *storage);
  std::cout << "psi = " << result.objective << ", dpsi/dp = " << result.gradient.transpose() << " ("
            << result.summary.recomputedSteps << " steps recomputed)\n";
  const auto psi = [&](const Vector& q) { return simulate(problem, q, options).objective; };
  const GradientCheckResult check = checkGradient(psi, p, result.gradient, {1e-6});
  std::cout << "finite-difference check: " << (check.passed ? "passed" : "FAILED") << ", " << check.message
            << "\n";
  return check.passed ? 0 : 1;
}
