// Modal reduction of the pinned-roller rod: the shape functions Phi of docs/design.md §2.
//
// Solves K phi = lambda M phi on the free DOFs (constrained K, M of FeModel) for the lowest n + 1
// eigenpairs by Spectra's Lanczos solver (SymEigsSolver) on the standard symmetric form of the pencil
// built from the one LDL^T of K (K is positive definite once A is pinned and B rolls; the largest
// eigenvalues of C = D^-1/2 L^-1 P M P^T L^-T D^-1/2 are 1/lambda), keeps the lowest n, and reports the
// spectral gap lambda_{n+1}/lambda_n: eigenvector sensitivities (Nelson 1976) degrade when the truncation
// cuts through a cluster.
//
// Modes are ascending in lambda, mass-normalised (phi^T M phi = 1) and signed deterministically: the
// first free-DOF entry whose magnitude is at least a tenth of the largest magnitude is positive. (The
// rule "largest entry positive" is not used because antisymmetric bending modes of a symmetric design
// have two extreme entries equal up to round-off, so the sign would be decided by round-off and jump
// under a finite-difference perturbation.)
//
// Optionally three static inertia-relief modes K^-1 M [e_x, e_y, S X] (restricted to the free DOFs) are
// appended, M-orthonormalised against the kept eigenmodes and each other (two passes of modified
// Gram-Schmidt). Their "eigenvalues" entries hold the Rayleigh quotients.
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/subtree_ldlt.h>
#include <hindsight/problems/rod/supernodal_ldlt.h>

#include <Eigen/SparseCholesky>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace hindsight {
namespace rod {

class SolidMember;

struct ModalReductionOptions {
  int modeCount = 10;                 ///< n eigenmodes kept, 1 <= n, n + 1 < free DOF count.
  bool inertiaReliefModes = false;    ///< append K^-1 M [e_x, e_y, S X] (3 more columns).
  double gapWarningThreshold = 1.05;  ///< warn when lambda_{n+1} / lambda_n is below this.
  double tolerance = 1e-13;           ///< Spectra convergence tolerance (relative, on Ritz values).
  int maxIterations = 1000;           ///< Spectra restarts.
  /// Block inverse-iteration + Rayleigh-Ritz steps applied to Spectra's n + 1 vectors (0 = none), one
  /// sparse Cholesky of K in total. Each step shrinks the error component of mode i outside the block by
  /// lambda_i / lambda_{n+2}. The solves K S = M V are iteratively refined with a residual accumulated in
  /// twice the working precision (compensatedResidual) and the projected stiffness S^T K S is summed over
  /// elements (elementwiseStiffnessForm): plain double products carry an absolute error
  /// ~eps |S|^T |K| |S|, i.e. ~eps lambda_max / lambda_1 relative in lambda_1 (2e-10 on a random
  /// 200 x 12 design), and that error, not Spectra's tolerance, was the noise of psi1 under tiny design
  /// changes. Without refinement (0) the eigenpairs are Spectra's, accurate to `tolerance` but not
  /// smooth in the design.
  int refinementSteps = 2;

  /// The options docs/design.md §2 implies for a RodConfig (modeCount, inertiaReliefModes).
  static ModalReductionOptions fromConfig(const RodConfig& config);
};

struct ModalBasis {
  /// lambda_i = omega_i^2 [1/s^2] of the eigenmodes (ascending), followed by the Rayleigh quotients of
  /// the inertia-relief modes if any. Size eigenmodeCount + reliefModeCount.
  Vector eigenvalues;
  /// Phi on the free DOFs, freeDofCount x (eigenmodeCount + reliefModeCount); Phi^T M Phi = I.
  Matrix modesFree;
  /// Phi on all DOFs (zeros at the constrained DOFs), dofCount x columns.
  Matrix modesFull;
  int eigenmodeCount = 0;
  int reliefModeCount = 0;
  /// lambda_{n+1} (first discarded eigenvalue) and the gap ratio lambda_{n+1} / lambda_n.
  double firstDiscardedEigenvalue = 0.0;
  double gapRatio = 0.0;
  /// Empty unless gapRatio < gapWarningThreshold; then a message naming the ratio.
  std::string warning;
  /// Phi^T K Phi of the columns as elementwiseStiffnessForm() sums it, kept from the refinement (its
  /// diagonal is the eigenvalues) so that computeInvariants() does not sum it a second time; empty when
  /// the refinement is off or there are inertia-relief modes. Like the eigenvalues it belongs to the modes:
  /// whoever changes modesFull clears it.
  Matrix stiffnessForm;
  /// Spectra counters, for the run summary.
  int iterations = 0;
  int operations = 0;

