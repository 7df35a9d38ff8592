// The continuous adjoint with hindsight's own storage (docs/design.md §5; Bestle & Eberhard 1992;
// in first-order form z = (y, y'), the paper's eqs. (7) terminal condition with fixed t1, (8) adjoint
// ODE, (9) initial-state term and (10) gradient):
//   lambda' = -F_z^T lambda - G_z^T,          lambda(t1) = dphi/dz(z(t1)),
//   mu'     = -(G_p + lambda^T F_p)^T,        mu(t1) = 0,
//   dpsi/dp = mu(t0) + dphi/dp + (dz0/dp)^T lambda(t0),
// integrated backward from t1 to t0 with its own adaptive steps. The forward sweep is the engine's
// own (any IntegratorOptions, fixed or adaptive, whose integrator state is the problem state: not
// generalized-alpha, which carries accelerations); psi is the forward sweep's computed psi.
//
// Backward integrator (the choice, ContinuousAdjointOptions::method):
//   "dopri5" (default): Dormand-Prince 5(4) on the augmented system (lambda, mu), with FSAL, an error
//     test on lambda and mu together (weighted RMS norm, atol_i + rtol_i |y_i|: lambda's tolerances,
//     scalar or per component, and mu's quadrature tolerances) and Hairer's starting-step
//     heuristic. Explicit: each step costs 6 evaluations of F_z^T lambda and F_p^T lambda and nothing
//     is factorised; it works matrix-free (rhsStateVjp) and suits the non-stiff mechanical problems.
//     On stiff problems (Robertson) the backward system is as stiff as the forward one and dopri5
//     is stability-limited.
//   "trbdf2": the L-stable TR-BDF2 ESDIRK (order 2, embedded order 3; Hosea & Shampine 1996) in the
//     backward time. The lambda equation is linear, so each implicit stage is one LU solve with
//     I - h gamma F_z^T (no Newton iteration); mu is a quadrature with the same weights. Needs a
//     dense Jacobian; for stiff problems.
//
// Stiff adjoints (hardening finding 9; Robertson over [0, 4e7], forward trbdf2 rtol 1e-10, backward
// trbdf2 rtol 1e-11: 1.18 M rejected backward steps; rtol 1e-12: more than maxSteps). Measured
// causes, in the order the sweep meets them:
//   1. A terminal layer narrower than the time resolution. lambda(t1) = dphi/dz is in general off the
//      slow manifold of the stiff adjoint (Robertson: lambda_2 relaxes in ~1e-4 s), and near
//      t1 = 4e7 times are ulp(t1) = 7.45e-9 apart, so a step is a whole number of ulps. A retry of a
//      rejected step of a few ulps could round back onto the same end and was repeated unchanged
//      until maxSteps. Now a retry ends at least one representable time closer, a step below half
//      an ulp becomes one ulp, and a rejected one-ulp step stops the sweep at once with a message
//      naming the tolerance fields; minStep (default 1e-14 |t|, i.e. ~54 ulps) usually stops it
//      first, with the same advice.
//   2. The starting-step heuristic scales by atol where y(t1) is zero (mu(t1) = 0, lambda_2,3) and
//      returned ~1e-12 at t1 = 4e7, below minStep |t1|: every tolerance failed at once. A start below
//      the bound is raised to 100 times the bound (only starts that failed before change).
//   3. Round-off in the error estimate of the stiff components. TR-BDF2's estimate h sum (b_i -
//      bhat_i) k_i with k_i = F_z^T lambda_i carries the round-off of lambda amplified by
//      h ||F_z|| (||F_z|| ~ 1e4 on Robertson): at rtol 1e-12 it caps the step near 1 s over 4e7 s.
//      filterErrorEstimate multiplies the estimate by (I - h gamma F_z^T)^{-1} (Shampine's filter,
//      the stage factorisation is reused): 645 rejected steps at rtol 1e-12. Off by default only
//      because it changes the step sequence of existing results.
//   The forward Hermite interpolation error and the Newton tolerance were ruled out: the backward
//   system is linear (no Newton), and the rejected estimates alternate in sign step to step, which a
//   smooth interpolation error does not do.
//
// Forward states z(t) at the backward stage times come from the storage:
//   - storage.canInterpolate() (e.g. "hermite:every=M"): storage.interpolate(t, z);
//   - otherwise (e.g. "full"): the backward sweep restores z_n in reverse order as usual and builds
//     a cubic Hermite dense output on each forward step [t_n, t_{n+1}] from z_n, z_{n+1} and
//     F(t_n, z_n), F(t_{n+1}, z_{n+1}) (one F evaluation per grid point), keeping only the window of
//     grid points the current and a possibly rejected backward step can reach.
// The result is the gradient of the exact psi up to the forward error, the O(h^4) interpolation
// error and the backward tolerance; unlike the discrete adjoint it is not the derivative of the
// computed psi.
//
// Dimensions: lambda in R^n (n = stateSize()), mu and the gradient in R^np (np = parameterSize()).
// Preconditions: p has problem.parameterSize() entries; a problem without a dense Jacobian must
// implement rhsStateVjp(). Throws std::invalid_argument for bad options (naming the field and its
// range), NumericalError with the time for a backward step-size underflow, too many backward steps
// or a non-finite adjoint, StorageError from the storage.
//
// References: D. Bestle, P. Eberhard, "Analyzing and optimizing multibody systems", Mech. Struct.
// Mach. 20 (1992) (the adjoint and its gradient quadrature); Y. Cao, S. Li, L. Petzold, R. Serban,
// SIAM J. Sci. Comput. 24 (2003) (the adjoint ODE/DAE, lambda(t1) = dphi/dz, backward quadrature);
// E. Hairer, S. P. Norsett, G. Wanner, Solving ODEs I (1993), II.4-II.5 (dopri5, step control, the
// starting step); M. E. Hosea, L. F. Shampine, Appl. Numer. Math. 20 (1996) (TR-BDF2).
#pragma once

