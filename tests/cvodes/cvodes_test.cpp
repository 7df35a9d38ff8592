// The CVODES route against closed forms (linear ODEs), against hindsight's discrete adjoint
// (nonlinear pendulum, stiff Robertson), and its failure modes: SUNDIALS flags become NumericalError
// with the flag's name and the time; bad options give std::invalid_argument naming the field.
#include <hindsight/cvodes/cvodes_adjoint.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/problems/classic/heat_equation.h>
#include "support/engine_fixtures.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

namespace hindsight {
namespace {

using testing::complexStepGradient;
using testing::gradientWithFullStorage;

struct Variant {
  CvodesMethod method;
  CvodesInterpolation interpolation;
};

class CvodesVariant : public ::testing::TestWithParam<Variant> {};

INSTANTIATE_TEST_SUITE_P(Cvodes, CvodesVariant,
                         ::testing::Values(Variant{CvodesMethod::Bdf, CvodesInterpolation::Hermite},
                                           Variant{CvodesMethod::Bdf, CvodesInterpolation::Polynomial},
                                           Variant{CvodesMethod::Adams, CvodesInterpolation::Hermite},
                                           Variant{CvodesMethod::Adams, CvodesInterpolation::Polynomial}),
                         [](const auto& info) {
                           return toString(info.param.method) + "_" + toString(info.param.interpolation);
                         });

CvodesOptions tightOptions(const Variant& variant, double t1) {
  CvodesOptions options;
  options.method = variant.method;
  options.interpolation = variant.interpolation;
  options.t1 = t1;
  options.relativeTolerance = 1e-10;
  options.absoluteTolerance = 1e-12;
  options.checkpointSteps = 50;
  return options;
}

TEST_P(CvodesVariant, ExponentialDecayMatchesClosedForm) {
  ExponentialDecay problem;
  const Vector p = Eigen::Vector2d(1.3, 0.7);
  const double horizon = 2.0;
  const GradientResult result = computeGradientCvodes(problem, p, tightOptions(GetParam(), horizon));
  const double exact = ExponentialDecay::exactObjective(p(0), p(1), horizon);
  const Vector exactGradient = complexStepGradient(
      [&](const Eigen::VectorXcd& x) { return ExponentialDecay::exactObjective(x(0), x(1), horizon); }, p);
  // Global errors of a variable-order multistep method run a few times above rtol = 1e-10.
  EXPECT_NEAR(result.objective, exact, 1e-8 * std::abs(exact));
  EXPECT_LT((result.gradient - exactGradient).norm(), 1e-7 * exactGradient.norm())
      << result.gradient.transpose() << " vs " << exactGradient.transpose();
  EXPECT_EQ(result.summary.adjoint, "cvodes");
  EXPECT_GT(result.summary.steps, 10);
  EXPECT_EQ(static_cast<std::int64_t>(result.times.size()), result.summary.steps + 1);
  EXPECT_EQ(result.times.back(), horizon);
  EXPECT_GT(result.summary.rhsEvaluations, result.summary.steps);
  EXPECT_GT(result.summary.jacobianEvaluations, 0);  // no VJP here: the backward rhs forms F_z
  EXPECT_GT(result.summary.newtonIterations, result.summary.steps);  // forward and backward iterations
  // The advised solvers: Newton with dense LU for BDF, fixed-point iteration (no linear solver) for Adams.
  if (GetParam().method == CvodesMethod::Bdf) {
    EXPECT_GT(result.summary.factorizations, 0);
  } else {
    EXPECT_EQ(result.summary.factorizations, 0);
  }
  EXPECT_EQ(result.summary.storage, "cvodes:checkpoints=50,interp=" + toString(GetParam().interpolation));
  EXPECT_GE(result.summary.statesStored, result.summary.steps / 50);
}

TEST_P(CvodesVariant, OscillatorMatchesClosedFormUndampedAndDamped) {
  Oscillator problem;
  const double horizon = 3.0;
  for (double damping : {0.0, 0.4}) {
    const Vector p = Eigen::Vector3d(4.0, damping, 0.8);
    const GradientResult result = computeGradientCvodes(problem, p, tightOptions(GetParam(), horizon));
    const double exact = Oscillator::exactObjective(p(0), p(1), p(2), horizon);
    const Vector exactGradient = complexStepGradient(
        [&](const Eigen::VectorXcd& x) { return Oscillator::exactObjective(x(0), x(1), x(2), horizon); }, p);
    EXPECT_NEAR(result.objective, exact, 1e-8 * std::abs(exact)) << "damping " << damping;
    // CV_HERMITE rebuilds z between backward steps by a cubic, whose O(h^4) error dominates when a
    // high-order Adams method takes long steps: observed 1.2e-7 relative for adams/hermite.
    const double tolerance = GetParam().interpolation == CvodesInterpolation::Hermite ? 1e-6 : 1e-7;
    EXPECT_LT((result.gradient - exactGradient).norm(), tolerance * exactGradient.norm())
        << "damping " << damping << ": " << result.gradient.transpose() << " vs "
        << exactGradient.transpose();
  }
}

TEST_P(CvodesVariant, LooseToleranceGivesAProportionatelyLooseGradient) {
  // The test above could not fail for a wrong tolerance wiring; this one checks that the error grows
  // when rtol is loosened and stays within a band around it.
  Oscillator problem;
  const Vector p = Eigen::Vector3d(4.0, 0.4, 0.8);
  const double horizon = 3.0;
  const Vector exactGradient = complexStepGradient(
      [&](const Eigen::VectorXcd& x) { return Oscillator::exactObjective(x(0), x(1), x(2), horizon); }, p);
  CvodesOptions options = tightOptions(GetParam(), horizon);
  options.relativeTolerance = 1e-4;
  options.absoluteTolerance = 1e-7;
  const GradientResult loose = computeGradientCvodes(problem, p, options);
  const double looseError = (loose.gradient - exactGradient).norm() / exactGradient.norm();
  const GradientResult tight = computeGradientCvodes(problem, p, tightOptions(GetParam(), horizon));
  const double tightError = (tight.gradient - exactGradient).norm() / exactGradient.norm();
  EXPECT_LT(looseError, 1e-2);
  EXPECT_GT(looseError, 100.0 * tightError);
  EXPECT_LT(loose.summary.steps, tight.summary.steps);
}

TEST(CvodesStiff, RobertsonBdfAgreesWithAdaptiveTrBdf2DiscreteAdjoint) {
  const double horizon = 1e5;
  Robertson problem(horizon);
  const Vector p = Robertson::nominalParameters();
  CvodesOptions options;
  options.method = CvodesMethod::Bdf;
  options.t1 = horizon;
  options.relativeTolerance = 1e-9;
  options.absoluteTolerance = 1e-14;
  options.checkpointSteps = 100;
  const GradientResult cvodes = computeGradientCvodes(problem, p, options);

  IntegratorOptions own;
  own.method = "trbdf2";
  own.t1 = horizon;
  own.adaptive = true;
  own.step = 1e-6;
  own.relativeTolerance = 1e-9;
  own.absoluteTolerance = 1e-14;
  const GradientResult discrete = gradientWithFullStorage(problem, p, own);

  // Many decades of step sizes in both.
  double smallest = 1e300, largest = 0.0;
  for (std::size_t i = 1; i < cvodes.times.size(); ++i) {
    smallest = std::min(smallest, cvodes.times[i] - cvodes.times[i - 1]);
    largest = std::max(largest, cvodes.times[i] - cvodes.times[i - 1]);
  }
  EXPECT_GT(largest / smallest, 1e8);
  EXPECT_NEAR(cvodes.objective, discrete.objective, 1e-6 * std::abs(discrete.objective));
  // dpsi/dk_i spans orders of magnitude (k2 = 3e7): compare component by component, relative to
  // the scale of the parameter, i.e. the logarithmic sensitivities k_i dpsi/dk_i.
  for (int i = 0; i < 3; ++i) {
    const double a = cvodes.gradient(i) * p(i), b = discrete.gradient(i) * p(i);
    std::cout << "[ robertson ] k" << i + 1 << " dpsi/dk: cvodes " << a << ", trbdf2 " << b << "\n";
    EXPECT_NEAR(a, b, 1e-4 * std::abs(b) + 1e-9) << "component " << i;
  }
}

TEST(CvodesSolvers, ExplicitNewtonAndFixedPointAgreeOnTheOscillatorAndReportTheirWork) {
  // The same problem with each nonlinear solver, for both families: the gradients agree with the
  // closed form, and the counters say which solver ran.
  Oscillator problem;
  const Vector p = Eigen::Vector3d(4.0, 0.4, 0.8);
  const double horizon = 3.0;
  const Vector exact = complexStepGradient(
      [&](const Eigen::VectorXcd& x) { return Oscillator::exactObjective(x(0), x(1), x(2), horizon); }, p);
  for (CvodesMethod method : {CvodesMethod::Adams, CvodesMethod::Bdf}) {
    for (CvodesNonlinearSolver solver : {CvodesNonlinearSolver::Newton, CvodesNonlinearSolver::FixedPoint}) {
      CvodesOptions options = tightOptions({method, CvodesInterpolation::Polynomial}, horizon);
      options.nonlinearSolver = solver;
      options.fixedPointAcceleration = method == CvodesMethod::Bdf ? 2 : 0;
      CvodesCounters counters;
      const GradientResult result = computeGradientCvodes(problem, p, options, &counters);
      const std::string label = toString(method) + "/" + toString(solver);
      EXPECT_LT((result.gradient - exact).norm(), 1e-7 * exact.norm()) << label;
      EXPECT_EQ(counters.nonlinearSolver, toString(solver)) << label;
      EXPECT_EQ(counters.backwardProducts, "dense") << label;  // Oscillator has no rhsStateVjp
      EXPECT_EQ(counters.stateVjps, 0) << label;
      EXPECT_EQ(counters.forwardRhsEvaluations + counters.recomputedRhsEvaluations,
                result.summary.rhsEvaluations)
          << label;
      EXPECT_GT(counters.recomputedRhsEvaluations, 0) << label;
      EXPECT_GT(counters.backwardQuadratureEvaluations, 0) << label;
      if (solver == CvodesNonlinearSolver::FixedPoint) {
        EXPECT_EQ(counters.linearSolver, "none") << label;
        EXPECT_EQ(result.summary.factorizations, 0) << label;
        EXPECT_EQ(counters.denseJacobians, counters.backwardRhsEvaluations) << label;  // only the rhs
      } else {
        EXPECT_EQ(counters.linearSolver, "dense") << label;
        EXPECT_GT(result.summary.factorizations, 0) << label;
        EXPECT_GT(counters.denseJacobians, counters.backwardRhsEvaluations) << label;  // plus the setups
      }
    }
  }
}

TEST(CvodesSolvers, ProblemWithoutDenseJacobianRunsMatrixFreeAndAgreesWithTheDiscreteAdjoint) {
  // The reaction-diffusion problem has only rhsStateVjp() and a tridiagonal Newton solver: CVODES runs
  // BDF with Newton-GMRES (backward Jacobian-times-vector by the VJP, forward by CVODES' difference
  // quotient) and Adams with fixed-point iteration, both with the VJP in the backward rhs, and never
  // forms F_z.
  HeatEquation problem(40, 2);
  const Vector p = problem.nominalParameters();
  const double horizon = 2.0;
  IntegratorOptions own;
  own.method = "trbdf2";
  own.t1 = horizon;
  own.adaptive = true;
  own.step = 1e-4;
  own.relativeTolerance = 1e-10;
  own.absoluteTolerance = 1e-12;
  const GradientResult discrete = gradientWithFullStorage(problem, p, own);
  for (CvodesMethod method : {CvodesMethod::Bdf, CvodesMethod::Adams}) {
    CvodesOptions options;
    options.method = method;
    options.t1 = horizon;
    options.relativeTolerance = 1e-9;
    options.absoluteTolerance = 1e-11;
    CvodesCounters counters;
    const GradientResult cvodes = computeGradientCvodes(problem, p, options, &counters);
    const std::string label = toString(method);
    EXPECT_LT((cvodes.gradient - discrete.gradient).norm(), 1e-6 * discrete.gradient.norm())
        << label << ": " << cvodes.gradient.transpose() << " vs " << discrete.gradient.transpose();
    EXPECT_NEAR(cvodes.objective, discrete.objective, 1e-7 * std::abs(discrete.objective)) << label;
    EXPECT_EQ(cvodes.summary.jacobianEvaluations, 0) << label;
    EXPECT_EQ(counters.denseJacobians, 0) << label;
    EXPECT_EQ(counters.backwardProducts, "vjp") << label;
    EXPECT_GE(counters.stateVjps, counters.backwardRhsEvaluations) << label;
    if (method == CvodesMethod::Bdf) {
      EXPECT_EQ(counters.linearSolver, "gmres") << label;
      EXPECT_GT(counters.backwardLinearIterations, 0) << label;
      EXPECT_GT(counters.stateVjps, counters.backwardRhsEvaluations) << label;  // GMRES products too
    } else {
      EXPECT_EQ(counters.linearSolver, "none") << label;
      EXPECT_EQ(counters.stateVjps, counters.backwardRhsEvaluations) << label;
    }
  }
  // The dense choices need the dense Jacobian it does not have: named, with what to use instead.
  CvodesOptions dense;
  dense.t1 = horizon;
  dense.linearSolver = CvodesLinearSolver::Dense;
  try {
    computeGradientCvodes(problem, p, dense);
    ADD_FAILURE() << "dense linear solver accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("CvodesOptions.linearSolver"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("gmres"), std::string::npos) << e.what();
  }
  dense.linearSolver = CvodesLinearSolver::Auto;
  dense.backwardProducts = CvodesBackwardProducts::Dense;
  try {
    computeGradientCvodes(problem, p, dense);
    ADD_FAILURE() << "dense backward products accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("CvodesOptions.backwardProducts"), std::string::npos) << e.what();
  }
  // Fixed point with the dense linear solver asked for: no linear solver is used, nothing is refused.
  dense.backwardProducts = CvodesBackwardProducts::Auto;
  dense.method = CvodesMethod::Adams;
  dense.linearSolver = CvodesLinearSolver::Dense;
  EXPECT_NO_THROW(computeGradientCvodes(problem, p, dense));
}

TEST(CvodesFailure, TooFewMaxStepsGivesNumericalErrorWithFlagNameAndTime) {
  Robertson problem(1e5);
  CvodesOptions options;
  options.t1 = 1e5;
  options.maxSteps = 20;
  try {
    computeGradientCvodes(problem, Robertson::nominalParameters(), options);
    FAIL() << "no NumericalError";
  } catch (const NumericalError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("CV_TOO_MUCH_WORK"), std::string::npos) << message;
    EXPECT_NE(message.find("CVodeF"), std::string::npos) << message;
    EXPECT_GT(e.time(), 0.0);
    EXPECT_LT(e.time(), 1e5);
  }
}

TEST(CvodesFailure, BackwardMaxStepsGivesTheSundialsFlagAndTime) {
  // z' = -z is easy forward, but G = sin(omega t) z forces lambda at omega = 1e4, so the backward
  // problem needs far more steps than the forward one (quadratures out of the error test). CVodeB
  // then returns CV_TOO_MUCH_WORK somewhere inside (t0, t1).
  class ForcedAdjoint final : public Problem {
   public:
    std::string name() const override { return "forced-adjoint"; }
    int stateSize() const override { return 1; }
    int parameterSize() const override { return 1; }
    void initialState(ConstVectorRef, VectorRef z0) const override { z0(0) = 1.0; }
    void rhs(double, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
      f(0) = -p(0) * z(0);
    }
    void rhsJacobian(double, ConstVectorRef, ConstVectorRef p, MatrixRef j,
                     ProblemWorkspace*) const override {
      j(0, 0) = -p(0);
    }
    void addRhsParameterVjp(double, ConstVectorRef z, ConstVectorRef, ConstVectorRef w, VectorRef out,
                            ProblemWorkspace*) const override {
      out(0) -= z(0) * w(0);
    }
    double integrand(double t, ConstVectorRef z, ConstVectorRef, ProblemWorkspace*) const override {
      return std::sin(1e4 * t) * z(0);
    }
    void addIntegrandStateGradient(double t, ConstVectorRef, ConstVectorRef, double scale, VectorRef out,
                                   ProblemWorkspace*) const override {
      out(0) += scale * std::sin(1e4 * t);
    }
    void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                       ProblemWorkspace*) const override {}
  } problem;
  CvodesOptions options;
  options.quadratureErrorControl = false;
  options.maxSteps = 300;
  try {
    computeGradientCvodes(problem, Vector::Ones(1), options);
    FAIL() << "no NumericalError";
  } catch (const NumericalError& e) {
    const std::string message = e.what();
    std::cout << "[ message ] " << message << "\n";
    EXPECT_NE(message.find("CVodeB failed with CV_TOO_MUCH_WORK"), std::string::npos) << message;
    EXPECT_GT(e.time(), 0.0) << message;
    EXPECT_LT(e.time(), 1.0) << message;
  }
}

