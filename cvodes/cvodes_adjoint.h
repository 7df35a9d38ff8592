// The CVODES route to dpsi/dp (docs/design.md §5): the continuous adjoint solved by SUNDIALS CVODES
// with its own checkpointing, as an independent cross-check of hindsight's discrete and continuous
// adjoints.
//
// For z' = F(t, z, p), z(t0) = z0(p), psi = int_{t0}^{t1} G dt + phi(z(t1), p):
//   forward  CVodeF integrates z and the quadrature q' = G (CVodeQuadInit); CVodeAdjInit(Nd, interp)
//            stores a check point every Nd steps and, during the backward phase, interpolates z
//            between recomputed steps (CV_HERMITE: cubic Hermite from (z, z'); CV_POLYNOMIAL:
//            variable-degree polynomial);
//   backward CVodeB integrates lambda' = -F_z^T lambda - G_z^T from lambda(t1) = dphi/dz(t1) to t0,
//            F_z^T lambda by the problem's vector-Jacobian product rhsStateVjp() when it has one
//            (Problem::hasStateVjp(); otherwise from the dense F_z), and the backward quadrature
//            qB' = -(G_p + lambda^T F_p) (CVodeQuadInitB, by addRhsParameterVjp()), so
//            qB(t0) = int (G_p + lambda^T F_p) dt;
//   solvers  as the CVODES user guide advises (notes of CVodeCreate: "the default Newton iteration is
//            recommended for stiff problems, and the fixed-point solver ... for nonstiff problems"):
//            Adams runs SUNNonlinSol_FixedPoint forward and backward (no Jacobian, no linear solver);
//            BDF runs Newton with a dense direct solver (SUNLinSol_Dense; the Jacobian -F_z^T of the
//            backward problem is formed only at the linear-solver setups) or, for a problem without a
//            dense Jacobian, matrix-free GMRES (SUNLinSol_SPGMR) whose backward Jacobian-times-vector
//            is -F_z^T v = -rhsStateVjp(v) and whose forward one is CVODES' difference quotient;
//   result   dpsi/dp = qB(t0) + dphi/dp + (dz0/dp)^T lambda(t0)  (Bestle & Eberhard 1992).
// In the paper's second-order notation (reference/, Held et al.) these are its eqs. (7) (terminal
// condition; here t1 is fixed, so no tau term), (8) (adjoint ODE), (9) (initial-state adjoint) and
// (10) (gradient), written for the first-order state z = (y, y').
// The gradient is that of the exact psi up to the tolerances, not the derivative of the computed psi.
//
// Preconditions: problem.hasDenseJacobian() for the dense linear solver and the dense backward
// products; a problem without one needs rhsStateVjp() and runs fixed point or GMRES. p has
// problem.parameterSize() entries. Dimensions: n = stateSize(), np = parameterSize().
// Throws std::invalid_argument for bad options (naming the field and its range), a wrong p size or a
// problem without the derivative a chosen solver needs (dense Jacobian or vector-Jacobian product);
// hindsight::NumericalError for every SUNDIALS return flag < 0, carrying the flag's name
// (CVodeGetReturnFlagName) and the simulation time of the failure. Exceptions thrown by the problem inside a
// SUNDIALS callback are caught there, make CVODES stop with an unrecoverable flag, and are rethrown
// unchanged.
//
// References: A. C. Hindmarsh, R. Serban et al., "User Documentation for CVODES" (SUNDIALS 6.4),
// chapter "Using CVODES for adjoint sensitivity analysis"; Y. Cao, S. Li, L. Petzold, R. Serban,
// "Adjoint sensitivity analysis for differential-algebraic equations: the adjoint DAE system and its
// numerical solution", SIAM J. Sci. Comput. 24 (2003); D. Bestle, P. Eberhard, "Analyzing and
// optimizing multibody systems", Mech. Struct. Mach. 20 (1992).
#pragma once

#include <hindsight/engine/adjoint.h>

#include <cstdint>
#include <string>
#include <vector>

