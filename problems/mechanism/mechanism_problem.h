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
// the product with b goes through c, c', c'' (three directions) and the explicit b rho_c. An explicit
// adjoint stage (RK4) needs only r_y^T mu and r_y'^T mu: the same dual pass, its derivatives combined with
// mu before the chain to q, q', and the direct terms as four products of mu_q with the invariant matrices
// (residualStateVjp(); no Jacobian, no M^{-1} r_y).
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
// The position solve. The constraints are put once, at construction, into block-triangular form (the
// Dulmage-Mendelsohn or BLT order of equation-based modelling compilers): a maximum matching of
// equations to dependent coordinates on the structural pattern of Phi_u (which coordinates each row's
// formula touches; a ground guide's zero direction component drops out), then Tarjan's strongly
// connected components of "equation needs the unknown matched to another". The blocks are solved in
// that order, each with the earlier ones fixed: a block affine in its unknowns (a pin's position, a
// driven angle, a guide) by one step from zero, exact; any other (a loop's closure) by Newton with a
// small dense LU from the last solution. The slider-crank's nine equations are nine 1 x 1 blocks with
// one nonlinear (the member's angle from the wrist pin), the four-bar's loop one 4 x 4 block. Every
// solve with Phi_u (R, z', zeta and the dual numbers' derivatives) is block forward substitution with
// the blocks factorised once per point; a block whose Jacobian is constant (coefficients +-1, a ground
// guide's direction) is factorised once at construction.
//
// What depends on time alone. A block whose equations touch only its own unknowns and earlier such
// blocks' (the driven crank, the member's A on it, a guided slider's y and angle) does not depend on the
// minimal coordinates: it is found once, at construction, in the block order. The dual passes skip its
// rows and solves (their derivatives are exactly zero), and a workspace keeps its polished positions and
// its rows' Jacobian entries and gamma with the bits of the time they were computed at, since the engine
// evaluates a step's predictor and Newton iterates at one time; the kept values are the bits a new
// evaluation would give, so nothing depends on the call history.
//
// Determinism and cost. An affine block's result is a function of the earlier blocks' and sigma. A
// nonlinear block's Newton result would depend on where it started (the history of calls), so its
// unknowns are then rounded to a grid of 2^-20 and Newton runs again from that grid point (two or three
// steps reach round-off): the result is a function of (t, sigma) alone, block by block (unless two
// solutions lie within 1e-16 of a grid midpoint), so every storage strategy and thread count gets the
// same bits. A motion of more than 0.25 (rad or m) since the last solve is followed in pieces
// (continuation), so that Newton stays on its branch. A workspace keeps the positions and kinematics of
// its last point, the dual kinematics of its last point, the member's products of q, q' and a (for a
// fixed p), and each body's sine and cosine with the angle's bits: the engine asks for the mass matrix,
// Jacobians, force and parameter product at one point.
//
// Parameters p: the member's invariants in the layout of problems/rod/invariants.h (b = the u_x row of
// the modes at B, which is how the member's B attaches; a solid's M_ee^xy after it), so
// problems/rod/design_gradient.h chains dpsi/dp to the element densities. The objective is psi1 = int q^T
// K_ee q dt as for the built-in model.
#pragma once

#include <hindsight/engine/second_order_problem.h>
#include <hindsight/problems/mechanism/mechanism.h>

#include <memory>
#include <string>
#include <vector>

namespace hindsight::mechanism {

class MechanismProblem final : public SecondOrderProblem {
 public:
  static constexpr int kMaxModes = 40;
  static constexpr int kMaxFree = 6;
  /// Validates the description (std::invalid_argument naming the element) and assembles it at t = 0
  /// (std::invalid_argument when the initial positions cannot be assembled or the constraints are
  /// redundant there).
  /// spatialMember: the member deforms in 3-D (a solid, problems/rod/member.h), and p carries the rotational
  /// modal mass M_ee^xy after b (problems/rod/invariants.h), which J_w and the centrifugal terms use in
  /// place of M_ee (docs/design.md, "The solid member in the mechanism").
  MechanismProblem(const Mechanism& mechanism, int modeCount, bool spatialMember = false);
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
  /// r_y^T mu and r_y'^T mu without forming the Jacobians (the transposed chord path): an explicit
  /// adjoint stage (RK4) then needs neither the Jacobians nor M^{-1} times them.
  bool hasResidualStateVjp() const override { return true; }
  void residualStateVjp(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                        ConstVectorRef mu, VectorRef outY, VectorRef outV,
                        ProblemWorkspace* ws) const override;
  /// Both products with one set of kinematics and modal products.
  void residualVjps(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                    ConstVectorRef mu, VectorRef outY, VectorRef outV, VectorRef gradient,
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

  /// One block of the position constraints' block-triangular order (the header's "position solve").
  struct ConstraintBlock {
    /// "joint.x", "joint.y" (revolute and fixed), "joint.angle" (fixed and prismatic), "joint.line"
    /// (prismatic), or the driver's name.
    std::vector<std::string> equations;
    std::vector<std::string> unknowns;  ///< "body.x", "body.y", "body.angle", matched to the equations
    bool affine = false;                ///< Phi is affine in the unknowns: one step from zero solves it
    /// The unknowns depend on time alone (not on the minimal coordinates): a driven crank and what it
    /// carries. Such blocks are solved and evaluated once per time, and the dual passes skip them.
    bool timeOnly = false;
    /// The equations' rows and the unknowns' columns in constraintPattern() and constraintJacobian().
    std::vector<int> rows, columns;
  };
  /// The blocks in the order they are solved (structural, fixed at construction).
  std::vector<ConstraintBlock> constraintBlocks() const;
  /// The structural pattern of Phi_u (1 where an entry may be nonzero; rows: the equations in the
  /// description's order, columns: the dependent coordinates) and Phi_u itself at the solved positions of
  /// (t, y).
  Eigen::MatrixXi constraintPattern() const;
  void constraintJacobian(double t, ConstVectorRef y, ConstVectorRef p, MatrixRef phiU,
                          ProblemWorkspace* ws) const;
  /// The chord system's coordinates at (t, y) by the block solve (z) and by dense Newton on all the
  /// constraints at once from z perturbed by 1e-3 (zDense): the reference of the block solve.
  void positionsBlockAndDense(double t, ConstVectorRef y, ConstVectorRef p, VectorRef z, VectorRef zDense,
                              ProblemWorkspace* ws) const;

  struct Impl;

 private:
  Mechanism mechanism_;
  int modes_;
  std::unique_ptr<Impl> impl_;   ///< full coordinates (reference path, diagnostics)
  std::unique_ptr<Impl> chord_;  ///< the chord system (rigid coordinates and c = b q)
};

}  // namespace hindsight::mechanism
