// Runge-Kutta integrators with discrete adjoints (docs/design.md §5), one implementation of the
// Integrator interface (engine/integrator.h); the integrator's state is the problem state z.
//
// One class covers explicit and diagonally implicit Runge-Kutta methods given by a Butcher tableau:
//   Z_i = z_n + h sum_j a_ij K_j,   K_i = F(t_n + c_i h, Z_i, p),   z_{n+1} = z_n + h sum_i b_i K_i,
// with the objective integrated by the same quadrature, psi += h sum_i b_i G(t_n + c_i h, Z_i, p).
// The discrete adjoint is the exact transpose of this map (Hager 2000; Sandu 2006): for stages in
// reverse order,
//   r_i = h b_i lambda + h sum_{j>i} a_ji Zbar_j,
//   (I - h a_ii F_z(Z_i))^T Zbar_i = F_z(Z_i)^T r_i + h b_i G_z(Z_i)^T,
//   Kbar_i = r_i + h a_ii Zbar_i,   gradient += F_p(Z_i)^T Kbar_i + h b_i G_p(Z_i)^T,
// then lambda_n = lambda_{n+1} + sum_i Zbar_i. The stages are recomputed from z_n with the same code
// path as the forward step, so they are the same bits. Implicit stages are solved by simplified
// Newton to a tight tolerance; the adjoint uses the exact Jacobian at the converged stage (implicit
// function theorem), so the gradient is the derivative of the computed psi up to the Newton residual.
//
// Methods: "rk4" (classic, order 4, fixed step), "dopri5" (Dormand-Prince 5(4), adaptive),
// "trbdf2" (TR-BDF2 as an L-stable ESDIRK, order 2 with an order-3 embedded estimate; Hosea & Shampine
// 1996), "sdirk2" (Alexander's L-stable 2-stage SDIRK, order 2, fixed step), "midpoint" (implicit
// midpoint, order 2, symplectic, fixed step). Adaptive stepping needs an embedded pair; the error
// norm is weightedRmsNorm() of engine/step_controller.h.
//
// The integrator owns a workspace allocated in its constructor; step() and adjointStep() allocate
// nothing (a test checks this with a counting operator new).
#pragma once

#include <hindsight/engine/integrator.h>

#include <Eigen/LU>

#include <memory>
#include <string>
#include <vector>

namespace hindsight {

/// A Butcher tableau, optionally with an embedded weight vector for error estimation.
struct ButcherTableau {
  std::string name;
  Matrix a;
  Vector b, c;
  Vector bEmbedded;  ///< empty: no error estimate, fixed step only
  int order = 0;
  int embeddedOrder = 0;
  bool isExplicit() const;
  /// The tableau of a Runge-Kutta method; throws std::invalid_argument for another family.
  static ButcherTableau byMethod(IntegratorMethod method);
  /// Looks up a method by name; throws std::invalid_argument listing the known ones.
  static ButcherTableau byName(const std::string& name);
  /// The Runge-Kutta method names (a subset of integratorMethodNames()).
  static std::vector<std::string> names();
};

class RungeKuttaIntegrator final : public Integrator {
 public:
  /// Throws std::invalid_argument when p has the wrong size, the options are invalid or the method
  /// is not a Runge-Kutta method.
  RungeKuttaIntegrator(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options);
  ~RungeKuttaIntegrator() override;

  const ButcherTableau& tableau() const { return tableau_; }
  const IntegratorOptions& options() const { return options_; }

  std::string name() const override { return tableau_.name; }
  IntegratorMethod method() const override { return method_; }
  int order() const override { return tableau_.order; }
  bool hasErrorEstimate() const override { return tableau_.bEmbedded.size() > 0; }
  int errorOrder() const override { return std::min(tableau_.order, tableau_.embeddedOrder); }
  int stateSize() const override { return n_; }

  void initialState(double t0, VectorRef z) override;
  void addInitialStateVjp(double t0, ConstVectorRef z0, ConstVectorRef lambda, VectorRef gradient) override;

  /// One step from (t, z) of size h: z <- z_{n+1}. Returns the objective increment
  /// h sum_i b_i G(Z_i). With errorNorm != nullptr, also the weighted RMS norm of the embedded error
  /// estimate (<= 1 means acceptable). Throws NumericalError when Newton fails or a value is not finite.
  double step(double t, double h, VectorRef z, double* errorNorm = nullptr) override;

