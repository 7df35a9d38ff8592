// The CVODES route on the reduced piston rod, configured as the CVODES user guide advises: the backward
// right-hand side by the rod's vector-Jacobian product gives the gradient of the dense path within the
// integration tolerance while forming no Jacobian, and the fixed-point Adams route converges on the rod and
// agrees with a tight discrete adjoint. Reference: the discrete adjoint of rk4 at h = 2e-5 (rk4's error is
// O(h^4), far below the CVODES tolerances used here).
#include <hindsight/cvodes/cvodes_adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/app/config.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/invariants.h>
#include <hindsight/problems/rod/modal_reduction.h>
#include "support/slider_crank.h"

#include <gtest/gtest.h>

#include <iostream>
#include <memory>

namespace hindsight::rod {
namespace {

constexpr double kEndTime = 0.5;  // within the crank's ramp: the rod accelerates throughout

struct Rod {
  std::unique_ptr<SliderCrankProblem> problem;
  Vector p;
  Vector reference;
};

/// The reduced rod of a coarse initial design (40x4 elements, 6 modes, ramp over 1 s), built like
/// PistonRod builds it.
const Rod& rod() {
  static const Rod r = [] {
    Config config;
    config.rod.elementsAlongLength = 40;
    config.rod.elementsThroughHeight = 4;
    config.rod.modeCount = 6;
    config.rod.rampTime = 1.0;
    const RodConfig& rc = config.rod;
    const Vector x = Vector::Constant(rc.designCount(), rc.initialDesign);
    const FeModel model(rc, x);
    const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(rc));
    CrankMotion crank;
    crank.radius = rc.crankRadius;
    crank.omega = rc.crankSpeed;
    crank.rampTime = rc.rampTime;
    Rod out;
    out.problem = std::make_unique<SliderCrankProblem>(basis.columnCount(), rc.length, crank);
    out.p = computeInvariants(model, basis).pack();
    IntegratorOptions rk4;
    rk4.method = "rk4";
    rk4.t1 = kEndTime;
    rk4.step = 2e-5;
    FullStorage storage;
    out.reference = computeGradient(*out.problem, out.p, rk4, storage).gradient;
    return out;
  }();
  return r;
}

CvodesOptions options(CvodesMethod method, CvodesBackwardProducts products) {
  CvodesOptions o;
  o.method = method;
  o.t1 = kEndTime;
  o.relativeTolerance = 1e-8;
  o.absoluteTolerance = 1e-12;
  o.backwardProducts = products;
  return o;
}

double relativeError(const Vector& a, const Vector& b) { return (a - b).norm() / b.norm(); }

TEST(CvodesRod, VjpPathGivesTheDenseGradientWithinTheToleranceAndFormsNoJacobianInTheBackwardRhs) {
  const Rod& r = rod();
  ASSERT_TRUE(r.problem->hasStateVjp());
  for (CvodesMethod method : {CvodesMethod::Adams, CvodesMethod::Bdf}) {
    CvodesCounters vjpCounters, denseCounters;
    const GradientResult vjp =
        computeGradientCvodes(*r.problem, r.p, options(method, CvodesBackwardProducts::Auto), &vjpCounters);
    const GradientResult dense = computeGradientCvodes(
        *r.problem, r.p, options(method, CvodesBackwardProducts::Dense), &denseCounters);
    const std::string label = toString(method);
    const double difference = relativeError(vjp.gradient, dense.gradient);
    const double error = relativeError(vjp.gradient, r.reference);
    std::cout << "[ rod ] " << label << ": |g_vjp - g_dense|/|g| = " << difference
              << ", |g_vjp - g_ref|/|g_ref| = " << error << ", backward rhs "
              << vjpCounters.backwardRhsEvaluations << ", VJPs " << vjpCounters.stateVjps << ", dense F_z "
              << vjpCounters.denseJacobians << " (dense path " << denseCounters.denseJacobians << ")\n";
    // The two paths differ by round-off in lambda', which can move CVODES' step choices: they agree to
    // the tolerance, not to the bit. Measured: 1.9e-11 (Adams) and 2.2e-13 (BDF) apart, 4.5e-10 and
    // 3.8e-10 from the reference; a wrong term would be off by 1e-2 or more.
    EXPECT_LT(difference, 1e-9) << label;
    EXPECT_LT(error, 1e-8) << label;
    EXPECT_LT(relativeError(dense.gradient, r.reference), 1e-8) << label;
    EXPECT_EQ(vjp.objective, dense.objective) << label;  // the forward phase is the same run
    EXPECT_EQ(vjpCounters.backwardProducts, "vjp") << label;
    EXPECT_EQ(denseCounters.backwardProducts, "dense") << label;
    EXPECT_EQ(vjpCounters.stateVjps, vjpCounters.backwardRhsEvaluations) << label;
    EXPECT_GT(vjpCounters.backwardRhsEvaluations, vjp.summary.steps) << label;
    // The dense path forms F_z at every backward rhs; the VJP path only where Newton needs a matrix.
    EXPECT_GE(denseCounters.denseJacobians, denseCounters.backwardRhsEvaluations) << label;
    if (method == CvodesMethod::Adams) {
      EXPECT_EQ(vjpCounters.denseJacobians, 0) << label;  // fixed point: no Jacobian at all
      EXPECT_EQ(vjp.summary.jacobianEvaluations, 0) << label;
    } else {
      EXPECT_GT(vjpCounters.denseJacobians, 0) << label;  // the Newton matrices at the setups
      EXPECT_LT(vjpCounters.denseJacobians, vjpCounters.backwardRhsEvaluations / 5) << label;
    }
  }
}

TEST(CvodesRod, FixedPointAdamsConvergesOnTheRodAndMatchesTheDiscreteAdjoint) {
  const Rod& r = rod();
  for (int acceleration : {0, 3}) {
    CvodesOptions o = options(CvodesMethod::Adams, CvodesBackwardProducts::Auto);
    o.fixedPointAcceleration = acceleration;
    CvodesCounters counters;
    const GradientResult result = computeGradientCvodes(*r.problem, r.p, o, &counters);
    const double error = relativeError(result.gradient, r.reference);
    std::cout << "[ rod ] adams fixed point, Anderson m = " << acceleration << ": error " << error
              << ", steps " << result.summary.steps << ", iterations " << counters.forwardNonlinearIterations
              << " + " << counters.backwardNonlinearIterations << ", convergence failures "
              << counters.forwardConvergenceFailures << " + " << counters.backwardConvergenceFailures << "\n";
    EXPECT_EQ(counters.nonlinearSolver, "fixed-point");
    EXPECT_EQ(counters.linearSolver, "none");
    EXPECT_EQ(result.summary.factorizations, 0);
    EXPECT_EQ(result.summary.jacobianEvaluations, 0);
    EXPECT_LT(error, 1e-8) << "m = " << acceleration;
    // Converged iterations: on average well under CVODES' limit of 3 per step (NLS_MAXCOR).
    EXPECT_LT(counters.forwardNonlinearIterations, 3 * result.summary.steps);
    EXPECT_GE(counters.forwardNonlinearIterations, result.summary.steps);
  }
}

TEST(CvodesRod, MatrixFreeNewtonGmresBdfAgreesOnTheRod) {
  const Rod& r = rod();
  CvodesOptions o = options(CvodesMethod::Bdf, CvodesBackwardProducts::Auto);
  o.linearSolver = CvodesLinearSolver::Gmres;
  CvodesCounters counters;
  const GradientResult result = computeGradientCvodes(*r.problem, r.p, o, &counters);
  EXPECT_LT(relativeError(result.gradient, r.reference), 1e-8);
  EXPECT_EQ(result.summary.jacobianEvaluations, 0);
  EXPECT_EQ(counters.linearSolver, "gmres");
  EXPECT_GT(counters.backwardLinearIterations, 0);
  EXPECT_GT(counters.stateVjps, counters.backwardRhsEvaluations);  // the GMRES products are VJPs too
}

}  // namespace
}  // namespace hindsight::rod
