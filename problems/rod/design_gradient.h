// Chain rule from the engine's dpsi/dp (p = packed inertia invariants, invariants.h) to dpsi/dx_d for
// every design variable of the rod (docs/design.md §4, "Chain to the design").
//
// psi depends on x through p(x) = p(M(x), K(x), Phi(x)). Two parts:
//  * explicit: every invariant is a bilinear form A^T W B with W = M or K (full, unconstrained), and
//    dM/dx_d = rho'(x_d) Me0, dK/dx_d = E'(x_d) Ke0 on the element of d, so the explicit part is a sum
//    of small element-local products;
//  * through the eigenvectors Phi (on the free DOFs of the pinned-roller model), by
//    - AdjointNelson (default): per mode i, with g_i = dpsi/dphi_i and k = argmax |phi_i|,
//      h_i = g_i - (g_i^T phi_i) M phi_i, h_i(k) = 0, solve A_mod z_i = h_i once, where A_mod is
//      K - lambda_i M with row and column k replaced by the unit vector; then for every element
//      g_i^T phi_i' = -z_i^T (K' - lambda_i M' - lambda_i' M) phi_i - 1/2 (g_i^T phi_i) phi_i^T M' phi_i,
//      lambda_i' = phi_i^T (K' - lambda_i M') phi_i. One factorisation and one solve per mode.
//    - NelsonPerVariable (the paper's route, Nelson 1976 "Simplified calculation of eigenvector
//      derivatives", AIAA J. 14(9)): per mode one factorisation of A_mod, then per design variable
//      A_mod v = -(K' - lambda M' - lambda' M) phi (row k zeroed), c = -1/2 phi^T M' phi - phi^T M v,
//      phi' = v + c phi. One solve per mode and per design variable.
// Both require simple eigenvalues (see ModalBasis::gapRatio / warning). A_mod is symmetric and
// indefinite: it is factorised as L D L^T without pivoting in one AMD ordering shared by all modes
// (Eigen::SparseLU with its own column ordering per mode, 3-5 times dearer, only where a pivot vanishes).
// The factorisations depend on the model and the modes only (NelsonFactorizations), so PistonRod builds
// them while the time integration runs. The density law of Olhoff & Du (2005) has a kink at the
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
};

/// Optional terms that bypass the invariants. Leave a vector empty to omit it.
struct DesignGradientExtras {
  Vector eigenvalueGradient;      ///< dpsi/dlambda_i, size basis.eigenmodeCount [units of psi s^2].
  Vector explicitDesignGradient;  ///< direct dpsi/dx_d, size model.designCount().
};

struct DesignGradientResult {
  Vector gradient;         ///< dpsi/dx_d, size model.designCount().
  int factorizations = 0;  ///< factorisations of A_mod (one per mode).
  int linearSolves = 0;    ///< forward/backward solves with A_mod.
  double seconds = 0.0;    ///< wall time of the whole chain.
};

/// The factorised Nelson operators A_mod of every mode of a design (built in parallel over the modes).
/// Immutable once built; computeDesignGradient solves with them.
class NelsonFactorizations {
 public:
  /// Throws like computeDesignGradient (wrong basis, A_mod singular).
  NelsonFactorizations(const FeModel& model, const ModalBasis& basis);
  ~NelsonFactorizations();
  NelsonFactorizations(const NelsonFactorizations&) = delete;
  NelsonFactorizations& operator=(const NelsonFactorizations&) = delete;
  struct Impl;
  const Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

/// dpsi/dx for psi = psi(p(x)), p packed as in invariants.h with n = basis.columnCount().
/// Preconditions: `basis` was computed from `model` without inertia-relief modes.
/// Throws std::invalid_argument for a wrong size of `invariantGradient` or of an extra, or a basis with
/// inertia-relief modes (their design derivative is not implemented); throws std::runtime_error if A_mod
/// cannot be factorised (repeated eigenvalue).
DesignGradientResult computeDesignGradient(const FeModel& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options = {},
                                           const DesignGradientExtras& extras = {});
/// The same with the Nelson operators factorised beforehand (for this model and basis).
DesignGradientResult computeDesignGradient(const FeModel& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras,
                                           const NelsonFactorizations& factorizations);

/// Derivative of eigenpair `mode` with respect to design variable `designIndex` by Nelson's method:
/// lambda' and phi' on the free DOFs (consistent with phi^T M phi = 1 and the sign convention).
/// Intended for tests and diagnostics (one factorisation per call). Throws like computeDesignGradient.
struct EigenpairDerivative {
  double eigenvalue = 0.0;
  Vector modeFree;
};
EigenpairDerivative computeEigenpairDerivative(const FeModel& model, const ModalBasis& basis, int mode,
                                               int designIndex);

}  // namespace rod
}  // namespace hindsight
