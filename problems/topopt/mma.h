// The Method of Moving Asymptotes (MMA) for inequality-constrained nonlinear optimization.
//
// Problem form (the standard form of Svanberg 2007): for design variables x (n), elastic variables
// y (m) and z,
//
//   minimize    f0(x) + a0 z + sum_i (c_i y_i + 1/2 d_i y_i^2)
//   subject to  f_i(x) - a_i z - y_i <= 0,   i = 1..m,
//               xmin_j <= x_j <= xmax_j,     j = 1..n,
//               y_i >= 0, z >= 0.
//
// With a0 = 1, a_i = 0 and c_i large (the defaults) this is the problem "minimize f0 s.t. f_i <= 0,
// xmin <= x <= xmax": at a KKT point of that problem whose multipliers are below c_i the elastic
// variables are zero, and while the design violates a constraint they keep the subproblem feasible.
//
// Each call of `Mma::update` builds the convex, separable MMA approximation of f0 and every f_i
// around the current x (terms p / (upp - x) + q / (x - low) with moving asymptotes low < x < upp;
// Svanberg 1987, 2007) and replaces x by the minimizer of that approximation, found by Svanberg's
// primal-dual interior-point method (the 2007 note's "subsolv"). The caller evaluates functions and
// gradients between updates; the optimizer never calls back. Preconditions: functions and gradients
// finite, xmin < xmax componentwise, x within the bounds; scaling f0 and f_i to order 1 (as docs/design.md
// sec. 7 does) matters because c_i = 1000 and the barrier tolerance are absolute.
//
// Restart: everything that carries over from one update to the next is the `MmaState` (iteration count,
// the two previous iterates and the asymptotes). `state()` copies it out and `restore()` copies it in,
// so an optimization continued from a stored state reproduces the uninterrupted one bit for bit.
//
// Cost per update: O(n m^2 + m^3) per Newton step of the subproblem solver, a few dozen Newton steps
// per update; all buffers are allocated by the constructor, `update` and `restore` allocate nothing.
// Accuracy: each subproblem is solved to the barrier parameter subproblem_tolerance (1e-7), which
// bounds how exactly a constraint is active at the end (f_i ~ -1e-7 / lambda_i).
//
// References:
//   K. Svanberg, The method of moving asymptotes - a new method for structural optimization,
//     Int. J. Numer. Meth. Engng 24 (1987) 359-373.
//   K. Svanberg, MMA and GCMMA - two methods for nonlinear optimization, KTH Stockholm, 2007
//     (the note that defines the standard form, the constants below and the subproblem solver).
#pragma once

#include <hindsight/engine/types.h>

#include <Eigen/LU>

#include <limits>
#include <string>