  int columnCount() const { return eigenmodeCount + reliefModeCount; }
  /// Natural frequency of eigenmode i in Hz.
  double frequencyHz(int mode) const;
};

/// B - A X with every product and sum accumulated in double-double (fma two-product, two-sum) and rounded
/// once: its error is ~eps |B - A X| instead of eps |A| |X|. Needed wherever A X nearly cancels, as
/// K phi - lambda M phi does for a mode phi when K spans many decades (stiffness contrast 1e5 in SIMP,
/// lambda_max / lambda_1 ~ 1e9). A is used as stored (both triangles).
Matrix compensatedResidual(ConstMatrixRef b, const SparseMatrix& a, ConstMatrixRef x);

/// X^T K X for the full stiffness of `model` and full-DOF columns X, summed element by element,
/// sum_e E(x_e) X_e^T (Ke0 X_e), with Ke0 X_e accumulated as in compensatedResidual. For near-eigenvectors
/// the element energies are non-negative, so the diagonal is accurate to ~eps relative and, above all,
/// smooth in the design: the assembled K is rounded entry by entry, and that rounding moves
/// phi^T K phi by ~eps |phi|^T |K| |phi| ~ eps lambda_max (1e-12 relative in lambda_1 on a random
/// 200 x 12 design), erratically as the design changes.
Matrix elementwiseStiffnessForm(const FeModel& model, ConstMatrixRef xFull);
Matrix elementwiseStiffnessForm(const SolidMember& model, ConstMatrixRef xFull);

/// The fill-reducing ordering of each member's factorisation of K. The plate keeps AMD: its ordering is
/// part of the recorded bits of the default configuration (tests/reproducibility/record.json). The solid
/// takes METIS's nested dissection: on its slender 3-D bars L has 28-35 % fewer nonzeros and the
/// factorisation, the eigen-solve and the chain's solves are the gradient's cost (bench/RESULTS.md,
/// "The solid's gradient"). Every StiffnessFactorization of a member is made with its ordering.
constexpr FillOrdering stiffnessOrdering(const FeModel&) { return FillOrdering::Amd; }
constexpr FillOrdering stiffnessOrdering(const SolidMember&) { return FillOrdering::Metis; }

/// One sparse LDL^T factorisation of the constrained stiffness K of a design (stiffnessOrdering), shared by
/// everything that solves with K: the eigen-solve (Lanczos on its transformed pencil), the refinement, the
/// inertia-relief modes and ESL (esl.h). The plate's (AMD) is Eigen's SimplicialLDLT with its
/// back-substitutions on the subtrees of the elimination tree in parallel, Eigen's bits
/// (SubtreeParallelLdlt, subtree_ldlt.h); the solid's (METIS) is hindsight's supernodal LDL^T
/// (SupernodalLdlt, supernodal_ldlt.h), its numeric factorisation 9 x the simplicial one's speed at
/// 200 x 12 x 8 (bench/RESULTS.md, "The supernodal factor"). Neither is
/// CHOLMOD: CHOLMOD's BLAS is picked at run time by the system (Debian alternatives), which would make the
/// bits depend on the machine.
class StiffnessFactorization {
 public:
  using Permutation = Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>;
  /// Throws std::runtime_error when K is not positive definite (a zero or negative pivot).
  StiffnessFactorization(const SparseMatrix& stiffness, FillOrdering ordering);
  StiffnessFactorization(const StiffnessFactorization&) = delete;
  StiffnessFactorization& operator=(const StiffnessFactorization&) = delete;
  /// Whether `stiffness` has the sparsity pattern this factorisation was analysed for (the same mesh and
  /// supports: the FE assembly scatters every design into the mesh's pattern).
  bool samePattern(const SparseMatrix& stiffness) const;
  /// Factorises another K of the same pattern with the symbolic analysis of the construction (the
  /// ordering, the elimination tree and the column counts depend on the pattern alone): the factor is
  /// bitwise the one a new object computes, without the analysis (0.6 s of 4.3 s at 1600 x 96).
  /// Throws std::invalid_argument for another pattern and std::runtime_error as the constructor.
  void refactorize(const SparseMatrix& stiffness);
  FillOrdering ordering() const { return ordering_; }
  /// The simplicial factor (FillOrdering::Amd); std::logic_error for the supernodal one.
  const SubtreeParallelLdlt& solver() const;
  /// The supernodal factor (FillOrdering::Metis); std::logic_error for the simplicial one.
  const SupernodalLdlt& supernodal() const;
  Eigen::Index size() const { return size_; }
  /// P K P^T = L D L^T: P, P^-1 and D of whichever factor.
  const Permutation& permutationP() const;
  const Permutation& permutationPinv() const;
  Vector vectorD() const;
  /// L^-1 and L^-T in place on right-hand sides stored by rows in the permuted order (the factor's
  /// forwardSweep and backwardSweep).
  void forwardSweep(double* x, Eigen::Index columns) const;
  void backwardSweep(double* x, Eigen::Index columns, bool parallel) const;
  /// Share of the back-substitution's work on parallel subtrees (tests, benchmarks).
  double parallelShare() const;
  /// K^-1 B.
  Matrix solve(ConstMatrixRef b) const;
  /// Right-hand sides stored by rows (one row per DOF, one column per right-hand side).
  using RowBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  /// K^-1 B in place for the columns of `block`, bitwise equal to solve() column by column: the same
  /// operations in the same order for each column. The triangular sweeps read each entry of L once for
  /// all columns, where a column-by-column solve streams the whole factor (60 MB at 800 x 48) once per
  /// column and is bound by memory bandwidth. `scratch` is resized on first use only.
  void solveInPlace(RowBlock& block, RowBlock& scratch) const;
  /// P^T L^{-T} B in place, the back-substitution alone (for the plate solver().matrixU().solveInPlace()
  /// and then permutationPinv() column by column, bitwise), in one sweep over the factor for all columns.
  void backSubstituteInPlace(RowBlock& block, RowBlock& scratch) const;

