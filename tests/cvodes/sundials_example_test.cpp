// SUNDIALS' own adjoint example cvsRoberts_ASAi_dns (among the serial CVODES examples of the SUNDIALS
// distribution; Debian: /usr/share/doc/libsundials-dev/examples/cvodes/serial/) reproduced with its
// settings: per-component absolute tolerances of the state, separate tolerances for the forward
// quadrature, the backward adjoint and the backward quadrature. The example prints, in its .out
// file, G = int_0^4e7 y3 dt = 3.9983e+07 and dG/dp = (7.6842e+05, -3.0691e+00, 5.1144e-04) (5
// significant digits) at p = (0.04, 1e4, 3e7).
#include <hindsight/problems/app/gradient_routes.h>

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

namespace hindsight {
namespace {

/// The example's problem, in its own parameter order (hindsight's Robertson orders and scales
/// differently): y1' = -p1 y1 + p2 y2 y3, y2' = p1 y1 - p2 y2 y3 - p3 y2^2, y3' = p3 y2^2,
/// y(0) = (1, 0, 0), G = int y3 dt, no terminal term.
class ExampleRobertson final : public Problem {
 public:
  std::string name() const override { return "cvsRoberts_ASAi_dns"; }
  int stateSize() const override { return 3; }
  int parameterSize() const override { return 3; }
  void initialState(ConstVectorRef, VectorRef z0) const override { z0 << 1.0, 0.0, 0.0; }
  void rhs(double, ConstVectorRef y, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
    const double r1 = p(0) * y(0), r2 = p(1) * y(1) * y(2), r3 = p(2) * y(1) * y(1);
    f << -r1 + r2, r1 - r2 - r3, r3;
  }
  void rhsJacobian(double, ConstVectorRef y, ConstVectorRef p, MatrixRef j,
                   ProblemWorkspace*) const override {
    j << -p(0), p(1) * y(2), p(1) * y(1),                      //
        p(0), -p(1) * y(2) - 2.0 * p(2) * y(1), -p(1) * y(1),  //
        0.0, 2.0 * p(2) * y(1), 0.0;
  }
  void addRhsParameterVjp(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace*) const override {
    out(0) += y(0) * (w(1) - w(0));
    out(1) += y(1) * y(2) * (w(0) - w(1));
    out(2) += y(1) * y(1) * (w(2) - w(1));
  }
  double integrand(double, ConstVectorRef y, ConstVectorRef, ProblemWorkspace*) const override {
    return y(2);
  }
  void addIntegrandStateGradient(double, ConstVectorRef, ConstVectorRef, double scale, VectorRef out,
                                 ProblemWorkspace*) const override {
    out(2) += scale;
  }
  void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                     ProblemWorkspace*) const override {}
};

const Vector kParameters = Eigen::Vector3d(0.04, 1e4, 3e7);
const Vector kExampleGradient = Eigen::Vector3d(7.6842e+05, -3.0691e+00, 5.1144e-04);
constexpr double kExampleObjective = 3.9983e+07;

/// The example's settings (cvsRoberts_ASAi_dns.c, SUNDIALS 6.4): RTOL = 1e-6 for everything (the
/// example's ewt function is rtol |y_i| + atol_i, i.e. CVodeSVtolerances), ATOL = (1e-8, 1e-14, 1e-6),
/// quadrature abstol 1e-6 with error control forward and backward, adjoint abstol ATOLl = 1e-8,
/// backward quadrature abstol 1e-6, BDF, Hermite interpolation, 150 steps between check points.
GradientOptions exampleOptions(AdjointMethod method) {
  GradientOptions options;
  options.adjoint = method;
  options.integrator.t1 = 4e7;
  options.cvodes.method = CvodesMethod::Bdf;
  options.cvodes.interpolation = CvodesInterpolation::Hermite;
  options.cvodes.checkpointSteps = 150;
  options.cvodes.relativeTolerance = 1e-6;
  options.cvodes.absoluteTolerances = {1e-8, 1e-14, 1e-6};
  options.cvodes.quadratureAbsoluteTolerance = 1e-6;
  options.cvodes.quadratureErrorControl = true;
  options.cvodes.backwardRelativeTolerance = 1e-6;
  options.cvodes.backwardAbsoluteTolerance = 1e-8;
  options.cvodes.backwardQuadratureAbsoluteTolerance = 1e-6;
  // The discrete adjoint: the same forward rtol and per-component atol on adaptive trbdf2.
  options.integrator.method = "trbdf2";
  options.integrator.adaptive = true;
  options.integrator.step = 1e-10;
  options.integrator.relativeTolerance = 1e-6;
  options.integrator.absoluteTolerances = {1e-8, 1e-14, 1e-6};
  return options;
}

void report(const char* route, const GradientResult& result) {
  std::cout << "[ cvsRoberts_ASAi_dns ] " << route << ": G = " << result.objective << ", dG/dp = ("
            << result.gradient.transpose() << "), steps " << result.summary.steps << ", rejected "
            << result.summary.rejectedSteps << "\n";
}

TEST(SundialsExample, CvodesRouteReproducesTheExamplesPrintedGradient) {
  ExampleRobertson problem;
  const GradientResult result =
      computeGradientByMethod(problem, kParameters, exampleOptions(AdjointMethod::Cvodes));
  report("cvodes", result);
  // The example steps past t1 and interpolates back (CV_NORMAL), hindsight stops at t1
  // (CVodeSetStopTime, one-step mode): a different last step, so the numbers agree to the
  // tolerances and the 5 printed digits, not to the bit.
  // The forward run is the example's: its .out reports 766 steps and 37 error-test failures, the
  // backward run 1 (SUNDIALS 6.4, the version whose example this is).
  EXPECT_EQ(result.summary.steps, 766);
  EXPECT_EQ(result.summary.rejectedSteps, 37 + 1);
  // Observed: G and dG/dp1, dG/dp2 within 2e-5 of the printed digits; dG/dp3 = 5.1148e-4 against the
  // printed 5.1144e-4 (8e-5 relative). That component is controlled by the backward quadrature's
  // abstolQB = 1e-6, i.e. only to ~2e-3 of its size, and the example's backward run stops at t = 40
  // on its way (CVodeB to TBout1), which changes the backward step sequence within that tolerance.
  EXPECT_NEAR(result.objective, kExampleObjective, 5e-5 * kExampleObjective);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(result.gradient(i), kExampleGradient(i), 2e-4 * std::abs(kExampleGradient(i)))
        << "p" << i + 1;
  }
}