namespace hindsight {

/// Constants of MMA. The defaults are the ones of Svanberg's 2007 note; the note's symbol is given for
/// each field. The elastic-variable constants (a0, a, c, d) are the same for every constraint.
struct MmaOptions {
  /// asyinit: in the first two iterations the asymptotes are x -/+ asyinit (xmax - xmin). In (0, 1].
  double initial_asymptote_distance = 0.5;
  /// asyincr: factor that widens the asymptotes when a variable keeps moving in one direction. >= 1.
  double asymptote_expansion = 1.2;
  /// asydecr: factor that narrows the asymptotes when a variable oscillates. In (0, 1].
  double asymptote_contraction = 0.7;
  /// Smallest distance |x - low|, |upp - x| of the asymptotes, in units of (xmax - xmin); 0.01 in
  /// Svanberg's 2007 implementation. It caps the curvature of the approximations: where the
  /// objective is stationary inside the box (no constraint balancing it) a step is about 0.9 times
  /// this distance whatever the gradient, so such variables end in a limit cycle of that amplitude;
  /// a smaller value lets them converge. In (0, initial_asymptote_distance].
  double min_asymptote_distance = 0.01;
  /// Largest distance of the asymptotes, in units of (xmax - xmin); 10 in Svanberg's 2007
  /// implementation. >= initial_asymptote_distance.
  double max_asymptote_distance = 10.0;
  /// albefa: the subproblem keeps x at least this fraction of the way from an asymptote. In (0, 1).
  double asymptote_margin = 0.1;
  /// move: a variable moves at most move (xmax - xmin) per iteration. In (0, 1].
  double move_limit = 0.5;
  /// Adaptive move limit (off in Svanberg's MMA): the move limit of an update is halved (times
  /// move_limit_shrink) after an update that raised the objective between two feasible designs, and
  /// grows (times move_limit_growth, up to move_limit) after one that lowered it. A trust-region
  /// safeguard for objectives on which MMA's approximations overshoot: it damps the period-2 swings
  /// between two designs that plain MMA keeps up at the move limit, so the iterates settle
  /// (docs/guides/optimizer.md has the measurements on the piston rod).
  bool adaptive_move_limit = false;
  /// Factor of the move limit after an update that raised the objective. In (0, 1).
  double move_limit_shrink = 0.5;
  /// Factor of the move limit after an update that lowered it. >= 1.
  double move_limit_growth = 1.2;
  /// The adaptive move limit never falls below this, in units of (xmax - xmin). In (0, move_limit].
  double min_move_limit = 1e-3;
  /// raa0: regularisation added to the curvature terms p, q of the approximations, divided by
  /// (xmax - xmin). > 0.
  double curvature_regularization = 1e-5;
  /// a0: cost of the elastic variable z. > 0.
  double z_cost = 1.0;
  /// a_i: weight of z in every constraint. >= 0.
  double z_weight = 0.0;
  /// c_i: linear cost of the elastic variables y_i. >= 0.
  double y_linear_cost = 1000.0;
  /// d_i: quadratic cost of the elastic variables y_i. >= 0, and c + d > 0.
  double y_quadratic_cost = 1.0;
  /// epsimin: the interior-point solver stops when its barrier parameter falls below this. > 0.
  double subproblem_tolerance = 1e-7;
  /// Newton iterations allowed per barrier level of the subproblem solver (200 in Svanberg's code). >= 1.
  int subproblem_max_newton_iterations = 200;

  /// True when every field is in its allowed range; otherwise false and *error (if not null) names the
  /// first offending field, its value and the allowed range.
  bool IsValid(std::string* error) const;
};

/// What carries over between MMA updates. Plain data: store it, copy it, restore it.
/// `iteration` is the number of completed updates; xold1 and xold2 are the designs passed to the last
/// and the second-to-last update; low and upp are the asymptotes used by the last update. All vectors
/// have length n. Before the first update iteration = 0 and the vectors hold zeros.
struct MmaState {
  int iteration = 0;
  Vector xold1;
  Vector xold2;
  Vector low;
  Vector upp;
  /// The move limit of the last update (0 before the first; always move_limit unless
  /// adaptive_move_limit) and the objective at xold1 when xold1 was feasible (NaN otherwise).
  double moveLimit = 0.0;
  double objective = std::numeric_limits<double>::quiet_NaN();
};

/// Diagnostics of the last subproblem solve and its Lagrange multipliers. At convergence of the outer
/// MMA iterations the multipliers approximate those of the original problem: `lambda` (m) of the
/// constraints f_i <= 0, `xsi` and `eta` (n) of the lower and upper bounds on x as seen by the
/// subproblem, `y` (m) and `z` the elastic variables.
struct MmaSubproblemSummary {
  bool converged = false;      ///< the barrier parameter reached subproblem_tolerance in time
  int newton_iterations = 0;   ///< total Newton steps over all barrier levels
  double residual_norm = 0.0;  ///< 2-norm of the relaxed KKT residual at the end
  Vector lambda;
  Vector xsi;
  Vector eta;
  Vector y;
  double z = 0.0;
};

/// First-order optimality (KKT) residual of "minimize f0(x) s.t. f_i(x) <= 0, xmin <= x <= xmax" at x
/// for multipliers lambda (m, >= 0; an MMA update's lastSubproblem().lambda estimates them):
///   max( max_j |x_j - clamp(x_j - g_j, xmin_j, xmax_j)|,  max_i max(f_i, 0),  max_i |lambda_i f_i| ),
/// with g = grad f0 + J^T lambda the gradient of the Lagrangian. The first term is the projected
/// gradient (zero exactly when g_j >= 0 at a lower bound, <= 0 at an upper bound and 0 between), the
/// others are feasibility and complementarity; all three vanish at a KKT point. It is the
/// multiplier-free-in-the-bounds form of Svanberg's kktcheck (2007 note): the bound multipliers are
/// the parts of g the projection removes. Units: those of f0 and f_i (scale them to order 1) and of
/// x. Throws std::invalid_argument when a size does not match.
double kktResidual(ConstVectorRef x, ConstVectorRef objective_gradient, ConstVectorRef constraints,
                   ConstMatrixRef constraint_jacobian, ConstVectorRef lambda, ConstVectorRef xmin,
                   ConstVectorRef xmax);

/// MMA optimizer for n design variables and m inequality constraints.
///
/// Usage: construct once, then repeatedly evaluate f0, its gradient, the m constraint values and their
/// m x n Jacobian at x and call update(..., x), which overwrites x with the next iterate.
class Mma final {
 public:
  /// Throws std::invalid_argument naming the argument when n < 1, m < 0 or the options are invalid.
  Mma(int n, int m, const MmaOptions& options = MmaOptions());

