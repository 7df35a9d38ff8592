// The default time integration of the piston rod against a tight reference: psi1 and dpsi1/dx of the
// default configuration (docs/guides/performance.md) within 1e-4 (relative) of RK4 at h = 1e-4, which is
// converged to ~1e-11 (halving its step moves psi1 by less than that).
#include <hindsight/problems/app/piston_rod.h>

#include <gtest/gtest.h>

#include <cmath>

namespace hindsight {
namespace {

TEST(DefaultIntegration, Psi1AndItsGradientAreWithinTheDocumentedToleranceOfTheRk4Reference) {
  const Config defaults;
  ASSERT_NE(defaults.simulation.integrator, "rk4") << "the test compares two different integrations";
  Config reference = defaults;
  reference.simulation.integrator = "rk4";
  reference.simulation.step = 1e-4;
  const PistonRod fast(defaults), tight(reference);
  // A non-uniform design, so that no symmetry hides an error of the gradient.
  Vector x = fast.initialDesign();
  for (Eigen::Index i = 0; i < x.size(); ++i) x(i) = 0.5 + 0.3 * std::sin(0.37 * static_cast<double>(i));
  PistonRod::Request request;
  request.psi2 = false;
  request.psi2Gradient = false;
  const PistonRodEvaluation a = fast.evaluate(x, request);
  const PistonRodEvaluation b = tight.evaluate(x, request);
  const double psiError = std::abs(a.psi1 - b.psi1) / std::abs(b.psi1);
  const double gradientError = (a.dpsi1 - b.dpsi1).norm() / b.dpsi1.norm();
  std::cout << "default " << defaults.simulation.integrator << " h = " << fast.integratorOptions().step
            << ": psi1 relative error " << psiError << ", dpsi1/dx relative error (2-norm) " << gradientError
            << '\n';
  EXPECT_LT(psiError, 1e-4);
  EXPECT_LT(gradientError, 1e-4);
  // Not vacuous: the two integrations differ.
  EXPECT_GT(psiError, 1e-12);
}

}  // namespace
}  // namespace hindsight