TEST(CvodesFailure, ExceptionInsideACallbackIsRethrown) {
  // A problem that throws in its rhs beyond t = 0.5: CVODES must stop and the exception come out.
  class Throwing final : public Problem {
   public:
    std::string name() const override { return "throwing"; }
    int stateSize() const override { return 1; }
    int parameterSize() const override { return 1; }
    void initialState(ConstVectorRef, VectorRef z0) const override { z0(0) = 1.0; }
    void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
      if (t > 0.5) throw NumericalError("model evaluation failed", t);
      f(0) = -p(0) * z(0);
    }
    void rhsJacobian(double, ConstVectorRef, ConstVectorRef p, MatrixRef j,
                     ProblemWorkspace*) const override {
      j(0, 0) = -p(0);
    }
    void addRhsParameterVjp(double, ConstVectorRef z, ConstVectorRef, ConstVectorRef w, VectorRef out,
                            ProblemWorkspace*) const override {
      out(0) -= z(0) * w(0);
    }
    double integrand(double, ConstVectorRef z, ConstVectorRef, ProblemWorkspace*) const override {
      return z(0);
    }
    void addIntegrandStateGradient(double, ConstVectorRef, ConstVectorRef, double scale, VectorRef out,
                                   ProblemWorkspace*) const override {
      out(0) += scale;
    }
    void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                       ProblemWorkspace*) const override {}
  } problem;
  CvodesOptions options;
  try {
    computeGradientCvodes(problem, Vector::Ones(1), options);
    FAIL() << "no exception";
  } catch (const NumericalError& e) {
    EXPECT_NE(std::string(e.what()).find("model evaluation failed"), std::string::npos) << e.what();
    EXPECT_GT(e.time(), 0.5);
  }
}

