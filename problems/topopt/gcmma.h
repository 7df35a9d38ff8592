// GCMMA: the globally convergent version of the Method of Moving Asymptotes (Svanberg 2002).
//
// Same problem form, approximations and subproblem solver as MMA (problems/topopt/mma.h), but every
// outer iteration is made conservative by inner iterations: the approximation f~_i of every function
// (objective i = 0, constraints i = 1..m) carries a curvature term rho_i d(x), and after each
// subproblem solve the caller's functions are evaluated at the trial point x^ (values only, no
// gradients). When f~_i(x^) + tolerance >= f_i(x^) for every i the approximations were conservative and
// x^ is accepted; otherwise rho_i grows for the functions that were not,
//   rho_i <- min(1.1 (rho_i + delta_i), 10 rho_i),   delta_i = (f_i(x^) - f~_i(x^)) / d(x^),
// (raising rho_i by delta_i would make f~_i(x^) = f_i(x^) exactly, see Mma::conservativeDistance) and the
// subproblem is solved again around the same x with the same asymptotes. At the start of every outer
// iteration rho_i = max(0.1/n sum_j |df_i/dx_j| (xmax_j - xmin_j), min_regularization) (the 2007 note).
//
// Consequences (Svanberg 2002, sec. 4): an accepted design x_{k+1} satisfies
//   f_i(x_{k+1}) <= f~_i(x_{k+1}) + tolerance <= tolerance   (feasible when x_k was), and
//   f0(x_{k+1}) <= f~0(x_{k+1}) + tolerance <= f0(x_k) + tolerance.
// Additions to the note, declared here:
//  * When x_k is feasible (every f_i(x_k) <= 0) a trial with f0(x^) > f0(x_k) is not accepted even if
//    it is within the tolerance: rho_0 is doubled instead. So the objective history of a feasible run
//    never increases, not even by the subproblem tolerance.
//  * A trial whose evaluation fails (the caller returns false: a diverged simulation) counts as
//    non-conservative in every function: every rho_i is multiplied by 10.
//  * GcmmaOptions::accept_descent (off by default): see there.
//  * After max_inner_iterations trials without an acceptable one the iteration keeps x_k (no move;
//    Summary::accepted = false). The state advances as after a move of zero.
// Between outer iterations GCMMA carries exactly the MMA state (rho restarts every outer iteration),
// so a run restored from a stored MmaState continues bit for bit.
//
// Cost: one function evaluation (values) per inner iteration; the number is reported per update.
//
// References:
//   K. Svanberg, A class of globally convergent optimization methods based on conservative convex
//     separable approximations, SIAM J. Optim. 12 (2002) 555-573.
//   K. Svanberg, MMA and GCMMA - two methods for nonlinear optimization, KTH Stockholm, 2007.
#pragma once

#include <hindsight/problems/topopt/mma.h>

#include <functional>
#include <string>

namespace hindsight {

struct GcmmaOptions {
  MmaOptions mma;                              ///< asymptotes, move limit, subproblem solver (as for MMA)
  int max_inner_iterations = 20;               ///< trials per outer iteration before x_k is kept; >= 1
  double initial_regularization_factor = 0.1;  ///< the 0.1 of rho_i's start value; > 0
  double min_regularization = 1e-5;            ///< lower bound of rho_i (raa0 of MMA); > 0
  /// Conservative means f~_i(x^) + tolerance >= f_i(x^); 0.5 epsimin in the note. >= 0.
  double conservative_tolerance = 0.5e-7;
  /// Descent acceptance (a declared variant, off by default): a trial is also accepted when it is
  /// not conservative but feasible (f_i(x^) <= 0 for every constraint that is not conservative) and
  /// its objective is below f0(x_k). The guarantee the caller sees is the same (accepted designs are
  /// feasible and no worse), but steps are not shortened where the true functions are better than
  /// the approximations; Svanberg's convergence proof does not cover it. The rod optimizer uses it:
  /// psi1 of the modal rod is not smooth where eigenvalues cross the truncation (the kept mode set
  /// changes), and pure GCMMA then shrinks its steps to nothing at such a kink.
  bool accept_descent = false;

  bool IsValid(std::string* error) const;
};

class Gcmma final {
 public:
  /// Function values at a trial design: objective f0 and the m constraint values. Returns false when
  /// the functions cannot be evaluated there (the trial is then rejected as non-conservative).
  using Evaluate = std::function<bool(const Vector& trial, double& objective, Vector& constraints)>;

  struct Summary {
    int inner_iterations = 0;  ///< trials evaluated in the last update (>= 1)
    int failed_evaluations = 0;
    bool accepted = false;  ///< false: no conservative trial within max_inner_iterations, x kept
    Vector regularization;  ///< rho_i (m + 1) of the accepted (or last) trial
  };

  /// Throws std::invalid_argument naming the argument when n < 1, m < 0 or the options are invalid.
  Gcmma(int n, int m, const GcmmaOptions& options = GcmmaOptions());

  /// One outer iteration from x (values and gradients at x as for Mma::update); `evaluate` is called
  /// at each trial. On return x is the accepted design (or unchanged, see accepted). Throws as
  /// Mma::update for bad arguments; exceptions of `evaluate` propagate with the state unchanged.
  void update(double objective, ConstVectorRef objective_gradient, ConstVectorRef constraints,
              ConstMatrixRef constraint_jacobian, ConstVectorRef xmin, ConstVectorRef xmax, Vector& x,
              const Evaluate& evaluate);

  const MmaState& state() const { return mma_.state(); }
  void restore(const MmaState& state) { mma_.restore(state); }
  const Summary& lastUpdate() const { return summary_; }
  const MmaSubproblemSummary& lastSubproblem() const { return mma_.lastSubproblem(); }

 private:
  int n_;
  int m_;
  GcmmaOptions options_;
  Mma mma_;
  Summary summary_;
};

}  // namespace hindsight
