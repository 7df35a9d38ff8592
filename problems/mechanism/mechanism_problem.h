// The equations of motion of a planar mechanism (problems/mechanism/mechanism.h) with one flexible
// member in the floating frame of reference, as a SecondOrderProblem in minimal coordinates, so that
// every integrator, storage strategy, adjoint route and objective of the engine applies unchanged
// (docs/design.md §10).
//
// Coordinates. z = (x, y, theta of every rigid body; x, y, beta, q of the member), q the modal
// coordinates (the rod's modal basis, problems/rod/modal_reduction.h). The minimal coordinates are
// y = (the listed free rigid coordinates, q); the other rigid coordinates u are dependent and solved
// from the joints' and drivers' constraints Phi(z, t) = 0 by Newton's method. Velocities and
// accelerations follow from Phi_z z' + Phi_t = 0 and Phi_z z'' + gamma(z, z', t) = 0:
//   z' = R y' - (Phi_u^{-1} Phi_t),  z'' = R y'' + zeta,  R = [I; -Phi_u^{-1} Phi_y] (rows by index).
// The residual is d'Alembert's principle projected on the admissible virtual displacements,
//   r(t, y, y', y'', p) = R^T (M(z) z'' - Q(z, z', t)),
// with M, Q of the member from its inertia invariants (the quadratic velocity terms of the floating
// frame), rigid bodies' m and J, gravity, the elastic K_ee q and the springs. This is the choice of
// Lauss et al. ("The discrete adjoint method for parameter identification in multibody system
// dynamics", 2018) for minimal coordinates with closed loops: the engine's discrete adjoints of
// every integrator stay exact, at the price of a small Newton solve per evaluation. An index-3 DAE with
// generalized-alpha (Arnold & Bruls) would need a second adjoint for the constraint forces.
//
// The chord path (every evaluation). The joints attach to the member at A and B only, and B moves
// along the chord by c = b q, so the constraints see the modal coordinates only through c. Positions,
// velocities, R and zeta are therefore solved on the chord system: the rigid coordinates plus c, whose
// independent coordinates are sigma = (free coordinates, c), k = (number free) + 1 of them. The member's
// modal rows, F_q = C1^T rho + A1 beta'' + M_ee a + K_ee q - 2 beta' Ct q' - h beta'^2 (rho the frame's
// acceleration in its own axes), are written out, and the residual is
//   r_free = rho_free,  r_q = F_q + b rho_c,  rho = R_chord^T F_chord (k entries),
// where the member's frame rows of F_chord depend on q, q', a only through nine moments (s_w = m c +
// C1 q, J_w, A1 . a, C1 a, C1 q', h . q'). The Jacobians are the direct O(n^2) terms of F_q plus
// rank-few corrections: dual numbers run only through the chord system, in sigma and sigma' (the
// kinematics, 2k directions) and the moments (seven more), and the chain to q, q' uses the moments'
// gradients (C1, 2 h, Ct a, M_ee q', h). The mass matrix is the same in sigma'' and the moments of a;
// the product with b goes through c, c', c'' (three directions) and the explicit b rho_c.
//
// Derivatives are exact. The dependent coordinates' derivatives come from the implicit-function
// theorem, du = R_u dy with R of the double kinematics at the same point (in the reference path, whose
// b carries derivatives, one Newton correction in forward-mode dual numbers at the converged point,
// u = u* - Phi_u(z*)^{-1} Phi(z)); the solves with Phi_u in dual numbers take their values from the
// double kinematics and solve for the derivatives Phi_u^{-1} (b' - Phi_u' x) with its factorisation.
// The dual numbers have fixed sizes where the number of directions is fixed (2 for the kinematics, 9
// for the Jacobians without free coordinates, 3 for the parameter product). The rest of the parameter
// product (r_p)^T mu is linear in the invariants and written out by hand. The full-coordinate route (z
// with all of q, R^T (M(z) z'' - Q) by dual numbers in all 2f directions) stays as the tests' reference
// (the *ByProjection and *ByAutoDiff methods).
//
// Determinism and cost. Newton starts from the workspace's previous solution, moved along its tangent
// (du/dt, du/dsigma) for a short move (continuation from it when the motion is large): one
// factorisation of Phi_u at this predictor and simplified steps with it, ended by their rate. Its
// converged bits would depend on the history of calls, so the dependent coordinates are then rounded
// to a grid of 2^-20 and two or three simplified Newton steps are taken from there with Phi_u
// factorised at the grid point and sigma rounded to the same grid: the result is a function of
// (t, sigma) alone (unless two solutions lie within 1e-16 of a grid midpoint), so every storage
// strategy and thread count gets the same bits. That factorisation is a function of (t, grid point,
// rounded sigma) and is kept for the next solve with the same three (the integrator's Newton
// iterations), which then needs no factorisation at all. A workspace keeps the positions and
// kinematics of its last point, the dual kinematics of its last point, the member's products of q, q'
// and a (for a fixed p), and each body's sine and cosine with the angle's bits: the engine asks for
// the mass matrix, Jacobians, force and parameter product at one point.
//
// Parameters p: the member's invariants in the layout of problems/rod/invariants.h (b = the u_x row of
// the modes at B, which is how the member's B attaches), so problems/rod/design_gradient.h chains
// dpsi/dp to the element densities. The objective is psi1 = int q^T K_ee q dt as for the built-in model.
#pragma once

