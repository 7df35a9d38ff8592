// The full-order (unreduced) elastodynamic variant of the piston rod (docs/design.md §9): a state
// large enough for trajectory storage to matter, with the same design parameters as the reduced model.
//
// Model. u in R^n are all free nodal displacements of the pinned (A) / roller (B) FE model of
// rod::FeModel, in the body frame. The frame follows the rigid mechanism without feedback from u:
//   beta_r(t) = asin(-r sin(phi) / L),
// so a material point at reference position xbar has the frame acceleration (body components)
//   a_P = R(beta_r)^T r_A'' + beta_r'' S xbar - beta_r'^2 xbar,     r_A = r (cos phi, sin phi).
// d'Alembert's principle with r_P = r_A + R (xbar + u) gives the linear time-varying equations
//   M u'' + C(t) u' + A(t) u = -f(t),                                                  (docs/design.md §9)
//   C = 2 beta_r' M_S,   A = K - beta_r'^2 M + beta_r'' M_S,   f = P^T M_full a_full(t),
// where P embeds the free DOFs in all DOFs, M = P^T M_full P, K = P^T K_full P and
// M_S = P^T M_full S_n P with S_n = S = [[0, -1], [1, 0]] applied node-wise. Consistent Q4 mass is
// (scalar mass) (x) I_2, so M_full S_n = (scalar mass) (x) S is skew and so is M_S (a test checks it):
// the Coriolis term is gyroscopic and does no work; C and A are nevertheless not symmetric.
// The load f uses the full mass matrix because S_n and a_full reach constrained DOFs (u_y at B).
// The terms with u in C and A are the relative Coriolis, centrifugal and Euler terms; with
// `coupling = false` they are dropped (C = 0, A = K), the load f is kept. Not modelled at all:
// feedback of u on the frame (the reduced model's b q in the closure), geometric stiffening, damping.
//
// First-order form: z = (u, v), size 2n, F = (v, -M^{-1}(A u + C v + f)). Objective
//   psi1,full = int_0^t1 u^T K u dt  [N m s], comparable with the reduced psi1 = int q^T K_ee q dt.
// Parameters p: the design x (rod::RodConfig::designCount() entries). The problem is built for one
// design (FeModel, sparse M, K, M_S, the Cholesky factor of M); p passed to the methods must equal that
// design (initialState() checks it and throws std::invalid_argument; the other methods assume it).
// (F_p)^T w and G_p are element-local with the SIMP derivatives: dK/dx_e = E'(x_e) Ke0,
// dM/dx_e = rho'(x_e) Me0 on the element's DOFs; for F_2 = -M^{-1} g:
//   w_2^T dF_2/dx_e = -mu^T (dM/dx_e F_2 + dg/dx_e),   mu = M^{-1} w_2.
// State products: F_z^T w = (-A^T mu, w_1 - C^T mu).
// Newton matrix of an implicit stage: (I - alpha F_z) x = b reduces to the Schur complement
//   (M + alpha C + alpha^2 A) x_2 = M b_2 - alpha A b_1,   x_1 = b_1 + alpha x_2,
// and its transpose to (M + alpha C^T + alpha^2 A^T) w = b_2 + alpha b_1, y_2 = M w,
// y_1 = b_1 - alpha A^T w. The solver factorises the symmetric positive definite P0 = M + alpha0^2 K
// (sparse LL^T; alpha0 = alpha rounded to 20 mantissa bits, a function of alpha alone so that
// recomputations reproduce their bits) and reaches the exact non-symmetric matrix by iterative
// refinement x <- x + P0^{-1}(r - P x), converging at rate ~ alpha (2 |beta_r'| + alpha |beta_r''|)
// (about 3e-3 at h = 1e-3 with TR-BDF2, 4-6 refinement sweeps to round-off); a fixed-step run
// therefore factorises once (the engine's "factorizations" counter counts factorize() calls, most of
// which reuse the factor). It throws NewtonFailure when the refinement does not contract (alpha far
// too large for the coupling terms).
//
// Allocation: rhs, rhsStateVjp, addRhsParameterVjp, the integrand terms, Newton solves and
// factorize() calls for an unchanged alpha0 allocate nothing (natural ordering: the node numbering
// along the rod is already a narrow band, so no permutation buffers). factorize() with a new alpha0
// re-runs the numeric sparse Cholesky, which allocates its scratch.
//
// Newton: the model is linear in the state and the solver above is exact to round-off, so the problem
// declares isLinearInState() and the engine takes one Newton step per implicit stage (a second one would
// only confirm it at the stage residual's round-off, ~1e-11 ||Z||: F sums terms omega_max^2 u ~ 1e8
// larger than itself; evaluateFullOrderRod() still raises the engine's tolerance 1e-13 to 1e-10 for
// any caller that iterates).
//
// Measured (bench/RESULTS.md): at x0 on 200 x 12, TR-BDF2 h = 1e-3, psi1,full = 0.25249 against the
// reduced psi1 = 0.25253 (-1.6e-4: modal truncation and the reduced model's frame feedback b q); the
// coupling terms contribute 1.4e-4; dpsi1/dx agrees with the reduced chain's to 5.4e-4 (norm).
//
// Sizes: n = 2 (nx+1)(ny+1) - 3 free DOFs (5223 at 200 x 12, state 10446). Units SI.
// Stiffness: the highest FE frequency grows like 1/element size (1.86e6 rad/s at 200 x 12, x = 0.5), so
// explicit methods need h < 2.8 / omega_max; evaluateFullOrderRod() refuses an unstable explicit step.
#pragma once

