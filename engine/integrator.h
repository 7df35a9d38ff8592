// The integrator interface of the adjoint engine (docs/design.md §5).
//
// An Integrator advances its own state x_n over one step, x_{n+1} = Phi(t_n, h, x_n, p), adds the
// step's share of the objective integral, and applies the exact transpose of that step map
// (adjointStep), so the forward sweep, the discrete adjoint (engine/adjoint.h), the recomputation of
// checkpointed steps (engine/grid_recomputer.h) and the continuous adjoint's forward sweep work with
// any method through this interface alone; createIntegrator() selects the implementation by
// IntegratorOptions::method.
//
// The integrator's state is what the trajectory storage records and restores per step. A one-step
// method carries only the problem state z (x = z); a method with memory carries more (generalized-
// alpha carries the accelerations). Invariant: the first problem.stateSize() entries of x are z, so
// the terminal term phi(z_N) and the observers read z = x.head(n), and dpsi/dx of phi is dphi/dz
// padded with zeros.
//
// Implementations:
//   engine/runge_kutta.h        explicit and diagonally implicit Runge-Kutta methods ("rk4", "dopri5",
//                               "trbdf2", "sdirk2", "midpoint"); adaptive with an embedded pair.
//   engine/generalized_alpha.h  generalized-alpha (Chung & Hulbert 1993) and HHT-alpha for
//                               SecondOrderProblem, fixed step ("generalized-alpha", "hht-alpha").
//
// Every implementation owns a workspace allocated in its constructor; step() and adjointStep()
// allocate nothing (tests/engine/allocation_test.cpp checks this with a counting malloc).
#pragma once

#include <hindsight/engine/problem.h>

#include <Eigen/LU>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {

/// The methods createIntegrator() knows; IntegratorOptions::method names one of them.
enum class IntegratorMethod { Rk4, Dopri5, TrBdf2, Sdirk2, Midpoint, GeneralizedAlpha, HhtAlpha };

/// The user-facing name ("rk4", ..., "generalized-alpha", "hht-alpha").
std::string toString(IntegratorMethod method);
/// Parses a method name; throws std::invalid_argument naming IntegratorOptions.method and listing
/// the known names.
IntegratorMethod parseIntegratorMethod(const std::string& name);
/// True for the methods of engine/runge_kutta.h.
bool isRungeKutta(IntegratorMethod method);
/// Every known method name, Runge-Kutta methods first.
std::vector<std::string> integratorMethodNames();

struct IntegratorOptions {
  /// A name from integratorMethodNames(); parsed once with parseIntegratorMethod().
  std::string method = "rk4";
  double t0 = 0.0;
  double t1 = 1.0;
  /// Fixed step size (the grid uses N = ceil((t1 - t0)/step) equal steps), or the first step when adaptive.
  double step = 1e-3;
  bool adaptive = false;
  /// Adaptive: the error test's rtol and atol (weightedRmsNorm, engine/step_controller.h), both > 0.
  double relativeTolerance = 1e-6;
  double absoluteTolerance = 1e-9;
  /// Adaptive: per-component absolute tolerances of the state z (CVODES' CVodeSVtolerances); when
  /// not empty they replace absoluteTolerance in the error test, need stateSize() entries, each
  /// positive and finite, and the Newton test uses their smallest entry. Empty (default): the scalar.
  std::vector<double> absoluteTolerances;
  /// Adaptive: a step below this size is an underflow (NumericalError with the time).
  double minStep = 1e-14;
  /// Adaptive: upper bound on the step size; 0 means t1 - t0.
  double maxStep = 0.0;
  std::int64_t maxSteps = 100'000'000;
  /// Newton stops when its correction is below newtonTolerance times the size of the unknown
  /// (Runge-Kutta: h a_ii ||delta K||_inf <= newtonTolerance (||Z||_inf + absoluteTolerance)).
  double newtonTolerance = 1e-13;
  int newtonMaxIterations = 30;
  /// Generalized-alpha and HHT-alpha: the spectral radius of the step map at infinite frequency,
  /// in [0, 1] (1: no numerical damping; 0: asymptotic annihilation). HHT-alpha needs [0.5, 1].
  double rhoInfinity = 0.8;
  /// When not empty: the time grid t_0 = t0 < t_1 < ... < t_N = t1 to step on, without error control.
  /// Used to differentiate the computed psi for a frozen adaptive step sequence.
  std::vector<double> replayTimes;

  /// False with a message naming the field, its value and the allowed range.
  bool IsValid(std::string* error) const;
  /// Throws std::invalid_argument with IsValid's message.
  void validate() const;
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

class Integrator {
 public:
  virtual ~Integrator() = default;

  /// The method's name, as in IntegratorOptions::method.
  virtual std::string name() const = 0;
  virtual IntegratorMethod method() const = 0;
  /// Order of convergence of the propagated solution.
  virtual int order() const = 0;
  /// True when step() can return an error estimate (adaptive stepping needs it).
  virtual bool hasErrorEstimate() const = 0;
  /// The error estimate is O(h^(errorOrder() + 1)); the step-size controller's exponent follows it.
  virtual int errorOrder() const = 0;
  /// Size of the integrator's state x (at least problem.stateSize(); its head is z).
  virtual int stateSize() const = 0;