  /// One MMA iteration. Inputs at the current design x (n):
  ///   objective           f0(x) (enters only through the gradient, kept for symmetry with the note)
  ///   objective_gradient  df0/dx, length n
  ///   constraints         f_i(x), length m (the constraint is f_i(x) <= 0)
  ///   constraint_jacobian df_i/dx_j, m x n (column-major; a row-major argument is copied)
  ///   xmin, xmax          bounds, length n, xmin_j < xmax_j
  /// On return x holds the next iterate, which satisfies xmin <= x <= xmax.
  /// Throws std::invalid_argument naming the argument when a size is wrong, a value is not finite,
  /// xmin_j >= xmax_j, or x lies outside the bounds; the state is unchanged then.
  void update(double objective, ConstVectorRef objective_gradient, ConstVectorRef constraints,
              ConstMatrixRef constraint_jacobian, ConstVectorRef xmin, ConstVectorRef xmax, Vector& x);

  /// The state that carries over between updates; copy it to store it.
  const MmaState& state() const { return state_; }
  /// Replaces the state. Throws std::invalid_argument naming the field when a vector has not length n
  /// or iteration < 0.
  void restore(const MmaState& state);

  // ---- The steps of one update, for conservative variants (GCMMA, problems/topopt/gcmma.h) ----
  // update() is beginConservativeIteration + solveConservativeSubproblem with every rho_i = raa0
  // (curvature_regularization) + finishConservativeIteration; GCMMA solves the subproblem several
  // times with growing rho_i around the same x and asymptotes before it finishes the iteration.

  /// Checks the inputs as update() does (same exceptions) and moves the asymptotes for the
  /// iteration at x; the state's iteration count is unchanged until finishConservativeIteration.
  void beginConservativeIteration(double objective, ConstVectorRef objective_gradient,
                                  ConstVectorRef constraints, ConstMatrixRef constraint_jacobian,
                                  ConstVectorRef xmin, ConstVectorRef xmax, const Vector& x);
  /// Builds the approximations with curvature regularization rho (m + 1 entries, objective first,
  /// each > 0; it replaces raa0 of the note, rho_i / (xmax - xmin) is added to the p and q terms)
  /// around x and writes the subproblem's minimizer to `trial` (within [xmin, xmax]).
  void solveConservativeSubproblem(ConstVectorRef objective_gradient, ConstVectorRef constraints,
                                   ConstMatrixRef constraint_jacobian, ConstVectorRef xmin,
                                   ConstVectorRef xmax, const Vector& x, ConstVectorRef regularization,
                                   Vector& trial);
  /// f~_i(trial) - f_i(x) of the last built approximation, i = 0 for the objective, 1..m for the
  /// constraints.
  double approximationChange(int i, const Vector& x, const Vector& trial) const;
  /// Svanberg's d(trial) = sum_j (u_j - l_j)(t_j - x_j)^2 / ((u_j - t_j)(t_j - l_j)(xmax_j - xmin_j)):
  /// raising rho_i by delta raises f~_i(trial) by exactly delta d(trial).
  double conservativeDistance(const Vector& x, const Vector& trial, ConstVectorRef xmin,
                              ConstVectorRef xmax) const;
  /// Counts the iteration (x becomes xold1) as update() does.
  void finishConservativeIteration(const Vector& x);