namespace hindsight {

/// CVODES' linear multistep family: BDF for stiff problems, Adams-Moulton for non-stiff ones. The same
/// family is used forward and backward.
enum class CvodesMethod { Bdf, Adams };
/// How CVODES rebuilds z(t) between stored data points in the backward phase (CVodeAdjInit's interp).
enum class CvodesInterpolation { Hermite, Polynomial };
/// The nonlinear solver of every implicit step, forward and backward. Auto: FixedPoint for Adams, Newton
/// for BDF (the CVODES user guide's advice).
enum class CvodesNonlinearSolver { Auto, Newton, FixedPoint };
/// The linear solver of the Newton iterations. Auto: Dense when the problem has a dense Jacobian,
/// otherwise Gmres (matrix-free, unpreconditioned).
enum class CvodesLinearSolver { Auto, Dense, Gmres };
/// Where the backward right-hand side gets F_z^T lambda from. Auto: Vjp when the problem has
/// rhsStateVjp() (Problem::hasStateVjp()), otherwise Dense (the transpose of rhsJacobian()).
enum class CvodesBackwardProducts { Auto, Vjp, Dense };

/// "bdf" | "adams"; throws std::invalid_argument listing them.
CvodesMethod parseCvodesMethod(const std::string& name);
/// "hermite" | "polynomial"; throws std::invalid_argument listing them.
CvodesInterpolation parseCvodesInterpolation(const std::string& name);
/// "auto" | "newton" | "fixed-point"; throws std::invalid_argument listing them.
CvodesNonlinearSolver parseCvodesNonlinearSolver(const std::string& name);
/// "auto" | "dense" | "gmres"; throws std::invalid_argument listing them.
CvodesLinearSolver parseCvodesLinearSolver(const std::string& name);
/// "auto" | "vjp" | "dense"; throws std::invalid_argument listing them.
CvodesBackwardProducts parseCvodesBackwardProducts(const std::string& name);
std::string toString(CvodesMethod method);
std::string toString(CvodesInterpolation interpolation);
std::string toString(CvodesNonlinearSolver solver);
std::string toString(CvodesLinearSolver solver);
std::string toString(CvodesBackwardProducts products);

struct CvodesOptions {
  CvodesMethod method = CvodesMethod::Bdf;
  CvodesInterpolation interpolation = CvodesInterpolation::Hermite;
  double t0 = 0.0;
  double t1 = 1.0;
  /// Tolerances of the forward state (CVodeSStolerances), rtol in [1e-14, 1), atol > 0; also of every
  /// problem below whose own tolerance is left at 0.
  double relativeTolerance = 1e-6;
  double absoluteTolerance = 1e-9;
  /// Per-component atol of the forward state (CVodeSVtolerances): empty (default) uses
  /// absoluteTolerance; otherwise stateSize() entries, each positive and finite.
  std::vector<double> absoluteTolerances;
  /// Forward quadrature psi (CVodeQuadSStolerances); 0: relativeTolerance / absoluteTolerance.
  double quadratureRelativeTolerance = 0.0;
  double quadratureAbsoluteTolerance = 0.0;
  /// Backward adjoint lambda (CVodeSStolerancesB); 0: relativeTolerance / absoluteTolerance.
  double backwardRelativeTolerance = 0.0;
  double backwardAbsoluteTolerance = 0.0;
  /// Per-component atol of lambda (CVodeSVtolerancesB): empty uses the backward scalar; otherwise
  /// stateSize() entries, each positive and finite.
  std::vector<double> backwardAbsoluteTolerances;
  /// Backward gradient quadrature (CVodeQuadSStolerancesB); 0: the backward rtol / scalar atol.
  double backwardQuadratureRelativeTolerance = 0.0;
  double backwardQuadratureAbsoluteTolerance = 0.0;
  /// Nd: integration steps between check points (CVodeAdjInit), in [1, 1e9].
  std::int64_t checkpointSteps = 100;
  /// mxstep of CVODES for the forward and the backward problem, in [1, 1e12].
  std::int64_t maxSteps = 100'000;
  /// First step size; 0 lets CVODES estimate it. In [0, t1 - t0].
  double initialStep = 0.0;
  /// Include the quadratures (psi and the gradient) in the local error test (CVodeSetQuadErrCon and
  /// CVodeSetQuadErrConB); their tolerances matter only then.
  bool quadratureErrorControl = true;
  /// Nonlinear solver (CVodeSetNonlinearSolver, CVodeSetNonlinearSolverB); see CvodesNonlinearSolver.
  CvodesNonlinearSolver nonlinearSolver = CvodesNonlinearSolver::Auto;
  /// Anderson acceleration depth m of the fixed-point solver (SUNNonlinSol_FixedPoint(y, m)), in
  /// [0, 20]; 0 (the SUNDIALS default) is plain fixed-point iteration.
  int fixedPointAcceleration = 0;
  /// Linear solver of the Newton iterations (ignored with the fixed-point solver).
  CvodesLinearSolver linearSolver = CvodesLinearSolver::Auto;
  /// F_z^T lambda in the backward right-hand side; see CvodesBackwardProducts.
  CvodesBackwardProducts backwardProducts = CvodesBackwardProducts::Auto;