  /// x_0 at t0 from the problem's initial state z0(p) (and what the method derives from it).
  virtual void initialState(double t0, VectorRef x) = 0;
  /// The transpose of initialState(): given lambda = dpsi/dx_0, adds dpsi/dp through x_0(p).
  virtual void addInitialStateVjp(double t0, ConstVectorRef x0, ConstVectorRef lambda,
                                  VectorRef gradient) = 0;

  /// One step from (t, x) of size h: x <- x_{n+1}. Returns the step's objective increment. With
  /// errorNorm != nullptr (only when hasErrorEstimate()), also the weighted RMS norm of the error
  /// estimate (<= 1 means acceptable). Throws NumericalError when Newton fails or a value is not finite.
  virtual double step(double t, double h, VectorRef x, double* errorNorm = nullptr) = 0;
  /// The transpose of step(): given x = x_n (the start of the step) and lambda = dpsi/dx_{n+1},
  /// sets lambda <- dpsi/dx_n and adds the step's contribution to gradient (size np).
  virtual void adjointStep(double t, double h, ConstVectorRef x, VectorRef lambda, VectorRef gradient) = 0;

  /// True when adjointStepWithEnd() can use x_{n+1} to skip work (the sweep then keeps the state of the
  /// step after, which the exact storages restore with the forward sweep's bits).
  virtual bool usesStepEnd() const { return false; }
  /// adjointStep() when x_{n+1} = xEnd, the state step() produced from x, is at hand with its forward
  /// bits: a method whose step solves for a quantity that x_{n+1} holds reads it instead of solving again.
  /// The result is bitwise that of adjointStep(). Only for exact storages: an approximate x_{n+1} would
  /// not be the solution of the step from x.
  virtual void adjointStepWithEnd(double t, double h, ConstVectorRef x, ConstVectorRef xEnd, VectorRef lambda,
                                  VectorRef gradient) {
    (void)xEnd;
    adjointStep(t, h, x, lambda, gradient);
  }

  /// Step data: the doubles per step that let adjointStepFromData() run without evaluating
  /// the right-hand side (a Runge-Kutta method's stage values); 0 when the method offers none.
  virtual std::int64_t stepDataSize() const { return 0; }
  /// Doubles a step record may hold after the stepDataSize() ones: what the step's rhs evaluations computed
  /// besides F (an explicit Runge-Kutta method: Problem::rhsDataSize() per stage), so that
  /// adjointStepFromData() evaluates none of it again either; 0 when the method offers none.
  virtual std::int64_t stepRhsDataSize() const { return 0; }
  /// Called before a sweep: whether saveStepData() will follow the steps (the storage keeps step data) and
  /// whether its records hold the rhs data too (TrajectoryStorage::keepsRhsData()). A method copies the rhs
  /// data during step() only when asked to.
  virtual void setSavesStepData(bool saves, bool withRhsData) {
    (void)saves;
    (void)withRhsData;
  }
  /// The step data of the last step(), the same bits that step computed: stepDataSize() doubles, followed by
  /// the stepRhsDataSize() of the rhs data after setSavesStepData(true, true).
  virtual void saveStepData(VectorRef data) const {
    (void)data;
    throw std::logic_error("method '" + name() + "' has no step data");
  }
  /// adjointStep() with the step data saveStepData() gave after the step from x (with or without the rhs
  /// data, told by data.size()): the same arithmetic on the same bits, so the result is bitwise that of
  /// adjointStep(), without recomputing the stages.
  virtual void adjointStepFromData(double t, double h, ConstVectorRef x, ConstVectorRef data,
                                   VectorRef lambda, VectorRef gradient) {
    (void)data;
    adjointStep(t, h, x, lambda, gradient);
  }

  /// True when stateDerivative() is available (a storage that interpolates, Hermite, needs it).
  virtual bool hasStateDerivative() const = 0;
  /// dx/dt at (t, x) into xdot (counts one evaluation).
  virtual void stateDerivative(double t, ConstVectorRef x, VectorRef xdot) = 0;
  /// True when the last step() already computed dx/dt at its start (its first stage, c_1 = 0, a_11 = 0).
  virtual bool firstStageIsRhs() const = 0;
  /// That derivative; meaningful only when firstStageIsRhs(). By value: a Ref to a column of the stage
  /// matrix (a `const Ref&` would dangle).
  virtual Eigen::Ref<const Vector> lastFirstStage() const = 0;

  virtual const IntegratorCounters& counters() const = 0;
};

/// The integrator options.method names, for `problem` and parameters p (copied). Throws
/// std::invalid_argument when p has the wrong size, the options are invalid or the method does not
/// fit the problem (generalized-alpha needs a SecondOrderProblem).
std::unique_ptr<Integrator> createIntegrator(const Problem& problem, ConstVectorRef p,
                                             const IntegratorOptions& options);

/// x <- A^{-T} x for A = P^T L U factorised by `lu`, in place, without allocating (Eigen's
/// lu.transpose().solve() allocates a temporary); `work` has the size of x. Shared by the implicit
/// adjoint steps.
void solveTransposedInPlace(const Eigen::PartialPivLU<Matrix>& lu, VectorRef x, VectorRef work);

/// The checks every implementation's constructor makes: validates the options, checks that p has the
/// problem's parameter size and absoluteTolerances (when given) its state size (std::invalid_argument
/// naming both sizes), and returns the parsed method.
IntegratorMethod checkedMethod(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options);

}  // namespace hindsight
