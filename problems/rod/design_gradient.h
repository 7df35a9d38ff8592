// Chain rule from the engine's dpsi/dp (p = packed inertia invariants, invariants.h) to dpsi/dx_d for
// every design variable of the rod (docs/design.md §4, "Chain to the design").
//
// psi depends on x through p(x) = p(M(x), K(x), Phi(x)). Two parts:
//  * explicit: every invariant is a bilinear form A^T W B with W = M or K (full, unconstrained), and
//    dM/dx_d = rho'(x_d) Me0, dK/dx_d = E'(x_d) Ke0 on the element of d, so the explicit part is a sum
//    of small element-local products;
//  * through the eigenvectors Phi (on the free DOFs of the pinned-roller model), by
//    - AdjointNelson (default): per mode i, with g_i = dpsi/dphi_i, solve
//      (K - lambda_i M) z_i = h_i = g_i - (g_i^T phi_i) M phi_i once; then for every element
//      g_i^T phi_i' = -z_i^T (K' - lambda_i M' - lambda_i' M) phi_i - 1/2 (g_i^T phi_i) phi_i^T M' phi_i,
//      lambda_i' = phi_i^T (K' - lambda_i M') phi_i. The systems are solved together with the one
//      factorisation of K the eigen-solve made: the kept modes' part exactly from the eigenpairs, the
//      rest by conjugate gradients deflated by the kept modes and preconditioned with K (positive
//      definite there; design_gradient.cpp derives it). A mode that does not converge (spectral gap
//      lambda_{n+1} / lambda_n near 1) is solved with Nelson's modified operator below instead.
//    - NelsonPerVariable (the paper's route, Nelson 1976 "Simplified calculation of eigenvector
//      derivatives", AIAA J. 14(9)): per mode one factorisation of A_mod, then per design variable
//      A_mod v = -(K' - lambda M' - lambda' M) phi (row k zeroed), c = -1/2 phi^T M' phi - phi^T M v,
//      phi' = v + c phi. One solve per mode and per design variable.
// Both require simple eigenvalues (see ModalBasis::gapRatio / warning). A_mod, where it is used, is
// symmetric and indefinite: it is factorised as L D L^T without pivoting in one AMD ordering shared by
// all modes (Eigen::SparseLU with its own column ordering per mode, 3-5 times dearer, only where a pivot
// vanishes). The density law of Olhoff & Du (2005) has a kink at the
// threshold; there the right-hand derivative is used (SimpLaw).
//
// Hooks for terms that do not go through p: `eigenvalueGradient` (dpsi/dlambda_i, e.g. a frequency
// constraint) and `explicitDesignGradient` (a direct dpsi/dx, added as is).
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/modal_reduction.h>

#include <memory>

namespace hindsight {
namespace rod {

enum class EigenvectorSensitivityMethod { AdjointNelson, NelsonPerVariable };

struct DesignGradientOptions {
  EigenvectorSensitivityMethod method = EigenvectorSensitivityMethod::AdjointNelson;
  /// Adjoint route: conjugate-gradient iterations a mode may take before it is solved with Nelson's
  /// factorised operator instead (>= 0; 0 solves every mode directly).
  int adjointIterationLimit = 300;
};

/// Optional terms that bypass the invariants. Leave a vector empty to omit it.
struct DesignGradientExtras {
  Vector eigenvalueGradient;      ///< dpsi/dlambda_i, size basis.eigenmodeCount [units of psi s^2].
  Vector explicitDesignGradient;  ///< direct dpsi/dx_d, size model.designCount().
};

struct DesignGradientResult {
  Vector gradient;  ///< dpsi/dx_d, size model.designCount().
  int factorizations =
      0;  ///< factorisations of A_mod (per-variable route: one per mode; adjoint: fallbacks).
  /// Solves with A_mod, or (adjoint route) with K's factor: conjugate-gradient iterations + 1 per mode.
  int linearSolves = 0;
  double seconds = 0.0;  ///< wall time of the whole chain.
};

/// dpsi/dx for psi = psi(p(x)), p packed as in invariants.h with n = basis.columnCount().
/// Preconditions: `basis` was computed from `model` without inertia-relief modes.
/// Throws std::invalid_argument for a wrong size of `invariantGradient` or of an extra, or a basis with
/// inertia-relief modes (their design derivative is not implemented); throws std::runtime_error if A_mod
/// cannot be factorised (repeated eigenvalue).
/// The member is the plate or the solid (member.h); the solid's p carries MeeRot (invariants.h).
DesignGradientResult computeDesignGradient(const FeModel& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options = {},
                                           const DesignGradientExtras& extras = {});
DesignGradientResult computeDesignGradient(const SolidMember& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options = {},
                                           const DesignGradientExtras& extras = {});
/// The same with the factorisation of model.stiffness() the eigen-solve made (shared, not repeated).
DesignGradientResult computeDesignGradient(const FeModel& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras,
                                           const StiffnessFactorization& stiffnessFactorization);
DesignGradientResult computeDesignGradient(const SolidMember& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras,
                                           const StiffnessFactorization& stiffnessFactorization);

/// Derivative of eigenpair `mode` with respect to design variable `designIndex` by Nelson's method:
/// lambda' and phi' on the free DOFs (consistent with phi^T M phi = 1 and the sign convention).
/// Intended for tests and diagnostics (one factorisation of A_mod per call). Throws like
/// computeDesignGradient.
struct EigenpairDerivative {
  double eigenvalue = 0.0;
  Vector modeFree;
};
EigenpairDerivative computeEigenpairDerivative(const FeModel& model, const ModalBasis& basis, int mode,
                                               int designIndex);
EigenpairDerivative computeEigenpairDerivative(const SolidMember& model, const ModalBasis& basis, int mode,
                                               int designIndex);

}  // namespace rod
}  // namespace hindsight
