// The flexible connecting rod of a planar slider-crank in the floating frame of reference, reduced
// to its n modal coordinates q (docs/design.md §2-3; Held, Knuefer & Seifried).
//
// The crank (radius r) turns with the prescribed cycloidal ramp phi(t); the rod's body frame is the
// chord A-B, A on the crank pin, B on the guide through the crank pivot (roller: u_y(B) = 0), so the
// frame angle follows from the closure r sin(phi) + (L + b q) sin(beta) = 0. The equations of motion
// are M(t, q) q'' = f(t, q, q') of docs/design.md §3, written compactly as the residual
//   r = M_ee a + K_ee q + A1^T (beta_q a + beta_c) + g kappa b + C1^T rho - beta'^2 h - 2 beta' Ct q'
// with g = dbeta/dc (c = b q, beta_q = g b), rho = R^T r_A'', h = C2 + M_ee q and the scalar
//   kappa = A1 a + J_w (g b a + beta_c) + (S s_w) . rho + 2 beta' h . q'.
// This is d'Alembert's principle projected with delta beta = beta_q delta q; tests compare it with
// Lagrange's equations built from the nodal kinetic energy.
//
// Its role: the closed-form reference, test code and not part of the library (docs/design.md §10). The
// piston rod runs the same slider-crank through the general mechanism path (mechanism::sliderCrank and
// problems/mechanism/mechanism_problem.h), so that every mechanism takes one path; this class is the
// independent route the tests hold that path to (term by term, over a simulation and its adjoint), and
// the benchmarks' reference problem (bench/speed_bench.cpp, bench/rod_bench.cpp). It is built once, as
// the static library hindsight_slider_crank_reference, which those test and benchmark programs link.
//
// The parameters p are the inertia invariants of the rod (SliderCrankLayout), so the engine's dpsi/dp
// is what the design chain (problems/rod/design_gradient.h) turns into dpsi/dx. The objective is
// psi1 = int q^T K_ee q dt. Initial state: at rest, undeformed.
//
// Derivatives: the state Jacobians r_q, r_q' by forward-mode automatic differentiation (Eigen's
// AutoDiffScalar over a fixed-capacity derivative vector, so nothing is allocated in a step); the
// parameter product (r_p)^T mu by hand for the terms linear in the invariants and by AD over the
// three scalar channels (b q, b q', b a) for the nonlinear dependence on b. Every derivative is
// tested against finite differences (tests/problems/rod/slider_crank_test.cpp).
#pragma once

#include <hindsight/engine/second_order_problem.h>
#include <hindsight/problems/rod/crank_motion.h>

#include <cmath>

namespace hindsight::rod {

/// Offsets of the invariants in the parameter vector p, for n modes (the same order as
/// rod::InvariantLayout of problems/rod/invariants.h, which packs them; a test checks they agree):
/// m (1), m c (2), J0 (1), C1 (2 x n, column-major), C2 (n), a0 (n), Ct (n x n, column-major),
/// M_ee (n x n), K_ee (n x n), b (n). Size 4 + 5n + 3n^2.
struct SliderCrankLayout {
  int modes = 0;
  int mass() const { return 0; }
  int massMoment() const { return 1; }
  int polarMoment() const { return 3; }
  int c1() const { return 4; }
  int c2() const { return 4 + 2 * modes; }
  int a0() const { return 4 + 3 * modes; }
  int cTilde() const { return 4 + 4 * modes; }
  int mee() const { return 4 + 4 * modes + modes * modes; }
  int kee() const { return 4 + 4 * modes + 2 * modes * modes; }
  int b() const { return 4 + 4 * modes + 3 * modes * modes; }
  int size() const { return 4 + 5 * modes + 3 * modes * modes; }
};

class SliderCrankProblem final : public SecondOrderProblem {
 public:
  static constexpr int kMaxModes = 40;
  /// Throws std::invalid_argument for modeCount outside [1, 40], a non-positive length, or a crank
  /// radius not below the rod length (the mechanism must be able to turn).
  SliderCrankProblem(int modeCount, double rodLength, const CrankMotion& crank);

  std::string name() const override { return "slider-crank"; }
  int coordinateCount() const override { return layout_.modes; }
  int parameterSize() const override { return layout_.size(); }
  const SliderCrankLayout& layout() const { return layout_; }
  const CrankMotion& crank() const { return crank_; }
  double rodLength() const { return length_; }

  std::unique_ptr<ProblemWorkspace> createModelWorkspace() const override;
  /// Keeps the symmetric part of M_ee of p for the whole solve.
  std::unique_ptr<ProblemWorkspace> createModelWorkspaceFor(ConstVectorRef p) const override;
  void initialCoordinates(ConstVectorRef p, VectorRef y0, VectorRef v0) const override;
  void massMatrix(double t, ConstVectorRef q, ConstVectorRef p, MatrixRef mass,
                  ProblemWorkspace* ws) const override;
  void force(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef p, VectorRef f,
             ProblemWorkspace* ws) const override;
  /// One frame kinematics and one product of q with each invariant matrix for both.
  void massMatrixAndForce(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef p, MatrixRef mass,
                          VectorRef f, ProblemWorkspace* ws) const override;
  /// r_q and r_q' in O(n^2) from the compact residual: the frame differentiated in the channels
  /// c = b q, c' = b q' (the transposed form of residualStateVjp() for every mu at once).
  void residualJacobians(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                         MatrixRef rq, MatrixRef rv, ProblemWorkspace* ws) const override;
  /// The same Jacobians by forward-mode AD through the whole residual (O(n^3), 2n directions): an
  /// independent derivation the tests hold residualJacobians() to.
  void residualJacobiansByAutoDiff(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                                   ConstVectorRef p, MatrixRef rq, MatrixRef rv, ProblemWorkspace* ws) const;
  void addResidualParameterVjp(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                               ConstVectorRef p, ConstVectorRef mu, VectorRef out,
                               ProblemWorkspace* ws) const override;
  /// (r_q)^T mu and (r_q')^T mu in O(n^2), by hand from the compact residual, with the frame
  /// kinematics differentiated in the scalars c = b q and c' = b q' by forward AD. Explicit adjoint
  /// stages use this instead of the AD Jacobian (O(n^3)).
  bool hasResidualStateVjp() const override { return true; }
  void residualStateVjp(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                        ConstVectorRef mu, VectorRef outQ, VectorRef outV,
                        ProblemWorkspace* ws) const override;
  /// The state and parameter products with one set of product scalars.
  void residualVjps(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                    ConstVectorRef mu, VectorRef outQ, VectorRef outV, VectorRef gradient,
                    ProblemWorkspace* ws) const override;
  double integrand(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef p,
                   ProblemWorkspace* ws) const override;
  void addIntegrandStateGradient(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef p, double scale,
                                 VectorRef gq, VectorRef gv, ProblemWorkspace* ws) const override;
  void addIntegrandParameterGradient(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef p,
                                     double scale, VectorRef gp, ProblemWorkspace* ws) const override;

  /// The residual r = M(t, q) a - f(t, q, q') (for tests and diagnostics).
  void residual(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p, VectorRef r,
                ProblemWorkspace* ws) const;
  /// The frame angle beta(t, q) from the closure condition.
  double frameAngle(double t, ConstVectorRef q, ConstVectorRef p) const;

 private:
  SliderCrankLayout layout_;
  double length_;
  CrankMotion crank_;
};

}  // namespace hindsight::rod