 private:
  void checkPositiveDefinite() const;
  /// Refuses a block without size() rows (std::invalid_argument naming `method`); sizes scratch to it.
  void prepareBlock(const char* method, const RowBlock& block, RowBlock& scratch) const;
  /// call(factor) on the live factor: the supernodal one for FillOrdering::Metis, the simplicial one
  /// otherwise (both have the same interface: compute, factorize, info, P, P^-1, D, the sweeps).
  template <class Call>
  decltype(auto) withFactor(Call&& call) const {
    return ordering_ == FillOrdering::Metis ? call(supernodal_) : call(simplicial_);
  }
  template <class Call>
  decltype(auto) withFactor(Call&& call) {
    return ordering_ == FillOrdering::Metis ? call(supernodal_) : call(simplicial_);
  }

  FillOrdering ordering_;
  SubtreeParallelLdlt simplicial_;
  SupernodalLdlt supernodal_;
  Eigen::Index size_ = 0;
  // The pattern the symbolic analysis is for (outer starts and row indices of K).
  std::vector<int> outer_, inner_;
};

/// Factorisations of K kept between the designs of one mesh, so that each design repeats only the numeric
/// factorisation (StiffnessFactorization::refactorize). take() hands out a kept one refactorised for the
/// given K, or a new one; give() keeps it for the next design. Thread-safe: concurrent evaluations each
/// get their own object. What a design computes does not depend on whether its factorisation was kept.
class StiffnessFactorizationPool {
 public:
  std::unique_ptr<StiffnessFactorization> take(const SparseMatrix& stiffness, FillOrdering ordering);
  void give(std::unique_ptr<StiffnessFactorization> factorization);
  /// Kept objects (tests).
  std::size_t size() const;

 private:
  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<StiffnessFactorization>> kept_;
};

/// Computes the modal basis of `model`, the plate or the solid (member.h).
/// Throws std::invalid_argument for modeCount < 1 or modeCount + 1 >= freeDofCount, or a
/// gapWarningThreshold < 1; throws std::runtime_error when Spectra does not converge (numerical outcome).
ModalBasis computeModalBasis(const FeModel& model, const ModalReductionOptions& options);
ModalBasis computeModalBasis(const SolidMember& model, const ModalReductionOptions& options);
/// The same with the factorisation of model.stiffness() supplied by the caller (who reuses it).
ModalBasis computeModalBasis(const FeModel& model, const ModalReductionOptions& options,
                             const StiffnessFactorization& stiffnessFactorization);
ModalBasis computeModalBasis(const SolidMember& model, const ModalReductionOptions& options,
                             const StiffnessFactorization& stiffnessFactorization);

}  // namespace rod
}  // namespace hindsight
