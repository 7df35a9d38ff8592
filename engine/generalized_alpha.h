// Generalized-alpha (Chung & Hulbert 1993) and HHT-alpha (Hilber, Hughes & Taylor 1977) for
// second-order systems M(t, y, p) ydd = f(t, y, v, p) (SecondOrderProblem), fixed step, with the exact
// discrete adjoint; one implementation of the Integrator interface (engine/integrator.h). The
// derivation is in docs/generalized_alpha.md.
//
// Step (the form of Arnold & Bruls 2007, which keeps order 2 for a configuration-dependent M): the
// state carried between steps is x = (y, v, d, a) with d = ydd the acceleration that satisfies the
// equations of motion and a the algorithmic acceleration. From x_n, with t' = t_n + h,
//   (1 - alpha_m) a_{n+1} + alpha_m a_n = (1 - alpha_f) d_{n+1} + alpha_f d_n,
//   y_{n+1} = y_n + h v_n + h^2 (1/2 - beta) a_n + h^2 beta a_{n+1},
//   v_{n+1} = v_n + h (1 - gamma) a_n + h gamma a_{n+1},
//   r(t', y_{n+1}, v_{n+1}, d_{n+1}) = M(t', y_{n+1}) d_{n+1} - f(t', y_{n+1}, v_{n+1}) = 0,
// solved for d_{n+1} by simplified Newton with S = M + h^2 beta c r_y + h gamma c r_v,
// c = (1 - alpha_f)/(1 - alpha_m). At t0, d_0 = a_0 = M^{-1} f(t0, y0, v0).
// Parameters from the spectral radius at infinity rho = IntegratorOptions::rhoInfinity:
//   "generalized-alpha": alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), rho in [0, 1];
//   "hht-alpha":         alpha_m = 0, alpha_f = (1 - rho)/(1 + rho), rho in [0.5, 1] (for constant M
//                        this is HHT: M a_{n+1} = (1 - alpha_f) f_{n+1} + alpha_f f_n);
//   both: gamma = 1/2 - alpha_m + alpha_f, beta = (1 - alpha_m + alpha_f)^2 / 4 (order 2, unconditionally
//   stable for linear problems; rho = 1 is the trapezoidal rule, no numerical damping).
//
// Objective quadrature: the trapezoidal rule in G over each step,
//   psi += h/2 (G(t_n, y_n, v_n) + G(t_{n+1}, y_{n+1}, v_{n+1})),
// second order like the step.
//
// Discrete adjoint: the exact transpose of this step map (implicit function theorem at the converged
// d_{n+1}, with the exact S, not the Newton iteration's), including the initial solve for d_0 and its
// dependence on p; the gradient is the derivative of the computed psi up to the Newton residual.
//
// State size 4f (f = coordinateCount()); the head (y, v) is the problem state z. No error estimate
// (fixed step only) and no state derivative (storages that interpolate, Hermite, are refused). The
// workspace is allocated in the constructor; step() and adjointStep() allocate nothing. The backward
// sweep of an exact storage passes x_{n+1} (adjointStepWithEnd): its d_{n+1} is the converged
// acceleration, so the backward step evaluates one Jacobian and no Newton iteration.
//
// References: J. Chung, G. M. Hulbert, J. Appl. Mech. 60 (1993) 371-375; H. M. Hilber, T. J. R.
// Hughes, R. L. Taylor, Earthq. Eng. Struct. Dyn. 5 (1977) 283-292; M. Arnold, O. Bruls, Multibody
// Syst. Dyn. 18 (2007) 185-202.
#pragma once

#include <hindsight/engine/integrator.h>
#include <hindsight/engine/second_order_problem.h>

#include <Eigen/LU>

#include <memory>

namespace hindsight {

class GeneralizedAlphaIntegrator final : public Integrator {
 public:
  struct Coefficients {
    double alphaM = 0.0, alphaF = 0.0, beta = 0.25, gamma = 0.5;
  };
  /// The coefficients of "generalized-alpha" or "hht-alpha" for rho_inf (see the file comment).
  static Coefficients coefficients(IntegratorMethod method, double rhoInfinity);

  /// Throws std::invalid_argument when p has the wrong size, the options are invalid or the method is
  /// not of this family.
  GeneralizedAlphaIntegrator(const SecondOrderProblem& problem, ConstVectorRef p,
                             const IntegratorOptions& options);
  ~GeneralizedAlphaIntegrator() override;

  const Coefficients& coefficients() const { return coefficients_; }

  std::string name() const override { return toString(method_); }
  IntegratorMethod method() const override { return method_; }
  int order() const override { return 2; }
  bool hasErrorEstimate() const override { return false; }
  int errorOrder() const override { return 0; }
  int stateSize() const override { return 4 * f_; }

  void initialState(double t0, VectorRef x) override;
  void addInitialStateVjp(double t0, ConstVectorRef x0, ConstVectorRef lambda, VectorRef gradient) override;
  double step(double t, double h, VectorRef x, double* errorNorm = nullptr) override;
  void adjointStep(double t, double h, ConstVectorRef x, VectorRef lambda, VectorRef gradient) override;
  /// x_{n+1} holds the converged acceleration d_{n+1} (the step stores accel_ there): no Newton solve.
  bool usesStepEnd() const override { return true; }
  void adjointStepWithEnd(double t, double h, ConstVectorRef x, ConstVectorRef xEnd, VectorRef lambda,
                          VectorRef gradient) override;

  bool hasStateDerivative() const override { return false; }
  /// Throws std::logic_error: not available (see the file comment).
  void stateDerivative(double t, ConstVectorRef x, VectorRef xdot) override;
  bool firstStageIsRhs() const override { return false; }
  Eigen::Ref<const Vector> lastFirstStage() const override { return work_; }

  const IntegratorCounters& counters() const override { return counters_; }

 private:
  /// yNext_, vNext_, aNext_ from x_n and the acceleration d_{n+1} in accel_.
  void kinematics(double h, ConstVectorRef x);
  /// Solves the step's residual for accel_ (and the kinematics) from x_n; x is not changed.
  void solveStep(double t, double h, ConstVectorRef x);
  /// The transpose of the step from x_n whose solution accel_, yNext_, vNext_, aNext_ is in place.
  void adjointAtSolution(double t, double h, ConstVectorRef x, VectorRef lambda, VectorRef gradient);
  /// S = M + betaPrime r_y + gammaPrime r_v at (t, y, v, accel) into lu_ (mass_, ry_, rv_ evaluated).
  void factorizeIterationMatrix(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef accel,
                                double betaPrime, double gammaPrime);

  const SecondOrderProblem& problem_;
  Vector p_;
  IntegratorOptions options_;
  IntegratorMethod method_;
  Coefficients coefficients_;
  std::unique_ptr<ProblemWorkspace> workspace_;  // the model's own (createModelWorkspace())
  int f_;
  Matrix mass_, ry_, rv_, iteration_;
  Eigen::PartialPivLU<Matrix> lu_;
  Vector force_, residual_, delta_, accel_, yNext_, vNext_, aNext_;
  Vector adjointY_, adjointV_, adjointA_, mu_, work_;
  IntegratorCounters counters_;
};

}  // namespace hindsight