#include <hindsight/engine/adjoint.h>

#include <cstdint>
#include <string>
#include <vector>

namespace hindsight {

/// The backward integrators (see the file comment).
enum class BackwardMethod { Dopri5, TrBdf2 };
/// "dopri5" or "trbdf2"; throws std::invalid_argument naming ContinuousAdjointOptions.method otherwise.
BackwardMethod parseBackwardMethod(const std::string& name);

struct ContinuousAdjointOptions {
  /// Backward integrator: "dopri5" (explicit, non-stiff, any problem) or "trbdf2" (L-stable, for
  /// stiff problems; needs a dense Jacobian); parsed with parseBackwardMethod().
  std::string method = "dopri5";
  /// Tolerances of the backward error test on lambda (and on mu unless the quadrature ones below are
  /// set). rtol in [1e-14, 1), atol > 0.
  double relativeTolerance = 1e-8;
  double absoluteTolerance = 1e-10;
  /// Per-component atol of lambda (CVODES' CVodeSVtolerancesB): empty (default) uses
  /// absoluteTolerance; otherwise stateSize() entries, each positive and finite.
  std::vector<double> absoluteTolerances;
  /// Tolerances of the gradient quadrature mu in the same error test (CVODES' CVodeQuadSStolerancesB):
  /// 0 (default) means relativeTolerance / absoluteTolerance; otherwise rtol in [1e-14, 1), atol > 0.
  double quadratureRelativeTolerance = 0.0;
  double quadratureAbsoluteTolerance = 0.0;
  /// "trbdf2" only: filter the error estimate of lambda through (I - h gamma F_z^T)^{-1} (Shampine;
  /// Hairer & Wanner, Solving ODEs II, IV.8), so that round-off in the stiff components, amplified by
  /// h ||F_z||, does not reject steps (see "Stiff adjoints" above). Off by default: it changes the
  /// step sequence, and the default keeps the earlier results' bits.
  bool filterErrorEstimate = false;
  /// First backward step; 0 chooses it by Hairer's heuristic. In [0, t1 - t0].
  double initialStep = 0.0;
  /// A backward step smaller than minStep * max(1, |t|) is an underflow (NumericalError). In (0, 1e-3].
  double minStep = 1e-14;
  /// Upper bound on accepted plus rejected backward steps, in [1, 1e12].
  std::int64_t maxSteps = 10'000'000;

  bool IsValid(std::string* error) const;
  /// Throws std::invalid_argument with IsValid's message.
  void validate() const;
};

/// psi (from the forward sweep over `forward`) and dpsi/dp by the continuous adjoint, with forward
/// states from `storage`. The summary's adjoint is "continuous", method the forward method; steps
/// are the forward steps; rejectedSteps, rhsEvaluations, jacobianEvaluations and factorizations are
/// the forward sweep's plus the backward sweep's (rejected backward steps; F for z' at grid points and
/// for recomputation; one F_z or F_z^T lambda per backward stage; one LU per implicit stage).
/// Throws as described in the file comment.
GradientResult computeGradientContinuous(const Problem& problem, ConstVectorRef p,
                                         const IntegratorOptions& forward, TrajectoryStorage& storage,
                                         const ContinuousAdjointOptions& options = {});

}  // namespace hindsight
