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
//   b    (n)                    row of Phi for u_x at B
// Modal columns carry the units of a mass-normalised mode (1/sqrt(kg)).
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/modal_reduction.h>

#include <Eigen/Core>

namespace hindsight {
namespace rod {

/// Offsets of each block inside the packed vector, for n modal columns.
struct InvariantLayout {
  explicit InvariantLayout(int modeCount);
  int modeCount;
  int mass = 0, massTimesCenter = 1, polarMoment = 3;
  int c1, c2, a0, cTilde, mee, kee, b, size;
};

struct InertiaInvariants {
  double mass = 0.0;
  Eigen::Vector2d massTimesCenter = Eigen::Vector2d::Zero();
  double polarMoment = 0.0;
  Matrix c1;      ///< 2 x n
  Vector c2;      ///< n
  Vector a0;      ///< n (the row (S X)^T M Phi stored as a column)
  Matrix cTilde;  ///< n x n
  Matrix mee;     ///< n x n
  Matrix kee;     ///< n x n
  Vector b;       ///< n

  int modeCount() const { return static_cast<int>(c2.size()); }
  static int packedSize(int modeCount) { return InvariantLayout(modeCount).size; }
  /// Packs into the order documented at the top of this file.
  Vector pack() const;
  /// Inverse of pack(). Throws std::invalid_argument if p.size() != packedSize(modeCount).
  static InertiaInvariants unpack(ConstVectorRef packed, int modeCount);
};

/// Computes the invariants of `model` with the modal basis `basis` (which must come from `model`).
/// Throws std::invalid_argument if basis.modesFull has not model.dofCount() rows.
InertiaInvariants computeInvariants(const FeModel& model, const ModalBasis& basis);

}  // namespace rod
}  // namespace hindsight