  /// False with a message naming the field, its value and the allowed range.
  bool IsValid(std::string* error) const;
  /// Throws std::invalid_argument with IsValid's message.
  void validate() const;
};

/// What one CVODES gradient did, beyond RunSummary: every callback counted where it runs.
struct CvodesCounters {
  std::string nonlinearSolver;                ///< "newton" | "fixed-point" (after Auto is resolved)
  std::string linearSolver;                   ///< "dense" | "gmres" | "none" (fixed point)
  std::string backwardProducts;               ///< "vjp" | "dense"
  std::int64_t forwardRhsEvaluations = 0;     ///< F during CVodeF
  std::int64_t recomputedRhsEvaluations = 0;  ///< F during CVodeB (re-integration between check points)
  std::int64_t backwardRhsEvaluations = 0;    ///< lambda' evaluations
  std::int64_t backwardQuadratureEvaluations = 0;
  std::int64_t stateVjps = 0;       ///< rhsStateVjp() calls (backward rhs and GMRES products)
  std::int64_t denseJacobians = 0;  ///< rhsJacobian() calls, all purposes (= summary.jacobianEvaluations)
  std::int64_t forwardNonlinearIterations = 0, backwardNonlinearIterations = 0;
  std::int64_t forwardLinearIterations = 0, backwardLinearIterations = 0;        ///< GMRES iterations
  std::int64_t forwardConvergenceFailures = 0, backwardConvergenceFailures = 0;  ///< nonlinear solver
};

/// psi and dpsi/dp by CVODES. The summary reports: method "cvodes-bdf" / "cvodes-adams", adjoint
/// "cvodes", storage "cvodes:checkpoints=Nd,interp=...", steps = forward steps; rejectedSteps = forward
/// plus backward error-test and nonlinear-solver convergence failures; newtonIterations = both problems'
/// nonlinear iterations (Newton or fixed point); rhsEvaluations = every F evaluation (forward and
/// recomputation phases) and jacobianEvaluations = every dense F_z evaluation (forward Jacobian,
/// backward right-hand side on the dense path and backward Jacobian; 0 with the fixed-point solver and
/// the problem's vector-Jacobian products), both counted in the callbacks; factorizations = the
/// linear-solver setups of both problems (CVodeGetNumLinSolvSetups; 0 with the fixed-point solver);
/// recomputedSteps = the forward steps before the last check point, which CVodeB re-integrates; statesStored
/// = check points (CVodeF's ncheck). peakBytesInMemory stays 0: CVODES does not report the memory of its
/// check points and data points. times is the forward grid (CVodeF in one-step mode up to the stop time t1).
/// `counters`, when given, receives the CvodesCounters of the run.
GradientResult computeGradientCvodes(const Problem& problem, ConstVectorRef p, const CvodesOptions& options,
                                     CvodesCounters* counters = nullptr);

}  // namespace hindsight