std::string invalidArgumentMessage(const CvodesOptions& options) {
  ExponentialDecay problem;
  try {
    computeGradientCvodes(problem, Eigen::Vector2d(1.0, 1.0), options);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "<no std::invalid_argument thrown>";
}

TEST(CvodesBadInput, EveryBadFieldIsNamedWithItsRange) {
  struct Case {
    std::function<void(CvodesOptions&)> spoil;
    std::string field;
    std::string range;
  };
  const std::vector<Case> cases = {
      {[](CvodesOptions& o) { o.relativeTolerance = 0.0; }, "relativeTolerance", "[1e-14, 1)"},
      {[](CvodesOptions& o) { o.relativeTolerance = 2.0; }, "relativeTolerance", "[1e-14, 1)"},
      {[](CvodesOptions& o) { o.absoluteTolerance = -1.0; }, "absoluteTolerance", "positive"},
      {[](CvodesOptions& o) {
         o.absoluteTolerances = {1e-8, -1.0};
       },
       "absoluteTolerances[1] = -1", "positive"},
      {[](CvodesOptions& o) { o.quadratureRelativeTolerance = 2.0; }, "quadratureRelativeTolerance",
       "[1e-14, 1)"},
      {[](CvodesOptions& o) { o.quadratureAbsoluteTolerance = -1.0; }, "quadratureAbsoluteTolerance",
       "positive"},
      {[](CvodesOptions& o) { o.backwardRelativeTolerance = 1e-20; }, "backwardRelativeTolerance",
       "[1e-14, 1)"},
      {[](CvodesOptions& o) { o.backwardAbsoluteTolerance = -1.0; }, "backwardAbsoluteTolerance", "positive"},
      {[](CvodesOptions& o) { o.backwardAbsoluteTolerances = {0.0}; }, "backwardAbsoluteTolerances[0] = 0",
       "positive"},
      {[](CvodesOptions& o) { o.backwardQuadratureRelativeTolerance = -1.0; },
       "backwardQuadratureRelativeTolerance", "[1e-14, 1)"},
      {[](CvodesOptions& o) { o.backwardQuadratureAbsoluteTolerance = NAN; },
       "backwardQuadratureAbsoluteTolerance", "positive"},
      {[](CvodesOptions& o) { o.checkpointSteps = 0; }, "checkpointSteps", "[1, 1e9]"},
      {[](CvodesOptions& o) { o.maxSteps = 0; }, "maxSteps", "[1, 1e12]"},
      {[](CvodesOptions& o) { o.initialStep = 5.0; }, "initialStep", "[0, t1 - t0"},
      {[](CvodesOptions& o) { o.t1 = o.t0; }, "t1", "greater than t0"},
      {[](CvodesOptions& o) { o.fixedPointAcceleration = -1; }, "fixedPointAcceleration", "[0, 20]"},
      {[](CvodesOptions& o) { o.fixedPointAcceleration = 21; }, "fixedPointAcceleration", "[0, 20]"},
  };
  for (const Case& c : cases) {
    CvodesOptions options;
    c.spoil(options);
    std::string error;
    EXPECT_FALSE(options.IsValid(&error)) << c.field;
    const std::string message = invalidArgumentMessage(options);
    EXPECT_NE(message.find(c.field), std::string::npos) << message;
    EXPECT_NE(message.find(c.range), std::string::npos) << message;
    EXPECT_EQ(message, error);
  }
  EXPECT_TRUE(CvodesOptions{}.IsValid(nullptr));
}

TEST(CvodesBadInput, WrongParameterSizeAndUnknownNames) {
  ExponentialDecay problem;
  EXPECT_THROW(computeGradientCvodes(problem, Vector::Ones(3), CvodesOptions{}), std::invalid_argument);
  CvodesOptions options;
  options.absoluteTolerances = {1e-8, 1e-8, 1e-8};  // ExponentialDecay has one state
  try {
    computeGradientCvodes(problem, Vector::Ones(problem.parameterSize()), options);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("CvodesOptions.absoluteTolerances has 3 entries"), std::string::npos)
        << e.what();
  }
  // A VJP asked of a problem without one.
  CvodesOptions vjp;
  vjp.backwardProducts = CvodesBackwardProducts::Vjp;
  try {
    computeGradientCvodes(problem, Vector::Ones(problem.parameterSize()), vjp);
    ADD_FAILURE() << "vjp accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("CvodesOptions.backwardProducts = vjp"), std::string::npos)
        << e.what();
  }
  for (const std::string name : {"auto", "newton", "fixed-point"})
    EXPECT_EQ(toString(parseCvodesNonlinearSolver(name)), name);
  for (const std::string name : {"auto", "dense", "gmres"})
    EXPECT_EQ(toString(parseCvodesLinearSolver(name)), name);
  for (const std::string name : {"auto", "vjp", "dense"})
    EXPECT_EQ(toString(parseCvodesBackwardProducts(name)), name);
  EXPECT_THROW(parseCvodesNonlinearSolver("functional"), std::invalid_argument);
  EXPECT_THROW(parseCvodesLinearSolver("klu"), std::invalid_argument);
  EXPECT_THROW(parseCvodesBackwardProducts("ad"), std::invalid_argument);
  EXPECT_THROW(parseCvodesMethod("rk4"), std::invalid_argument);
  EXPECT_THROW(parseCvodesInterpolation("linear"), std::invalid_argument);
  EXPECT_EQ(parseCvodesMethod("adams"), CvodesMethod::Adams);
  EXPECT_EQ(parseCvodesInterpolation("polynomial"), CvodesInterpolation::Polynomial);
}

}  // namespace
}  // namespace hindsight
