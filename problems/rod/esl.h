// Equivalent static load (ESL) objective psi2 of docs/design.md §2 (reference/, eq. 13; Kang & Park 2005).
//
// From a dynamic simulation at design x_s one takes the modal coordinates q_k = q(t_k) at
// t_k = k t1 / N, k = 1..N, and forms the loads f_k = K(x_s) Phi(x_s) q_k (free DOFs of the pinned-roller
// model). These loads are then held fixed (design independent) and the static compliance sum
//   psi2(x) = (t1 / N) sum_k f_k^T u_k,   K(x) u_k = f_k,
//   dpsi2/dx_d = -(t1 / N) sum_k u_k^T (dK/dx_d) u_k
// is evaluated with one sparse Cholesky factorisation of K(x) and N right-hand sides. At x = x_s,
// u_k = Phi q_k and psi2 = (t1 / N) sum_k q_k^T K_ee q_k. The gradient is the ESL approximation: it
// ignores that the loads come from a dynamic simulation at the current design (that is the point of
// comparing it with the exact psi1 route).
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/modal_reduction.h>

namespace hindsight {
namespace rod {

class SolidMember;

/// Loads f_k = K Phi q_k as columns, freeDofCount x N [N]. `modalCoordinates` is n x N with
/// n = basis.columnCount(), column k - 1 holding q(t_k).
/// Throws std::invalid_argument if the sizes do not match.
Matrix equivalentStaticLoads(const FeModel& model, const ModalBasis& basis, ConstMatrixRef modalCoordinates);

struct EslResult {
  double value = 0.0;    ///< psi2 [J s]
  Vector gradient;       ///< dpsi2/dx_d, size model.designCount()
  Matrix displacements;  ///< u_k on the free DOFs, freeDofCount x N [m]
};

/// psi2 and its gradient for fixed loads (freeDofCount x N) at the design of `model`; endTime = t1 [s].
/// Throws std::invalid_argument for a wrong load size, no load column or endTime <= 0; throws
/// std::runtime_error if K is not positive definite.
EslResult evaluateEsl(const FeModel& model, ConstMatrixRef loads, double endTime);
/// The same with the caller's factorisation of model.stiffness(); the gradient only when `withGradient`
/// (EslResult::gradient is then empty).
EslResult evaluateEsl(const FeModel& model, ConstMatrixRef loads, double endTime,
                      const StiffnessFactorization& stiffnessFactorization, bool withGradient);

/// psi2 at the design the loads come from, where u_k = Phi q_k exactly: the value
/// (t1 / N) sum_k q_k^T K_ee q_k from the modal stiffness `kee` = Phi^T K Phi (n x n; the invariants'
/// element-wise form) and the gradient from the displacements Phi q_k, without solving with K. The same
/// quantity as evaluateEsl() on equivalentStaticLoads(), without its round-off: the solve through K's
/// factor loses up to ~4e-10 relative on a design with weak elements (K's condition grows like
/// 1 / E(x_min)). `modalCoordinates` is n x N, column k - 1 holding q(t_k); EslResult::displacements is
/// left empty. Throws std::invalid_argument if the sizes do not match or endTime <= 0.
EslResult evaluateEslAtLoadDesign(const FeModel& model, const ModalBasis& basis, ConstMatrixRef kee,
                                  ConstMatrixRef modalCoordinates, double endTime, bool withGradient);
/// The same for the solid member (member.h).
EslResult evaluateEslAtLoadDesign(const SolidMember& model, const ModalBasis& basis, ConstMatrixRef kee,
                                  ConstMatrixRef modalCoordinates, double endTime, bool withGradient);

}  // namespace rod
}  // namespace hindsight