#include <hindsight/engine/second_order_problem.h>
#include <hindsight/problems/mechanism/mechanism.h>

#include <memory>

namespace hindsight::mechanism {

class MechanismProblem final : public SecondOrderProblem {
 public:
  static constexpr int kMaxModes = 40;
  static constexpr int kMaxFree = 6;
  /// Validates the description (std::invalid_argument naming the element) and assembles it at t = 0
  /// (std::invalid_argument when the initial positions cannot be assembled or the constraints are
  /// redundant there).
  MechanismProblem(const Mechanism& mechanism, int modeCount);
  ~MechanismProblem() override;

  std::string name() const override { return "mechanism"; }
  int coordinateCount() const override;
  int parameterSize() const override;
  int modeCount() const { return modes_; }
  int freeCount() const;
  const Mechanism& mechanism() const { return mechanism_; }
  /// Size of z (3 per rigid body, 3 + n for the member).
  int fullCoordinateCount() const;
  /// Offset of the member's (x, y, beta) in z (q follow).
  int memberOffset() const;

  std::unique_ptr<ProblemWorkspace> createModelWorkspace() const override;
  /// Keeps the symmetric part of M_ee of p for the whole solve.
  std::unique_ptr<ProblemWorkspace> createModelWorkspaceFor(ConstVectorRef p) const override;
  void initialCoordinates(ConstVectorRef p, VectorRef y0, VectorRef v0) const override;
  void massMatrix(double t, ConstVectorRef y, ConstVectorRef p, MatrixRef mass,
                  ProblemWorkspace* ws) const override;
  void force(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef f,
             ProblemWorkspace* ws) const override;
  void massMatrixAndForce(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, MatrixRef mass,
                          VectorRef f, ProblemWorkspace* ws) const override;
  void residualJacobians(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                         MatrixRef ry, MatrixRef rv, ProblemWorkspace* ws) const override;
  void addResidualParameterVjp(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                               ConstVectorRef p, ConstVectorRef mu, VectorRef out,
                               ProblemWorkspace* ws) const override;
  double integrand(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                   ProblemWorkspace* ws) const override;
  void addIntegrandStateGradient(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, double scale,
                                 VectorRef gy, VectorRef gv, ProblemWorkspace* ws) const override;
  void addIntegrandParameterGradient(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                     double scale, VectorRef gp, ProblemWorkspace* ws) const override;

  // ---- The reference path in full coordinates z (tests hold the chord path to it). ----
  /// M = R^T M(z) R and f = -R^T (M(z) zeta - Q) with R, zeta in full coordinates (O(n^3)).
  void massMatrixAndForceByProjection(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                      MatrixRef mass, VectorRef f, ProblemWorkspace* ws) const;
  /// r = R^T (M(z) z'' - Q) in full coordinates.
  void residualByProjection(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                            VectorRef r, ProblemWorkspace* ws) const;
  /// r_y, r_y' by dual numbers in all 2f directions through the full-coordinate residual.
  void residualJacobiansByAutoDiff(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                   ConstVectorRef p, MatrixRef ry, MatrixRef rv, ProblemWorkspace* ws) const;
  /// (r_p)^T mu with the b part by dual numbers in the n entries of b through the full-coordinate path.
  void addResidualParameterVjpByAutoDiff(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                         ConstVectorRef p, ConstVectorRef mu, VectorRef out,
                                         ProblemWorkspace* ws) const;

  // ---- Diagnostics and tests. ----
  /// r = M a - f.
  void residual(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p, VectorRef r,
                ProblemWorkspace* ws) const;
  /// z(t, y) and z'(t, y, y').
  void coordinates(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef z,
                   VectorRef zDot, ProblemWorkspace* ws) const;
  struct Energies {
    double kinetic = 0.0;      ///< 1/2 z'^T M(z) z'
    double potential = 0.0;    ///< strain 1/2 q^T K_ee q + gravity + springs
    double drivePower = 0.0;   ///< power of the drivers' constraint forces at the acceleration a
    double dissipation = 0.0;  ///< power dissipated by the dampers (>= 0)
  };
  Energies energies(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                    ProblemWorkspace* ws) const;

  struct Impl;

 private:
  Mechanism mechanism_;
  int modes_;
  std::unique_ptr<Impl> impl_;   ///< full coordinates (reference path, diagnostics)
  std::unique_ptr<Impl> chord_;  ///< the chord system (rigid coordinates and c = b q)
};

}  // namespace hindsight::mechanism
