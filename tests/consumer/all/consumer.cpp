// Uses an installed hindsight with every component, as a user would: a problem from hindsight::classic,
// the three-route dispatcher of hindsight::app (its CVODES route from hindsight::cvodes) with a storage
// made from a spec string (hindsight::storage), and an MMA object from hindsight::topopt. Exit code 0
// only when the discrete and CVODES gradients of z' = -k z, psi = int z^2 dt agree with the closed form.
#include <hindsight/problems/app/gradient_routes.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/problems/topopt/mma.h>

#include <cmath>
#include <complex>
#include <cstdio>

int main() {
  const hindsight::ExponentialDecay problem;
  const double k = 2.0, a = 1.0, horizon = 1.0;
  hindsight::GradientOptions options;
  options.integrator.t1 = horizon;
  options.integrator.step = 1e-3;
  options.storage = "binomial:checkpoints=10";
  const hindsight::Vector p = Eigen::Vector2d(k, a);
  // dpsi/dk by complex step of the closed form: exact to round-off.
  const double h = 1e-30;
  const double exact = hindsight::ExponentialDecay::exactObjective(std::complex<double>(k, h),
                                                                   std::complex<double>(a), horizon)
                           .imag() /
                       h;
  int failures = 0;
  for (auto method : {hindsight::AdjointMethod::Discrete, hindsight::AdjointMethod::Cvodes}) {
    options.adjoint = method;
    options.cvodes.relativeTolerance = 1e-10;
    options.cvodes.absoluteTolerance = 1e-12;
    const auto result = hindsight::computeGradientByMethod(problem, p, options);
    const double error = std::abs(result.gradient(0) - exact) / std::abs(exact);
    std::printf("hindsight %s, %s route: dpsi/dk = %.12g, exact %.12g, relative error %.2e\n",
                hindsight::version(), hindsight::toString(method).c_str(), result.gradient(0), exact, error);
    failures += error < 1e-7 ? 0 : 1;
  }
  hindsight::MmaOptions mma;  // constructing it proves hindsight::topopt links
  (void)mma;
  return failures == 0 ? 0 : 1;
}
