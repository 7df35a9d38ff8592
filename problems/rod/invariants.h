// Inertia invariants of the reduced flexible rod (docs/design.md §3, table "Inertia invariants").
//
// Every invariant is a bilinear form A^T W B with W the FULL (unconstrained) mass matrix M or stiffness
// matrix K of FeModel and A, B drawn from {e_x, e_y, X, S X, Phi, S^T Phi}; Phi is the modal basis
// extended by zeros at the constrained DOFs. Using the full M makes the rigid-body quantities (m, m c,
// J0) include the mass lumped at the constrained nodes. M_ee and K_ee are computed as bilinear forms,
// not assumed to be I and Lambda, so that their design derivatives are consistent.
//
// With n = basis.columnCount() (eigenmodes plus inertia-relief modes), the packed parameter vector p
// of the engine has packedSize(n) = 4 + 5 n + 3 n^2 entries in this fixed order:
//   [0]            m                        e_x^T M e_x                      [kg]
//   [1, 2]         m c = (e_x^T M X, e_y^T M X)                              [kg m]
//   [3]            J0 = X^T M X (about A, the body-frame origin)            [kg m^2]
//   C1   (2 x n, column-major)  [e_x e_y]^T M Phi
//   C2   (n)                    Phi^T M X
//   a0   (n)                    (S X)^T M Phi
//   Ctilde (n x n, col-major)   Phi^T M (S^T Phi), S^T node-wise; skew-symmetric
//   Mee  (n x n, col-major)     Phi^T M Phi
//   Kee  (n x n, col-major)     Phi^T K Phi
//   b    (n)                    row of Phi for u_x at B (the solid: the mean over B's axis)
// and for a member that deforms in 3-D (the solid, solid_member.h) one block more, n^2 entries:
//   MeeRot (n x n, col-major)   Phi^T M_xy Phi, the modal mass of the in-plane components
// Modal columns carry the units of a mass-normalised mode (1/sqrt(kg)).
//
// The solid (docs/design.md, "The solid member in the mechanism"). The member frame rotates about z by
// beta; a material point at X + u (3-D) moves with r = R + A(beta) (X + u), and A' = beta' A S with S the
// rotation generator about z, whose z row and column are zero. Every term of the kinetic energy that comes
// from the rotation (beta' S (X + u)) therefore sees only the x and y components: J0, C2, a0, Ct and the
// q^T (.) q part of J_w use X and Phi projected on the plane (X_xy, Phi_xy), C1 pairs with e_x, e_y, while
// the relative kinetic energy 1/2 q'^T Phi^T M Phi q' sees all three, Mee. With M = M_s (x) I_3 (the
// consistent mass does not couple components), Phi_xy^T M Phi_xy = Phi^T M Phi_xy: the block MeeRot. For
// the plate both are Mee and the block is absent (the layout, and every bit, as before).
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/modal_reduction.h>

#include <Eigen/Core>

namespace hindsight {
namespace rod {

/// Offsets of each block inside the packed vector, for n modal columns.
struct InvariantLayout {
  /// spatial: a member that deforms in 3-D, with the block MeeRot after b.
  explicit InvariantLayout(int modeCount, bool spatial = false);
  int modeCount;
  bool spatial;
  int mass = 0, massTimesCenter = 1, polarMoment = 3;
  int c1, c2, a0, cTilde, mee, kee, b;
  int meeRotation;  ///< the block MeeRot of a spatial member; -1 for the plate
  int size;
};

struct InertiaInvariants {
  double mass = 0.0;
  Eigen::Vector2d massTimesCenter = Eigen::Vector2d::Zero();
  double polarMoment = 0.0;
  Matrix c1;           ///< 2 x n
  Vector c2;           ///< n
  Vector a0;           ///< n (the row (S X)^T M Phi stored as a column)
  Matrix cTilde;       ///< n x n
  Matrix mee;          ///< n x n
  Matrix kee;          ///< n x n
  Vector b;            ///< n
  Matrix meeRotation;  ///< n x n of a spatial member (the solid), empty for the plate

  int modeCount() const { return static_cast<int>(c2.size()); }
  bool spatial() const { return meeRotation.size() != 0; }
  static int packedSize(int modeCount, bool spatial = false) {
    return InvariantLayout(modeCount, spatial).size;
  }
  /// Packs into the order documented at the top of this file.
  Vector pack() const;
  /// Inverse of pack(), of a plate's or (by the size) a spatial member's packed vector. Throws
  /// std::invalid_argument if p.size() is neither packedSize(modeCount) nor packedSize(modeCount, true).
  static InertiaInvariants unpack(ConstVectorRef packed, int modeCount);
};

/// Computes the invariants of `model`, the plate or the solid (member.h), with the modal basis `basis`
/// (which must come from `model`). Throws std::invalid_argument if basis.modesFull has not
/// model.dofCount() rows.
InertiaInvariants computeInvariants(const FeModel& model, const ModalBasis& basis);
InertiaInvariants computeInvariants(const SolidMember& model, const ModalBasis& basis);

/// Phi_xy: the columns with their z components set to zero (components = 3); the columns themselves for
/// components = 2.
Matrix planarComponents(ConstMatrixRef full, int components);

}  // namespace rod
}  // namespace hindsight