  /// The transpose of step(): given z = z_n (the start of the step) and lambda = dpsi/dz_{n+1},
  /// sets lambda <- dpsi/dz_n and adds the step's contribution to gradient (size np).
  void adjointStep(double t, double h, ConstVectorRef z, VectorRef lambda, VectorRef gradient) override;

  /// The stage states Z_i of the step, column by column; Z_1 is left out when it is z_n itself (a_11 = 0),
  /// so rk4 keeps 3 n doubles per step. The adjoint needs only the Z_i (K_i, x_{n+1} are not used).
  std::int64_t stepDataSize() const override;
  /// An explicit method of a problem with rhs data (Problem::rhsDataSize() = d > 0): each stage's, s d
  /// doubles (rk4 of a SecondOrderProblem with f coordinates: 4 (f + f (f + 1) / 2)). Restored, the adjoint
  /// stage evaluates nothing the rhs computed (for a SecondOrderProblem: M, f and the factorisation of M).
  std::int64_t stepRhsDataSize() const override { return static_cast<std::int64_t>(rhsDataSize_) * stages_; }
  void setSavesStepData(bool saves, bool withRhsData) override {
    savesRhsData_ = saves && withRhsData && rhsDataSize_ > 0;
  }
  void saveStepData(VectorRef data) const override;
  void adjointStepFromData(double t, double h, ConstVectorRef z, ConstVectorRef data, VectorRef lambda,
                           VectorRef gradient) override;

  bool hasStateDerivative() const override { return true; }
  /// F(t, z) into f (counts one evaluation); for the storage's derivative and diagnostics.
  void stateDerivative(double t, ConstVectorRef z, VectorRef f) override;
  /// The first stage derivative of the last step() when it equals F(t_n, z_n) (c_1 = 0 and a_11 = 0).
  bool firstStageIsRhs() const override;
  Eigen::Ref<const Vector> lastFirstStage() const override;

  ProblemWorkspace* problemWorkspace() const { return workspace_.get(); }
  const IntegratorCounters& counters() const override { return counters_; }

 private:
  void computeStages(double t, double h, ConstVectorRef z);
  void solveImplicitStage(int i, double t, double h);
  /// The transposed stages, given stageStates_ of the step from (t, h).
  /// rhsData: the stages' rhs data (rhsDataSize_ doubles each, stage by stage) or nullptr.
  void adjointFromStages(double t, double h, VectorRef lambda, VectorRef gradient,
                         const double* rhsData = nullptr);
  /// Columns of stageStates_ kept as step data: 1..s-1 when Z_1 = z_n (a_11 = 0), else 0..s-1.
  int firstDataStage() const { return tableau_.a(0, 0) == 0.0 ? 1 : 0; }
  void jacobianTransposeProduct(double t, ConstVectorRef z, ConstVectorRef w, VectorRef out,
                                bool needDenseJacobian);

  const Problem& problem_;
  Vector p_;
  IntegratorOptions options_;
  IntegratorMethod method_;
  ButcherTableau tableau_;
  std::unique_ptr<ProblemWorkspace> workspace_;
  std::unique_ptr<NewtonSolver> newtonSolver_;  // null: dense path below
  bool linearInState_ = false;                  // Problem::isLinearInState(): one Newton step per stage
  int n_;
  int stages_;
  Matrix stageSlopes_;    // K, n x s
  Matrix stageStates_;    // Z, n x s
  Matrix stageAdjoints_;  // Zbar, n x s
  // Problem::rhsDataSize() of an explicit method (else 0), and each stage's rhs data of the last step,
  // rhsDataSize_ x s, filled only while savesRhsData_ (setSavesStepData).
  int rhsDataSize_ = 0;
  bool savesRhsData_ = false;
  Matrix stageRhsData_;
  Vector base_, residual_, delta_, work_, rhsWork_, zStart_;
  Matrix jacobian_, newtonMatrix_;
  Eigen::PartialPivLU<Matrix> lu_;
  IntegratorCounters counters_;
  // IntegratorOptions::absoluteTolerances as vectors for the error norm (empty: the scalar norm, so
  // the default keeps its bits), and the atol of the Newton test.
  Vector relativeTolerances_, absoluteTolerances_;
  double newtonAbsoluteTolerance_ = 0.0;
};

}  // namespace hindsight