#include <hindsight/engine/adjoint.h>
#include <hindsight/problems/rod/crank_motion.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/rod_config.h>

#include <Eigen/SparseCholesky>

#include <memory>
#include <string>

namespace hindsight {
namespace rod {

/// The rigid frame's motion at time t: beta_r and its rates, and R^T r_A'' (body components).
struct RigidFrameMotion {
  double angle = 0.0;             ///< beta_r [rad]
  double rate = 0.0;              ///< beta_r' [rad/s]
  double acceleration = 0.0;      ///< beta_r'' [rad/s^2]
  double pinAccelerationX = 0.0;  ///< (R^T r_A'')_x [m/s^2]
  double pinAccelerationY = 0.0;  ///< (R^T r_A'')_y [m/s^2]
};
/// beta_r = asin(-r sin(phi) / L) and its derivatives; requires r < L.
RigidFrameMotion rigidFrameMotion(const CrankMotion& crank, double length, double t);

class FullOrderRodProblem final : public Problem {
 public:
  /// Builds the FE model of `design` and factorises M. Throws std::invalid_argument for an invalid
  /// config or design (see FeModel), and std::runtime_error if M is not positive definite.
  FullOrderRodProblem(const RodConfig& config, ConstVectorRef design, bool coupling = true);
  /// Same with an explicit crank (tests use a short ramp).
  FullOrderRodProblem(const RodConfig& config, ConstVectorRef design, const CrankMotion& crank,
                      bool coupling);
  ~FullOrderRodProblem() override;

  std::string name() const override { return "full-order-rod"; }
  int stateSize() const override { return 2 * n_; }
  int parameterSize() const override { return model_.designCount(); }
  int freeDofCount() const { return n_; }
  bool coupling() const { return coupling_; }
  const FeModel& model() const { return model_; }
  const CrankMotion& crank() const { return crank_; }
  /// M_S = P^T M_full S_n P (free DOFs).
  const SparseMatrix& rotatedMass() const { return rotatedMass_; }

  /// f(t) = P^T M_full a_full(t) on the free DOFs [N]; the equations read M u'' + C u' + A u = -f.
  void inertialLoad(double t, VectorRef f) const;
  /// The largest eigenvalue of M^{-1} K (omega_max^2 [1/s^2]) by power iteration (for step-size checks).
  double largestEigenvalue(int iterations = 200) const;

  std::unique_ptr<ProblemWorkspace> createWorkspace() const override;
  void initialState(ConstVectorRef p, VectorRef z0) const override;
  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace* ws) const override;
  bool hasDenseJacobian() const override { return false; }
  void rhsStateVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                   ProblemWorkspace* ws) const override;
  void addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace* ws) const override;
  std::unique_ptr<NewtonSolver> createNewtonSolver() const override;
  /// F is affine in z and the Newton solver refines to round-off: one Newton step per implicit stage.
  bool isLinearInState() const override { return true; }
  double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace* ws) const override;
  void addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale, VectorRef out,
                                 ProblemWorkspace* ws) const override;
  void addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                     VectorRef out, ProblemWorkspace* ws) const override;

  /// out = A(t) x and out = A(t)^T x (free DOFs); C(t) x = 2 beta_r' M_S x (0 without coupling).
  void applyStiffnessOperator(const RigidFrameMotion& frame, ConstVectorRef x, VectorRef out,
                              bool transposed) const;
  /// x <- M^{-1} x in place, without allocation.
  void solveMass(VectorRef x) const;

 private:
  class Workspace;
  class Newton;
  void build();
  /// out = M^{-1} g with g = A u + C v + f(t) for z = (u, v), so that F_2 = -out.
  void massSolvedForce(const RigidFrameMotion& frame, ConstVectorRef z, VectorRef out) const;

  FeModel model_;
  CrankMotion crank_;
  bool coupling_;
  int n_;
  SparseMatrix rotatedMass_;                           // M_S
  Vector loadX_, loadY_, loadRotated_, loadPosition_;  // P^T M_full {e_x, e_y, S X, X}
  Eigen::SimplicialLLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>> massFactor_;
};

/// The recommended time stepping for the full-order model (the CLI's `--model full` default): TR-BDF2 is
/// L-stable, so the FE modes far above the load's spectrum are damped instead of limiting the step;
/// at h = 1e-3 s (omega_1 h ~ 0.2) psi1,full changes by 4e-6 relative when h is halved (40 x 4 mesh).
inline constexpr const char* kFullOrderDefaultIntegrator = "trbdf2";
inline constexpr double kFullOrderDefaultStep = 1e-3;

}  // namespace rod
}  // namespace hindsight