  /// Multipliers and solver diagnostics of the last update.
  const MmaSubproblemSummary& lastSubproblem() const { return sub_; }

  int variableCount() const { return n_; }
  int constraintCount() const { return m_; }
  const MmaOptions& options() const { return options_; }

 private:
  // The argument checks of update().
  void checkInputs(double objective, ConstVectorRef objective_gradient, ConstVectorRef constraints,
                   ConstMatrixRef constraint_jacobian, ConstVectorRef xmin, ConstVectorRef xmax,
                   const Vector& x) const;
  // The adaptive move limit for an update at a design with these values (see MmaOptions).
  void adaptMoveLimit(double objective, ConstVectorRef constraints);
  // Asymptotes and move limits of one update.
  void updateAsymptotes(ConstVectorRef xmin, ConstVectorRef xmax, const Vector& x);
  // The approximation coefficients p, q, b of one update, with curvature regularization rho_i
  // (m + 1 entries, objective first).
  void buildApproximation(ConstVectorRef objective_gradient, ConstVectorRef constraints,
                          ConstMatrixRef constraint_jacobian, ConstVectorRef xmin, ConstVectorRef xmax,
                          const Vector& x, ConstVectorRef regularization);
  // Primal-dual interior-point solution of the subproblem; leaves the solution in xsub_.
  void solveSubproblem();
  // Relaxed KKT residual of the subproblem at the current primal-dual point for barrier parameter
  // epsilon; fills the residual blocks and returns their 2-norm, *max_abs gets the infinity norm.
  double subproblemResidual(double epsilon, double* max_abs);

  int n_;
  int m_;
  MmaOptions options_;
  MmaState state_;
  MmaSubproblemSummary sub_;

  using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

  // Approximation data: p0, q0 (n); P, Q (m x n, rows contiguous); b (m); alpha, beta (n).
  Vector p0_, q0_, alpha_, beta_, b_;
  Vector uniformRegularization_;  // m + 1 copies of curvature_regularization (plain MMA)
  RowMatrix P_, Q_;

  // Interior-point iterate: xsub_ (n), y, z, lambda, xsi, eta, mu, zeta, s (sizes as in the note).
  Vector xsub_, mu_, s_;
  double zeta_ = 0.0;
  // Trial point and Newton direction.
  Vector xOld_, yOld_, lambdaOld_, xsiOld_, etaOld_, muOld_, sOld_;
  double zOld_ = 0.0, zetaOld_ = 0.0;
  Vector dx_, dy_, dlambda_, dxsi_, deta_, dmu_, ds_;
  double dz_ = 0.0, dzeta_ = 0.0;

  // Work vectors of length n and m.
  Vector uxInv_, xlInv_, toAlphaInv_, toBetaInv_, plam_, qlam_, deltaX_, inverseDiagX_;
  Vector gvec_, deltaY_, diagY_, deltaLambda_;
  RowMatrix gradG_;        // m x n, dg_i/dx_j of the approximations at xsub_
  RowMatrix scaledGradG_;  // m x n, gradG_ * inverseDiagX_
  Matrix reducedMatrix_;   // (m+1) x (m+1)
  Vector reducedRhs_, reducedSolution_;
  Eigen::PartialPivLU<Matrix> reducedLu_;
};

}  // namespace hindsight
