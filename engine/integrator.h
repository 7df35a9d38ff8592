// Runge-Kutta integrators with discrete adjoints (docs/design.md §5).
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
// midpoint, order 2, symplectic, fixed step). Adaptive stepping needs an embedded pair.
//
// The integrator owns a workspace allocated in its constructor; step() and adjointStep() allocate
// nothing (a test checks this with a counting operator new).
#pragma once

#include <hindsight/engine/problem.h>

#include <Eigen/LU>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {

struct IntegratorOptions {
  std::string method = "rk4";
  double t0 = 0.0;
  double t1 = 1.0;
  /// Fixed step size (the grid uses N = ceil((t1 - t0)/step) equal steps), or the first step when adaptive.
  double step = 1e-3;
  bool adaptive = false;
  double relativeTolerance = 1e-6;
  double absoluteTolerance = 1e-9;
  /// Adaptive: a step below this size is an underflow (NumericalError with the time).
  double minStep = 1e-14;
  /// Adaptive: upper bound on the step size; 0 means t1 - t0.
  double maxStep = 0.0;
  std::int64_t maxSteps = 100'000'000;
  /// Newton stops when h a_ii ||delta K||_inf <= newtonTolerance (||Z||_inf + absoluteTolerance).
  double newtonTolerance = 1e-13;
  int newtonMaxIterations = 30;
  /// When not empty: the time grid t_0 = t0 < t_1 < ... < t_N = t1 to step on, without error control.
  /// Used to differentiate the computed psi for a frozen adaptive step sequence.
  std::vector<double> replayTimes;

  /// False with a message naming the field, its value and the allowed range.
  bool IsValid(std::string* error) const;
  /// Throws std::invalid_argument with IsValid's message.
  void validate() const;
};

/// A Butcher tableau, optionally with an embedded weight vector for error estimation.
struct ButcherTableau {
  std::string name;
  Matrix a;
  Vector b, c;
  Vector bEmbedded;  ///< empty: no error estimate, fixed step only
  int order = 0;
  int embeddedOrder = 0;
  bool isExplicit() const;
  /// Looks up a method by name; throws std::invalid_argument listing the known ones.
  static ButcherTableau byName(const std::string& name);
  static std::vector<std::string> names();
};

/// Thrown by a step when the Newton iteration of an implicit stage fails; an adaptive driver
/// retries with a smaller step, a fixed-step driver lets it propagate.
class NewtonFailure final : public NumericalError {
 public:
  using NumericalError::NumericalError;
};

/// Counters of integrator work, summed over forward, recomputation and adjoint steps.
struct IntegratorCounters {
  std::int64_t rhsEvaluations = 0;
  std::int64_t jacobianEvaluations = 0;
  std::int64_t factorizations = 0;
  std::int64_t newtonIterations = 0;
};

class RungeKuttaIntegrator final {
 public:
  /// Throws std::invalid_argument when p has the wrong size or the options are invalid.
  RungeKuttaIntegrator(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options);
  ~RungeKuttaIntegrator();

  const ButcherTableau& tableau() const { return tableau_; }
  const IntegratorOptions& options() const { return options_; }

  /// One step from (t, z) of size h: z <- z_{n+1}. Returns the objective increment
  /// h sum_i b_i G(Z_i). With errorNorm != nullptr, also the weighted RMS norm of the embedded error
  /// estimate (<= 1 means acceptable). Throws NumericalError when Newton fails or a value is not finite.
  double step(double t, double h, VectorRef z, double* errorNorm = nullptr);

  /// The transpose of step(): given z = z_n (the start of the step) and lambda = dpsi/dz_{n+1},
  /// sets lambda <- dpsi/dz_n and adds the step's contribution to gradient (size np).
  void adjointStep(double t, double h, ConstVectorRef z, VectorRef lambda, VectorRef gradient);

  /// F(t, z) into f (counts one evaluation); for the storage's derivative and diagnostics.
  void evaluateRhs(double t, ConstVectorRef z, VectorRef f);
  /// The first stage derivative of the last step() when it equals F(t_n, z_n) (c_1 = 0 and a_11 = 0).
  bool firstStageIsRhs() const;
  /// By value: a Ref to the column of the stage matrix (returning `const Ref&` would dangle).
  Eigen::Ref<const Vector> lastFirstStage() const;

  ProblemWorkspace* problemWorkspace() const { return workspace_.get(); }
  const IntegratorCounters& counters() const { return counters_; }

 private:
  void computeStages(double t, double h, ConstVectorRef z);
  void solveImplicitStage(int i, double t, double h);
  void jacobianTransposeProduct(double t, ConstVectorRef z, ConstVectorRef w, VectorRef out,
                                bool needDenseJacobian);

  const Problem& problem_;
  Vector p_;
  IntegratorOptions options_;
  ButcherTableau tableau_;
  std::unique_ptr<ProblemWorkspace> workspace_;
  std::unique_ptr<NewtonSolver> newtonSolver_;  // null: dense path below
  bool linearInState_ = false;                  // Problem::isLinearInState(): one Newton step per stage
  int n_;
  int stages_;
  Matrix stageSlopes_;    // K, n x s
  Matrix stageStates_;    // Z, n x s
  Matrix stageAdjoints_;  // Zbar, n x s
  Vector base_, residual_, delta_, work_, rhsWork_, zStart_;
  Matrix jacobian_, newtonMatrix_;
  Eigen::PartialPivLU<Matrix> lu_;
  IntegratorCounters counters_;
};

}  // namespace hindsight