/// The per-component atol is really used by `method`'s forward error test: with the scalar 1e-8 in
/// place of the example's atol_2 = 1e-14 (which resolves y2 ~ 1e-5 ... 1e-11) the step sequence
/// differs; per-component atol equal to the scalar gives the scalar run's bits.
void expectVectorToleranceIsUsed(AdjointMethod method, std::vector<double>& (*atol)(GradientOptions&)) {
  ExampleRobertson problem;
  const GradientOptions vector = exampleOptions(method);
  GradientOptions scalar = vector;
  atol(scalar).clear();
  scalar.cvodes.absoluteTolerance = scalar.integrator.absoluteTolerance = 1e-8;
  GradientOptions same = scalar;
  atol(same) = {1e-8, 1e-8, 1e-8};
  const GradientResult a = computeGradientByMethod(problem, kParameters, vector);
  const GradientResult b = computeGradientByMethod(problem, kParameters, scalar);
  const GradientResult c = computeGradientByMethod(problem, kParameters, same);
  EXPECT_NE(a.summary.steps, b.summary.steps);
  EXPECT_EQ(b.times, c.times);
  EXPECT_EQ(b.objective, c.objective);
  EXPECT_EQ(b.gradient, c.gradient);
}

TEST(SundialsExample, VectorToleranceChangesTheRunAndScalarOnesKeepIt) {
  expectVectorToleranceIsUsed(AdjointMethod::Cvodes, [](GradientOptions& o) -> std::vector<double>& {
    return o.cvodes.absoluteTolerances;
  });
  expectVectorToleranceIsUsed(AdjointMethod::Discrete, [](GradientOptions& o) -> std::vector<double>& {
    return o.integrator.absoluteTolerances;
  });
}

TEST(SundialsExample, DiscreteAdjointWithTheSameVectorTolerancesAgrees) {
  ExampleRobertson problem;
  const GradientResult result =
      computeGradientByMethod(problem, kParameters, exampleOptions(AdjointMethod::Discrete));
  report("discrete trbdf2", result);
  // trbdf2 is order 2 against CVODES' BDF up to order 5: at the same rtol its global error is
  // larger (see the printed numbers), so the bound is looser than the CVODES route's.
  // Observed: dG/dp1 = 768327 (1.2e-4 below), dG/dp2 = -3.06872 (1e-4), dG/dp3 = 5.11456e-4 (3e-5).
  EXPECT_NEAR(result.objective, kExampleObjective, 5e-5 * kExampleObjective);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(result.gradient(i), kExampleGradient(i), 5e-4 * std::abs(kExampleGradient(i)))
        << "p" << i + 1;
  }
}

TEST(SundialsExample, BadVectorTolerancesAreNamed) {
  ExampleRobertson problem;
  GradientOptions same = exampleOptions(AdjointMethod::Discrete);
  same.integrator.absoluteTolerances = {1e-8, 1e-8};
  try {
    computeGradientByMethod(problem, kParameters, same);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("IntegratorOptions.absoluteTolerances has 2 entries"),
              std::string::npos)
        << e.what();
  }
  same.integrator.absoluteTolerances = {1e-8, 0.0, 1e-8};
  try {
    computeGradientByMethod(problem, kParameters, same);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("IntegratorOptions.absoluteTolerances[1] = 0 must be positive"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace hindsight
