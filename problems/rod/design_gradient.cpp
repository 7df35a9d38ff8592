#include <hindsight/problems/rod/design_gradient.h>

#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/rod/invariants.h>
#include <hindsight/problems/rod/parallel.h>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace hindsight {
namespace rod {
namespace {

// Gathers the rows of the element DOFs of a full-DOF matrix.
Eigen::Matrix<double, 8, Eigen::Dynamic> gatherRows(const Matrix& full, const std::array<int, 8>& dofs) {
  Eigen::Matrix<double, 8, Eigen::Dynamic> local(8, full.cols());
  for (int a = 0; a < 8; ++a) local.row(a) = full.row(dofs[a]);
  return local;
}

ElementVector gather(const Vector& full, const std::array<int, 8>& dofs) {
  ElementVector local;
  for (int a = 0; a < 8; ++a) local(a) = full(dofs[a]);
  return local;
}

using Permutation = Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>;

// The fill-reducing ordering (AMD) of the pattern of K - lambda M, the same for every mode: computed
// once per design and shared by all Nelson systems, so each factorisation does only its numeric part
// (and the cheap elimination tree of the permuted pattern).
Permutation nelsonOrdering(const FeModel& model) {
  const SparseMatrix pattern = model.stiffness() + model.mass();
  Permutation inverse;
  Eigen::AMDOrdering<int>()(pattern, inverse);
  return inverse.inverse();
}

// K and M on the free DOFs, both in the pattern of K + M and permuted symmetrically into the shared
// ordering, once per design: each mode's operator K - lambda M is then formed on the value arrays, entry
// by entry the arithmetic of the sparse difference (k - lambda m; an entry absent from one matrix is an
// explicit zero there), without a sparse sum and a symmetric permutation per mode.
struct PermutedOperators {
  SparseMatrix stiffness, mass;
};

PermutedOperators permutedOperators(const FeModel& model, const Permutation& ordering) {
  SparseMatrix stiffness = model.stiffness() + 0.0 * model.mass();
  SparseMatrix mass = 0.0 * model.stiffness() + model.mass();
  stiffness.makeCompressed();
  mass.makeCompressed();
  PermutedOperators permuted;
  permuted.stiffness = stiffness.selfadjointView<Eigen::Lower>().twistedBy(ordering);
  permuted.mass = mass.selfadjointView<Eigen::Lower>().twistedBy(ordering);
  permuted.stiffness.makeCompressed();
  permuted.mass.makeCompressed();
  if (permuted.stiffness.nonZeros() != permuted.mass.nonZeros() ||
      !std::equal(permuted.stiffness.innerIndexPtr(),
                  permuted.stiffness.innerIndexPtr() + permuted.stiffness.nonZeros(),
                  permuted.mass.innerIndexPtr()))
    throw std::logic_error("Nelson operators: K and M do not share one permuted pattern");
  return permuted;
}

// Nelson's modified operator for one mode: K - lambda M with row and column k replaced by e_k, where
// k = argmax |phi| (free-DOF index). Factorised once, reused for every right-hand side.
//
// The operator is symmetric and indefinite (lambda_i lies inside the spectrum): it is factorised as
// L D L^T without pivoting in the shared AMD ordering, 3-5 times cheaper than a sparse LU with its own
// column ordering. Should a pivot vanish (D with a zero or non-finite entry), the system falls back to
// the pivoting sparse LU.
class NelsonSystem {
 public:
  NelsonSystem(const FeModel& model, double eigenvalue, const Vector& modeFree, const Permutation& ordering,
               const PermutedOperators& operators)
      : ordering_(ordering) {
    modeFree.cwiseAbs().maxCoeff(&pivot_);
    // P (K - lambda M) P^T with the pivot's row and column (index P(k) after the permutation) set to e.
    SparseMatrix permuted = operators.stiffness;
    const Eigen::Index count = permuted.nonZeros();
    Eigen::Map<Vector>(permuted.valuePtr(), count) -=
        eigenvalue * Eigen::Map<const Vector>(operators.mass.valuePtr(), count);
    const int permutedPivot = ordering_.indices()(pivot_);
    for (int column = 0; column < permuted.outerSize(); ++column) {
      for (SparseMatrix::InnerIterator it(permuted, column); it; ++it) {
        if (it.row() == permutedPivot || column == permutedPivot)
          it.valueRef() = (it.row() == column) ? 1.0 : 0.0;
      }
    }
    ldlt_.compute(permuted);
    const bool pivotsUsable = ldlt_.info() == Eigen::Success && ldlt_.vectorD().allFinite() &&
                              (ldlt_.vectorD().array() != 0.0).all();
    if (pivotsUsable) return;
    useLu_ = true;
    SparseMatrix matrix = model.stiffness() - eigenvalue * model.mass();
    matrix.makeCompressed();
    for (int column = 0; column < matrix.outerSize(); ++column) {
      for (SparseMatrix::InnerIterator it(matrix, column); it; ++it) {
        if (it.row() == pivot_ || column == pivot_) it.valueRef() = (it.row() == column) ? 1.0 : 0.0;
      }
    }
    lu_.analyzePattern(matrix);
    lu_.factorize(matrix);
    if (lu_.info() != Eigen::Success) {
      std::ostringstream message;
      message << "Nelson's modified matrix K - lambda M (lambda = " << eigenvalue
              << ") is singular: the eigenvalue is repeated or the mode is degenerate ("
              << lu_.lastErrorMessage() << ")";
      throw std::runtime_error(message.str());
    }
  }
  Eigen::Index pivot() const { return pivot_; }
  /// Solves with the right-hand side's pivot entry set to zero (so the solution's pivot entry is zero).
  Vector solve(Vector rightHandSide) const {
    rightHandSide(pivot_) = 0.0;
    if (useLu_) return lu_.solve(rightHandSide);
    const Vector permuted = ordering_ * rightHandSide;
    return ordering_.transpose() * Vector(ldlt_.solve(permuted));
  }

 private:
  const Permutation& ordering_;
  Eigen::Index pivot_ = 0;
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>> ldlt_;
  bool useLu_ = false;
  Eigen::SparseLU<SparseMatrix> lu_;
};

}  // namespace

struct NelsonFactorizations::Impl {
  Permutation ordering;
  std::vector<std::unique_ptr<NelsonSystem>> systems;
  Eigen::Index rows = 0;
  int modes = 0;
};

namespace {

void checkBasis(const FeModel& model, const ModalBasis& basis) {
  if (basis.reliefModeCount != 0)
    throw std::invalid_argument(
        "design gradient: basis.reliefModeCount = " + std::to_string(basis.reliefModeCount) +
        " is outside the allowed range {0} (inertia-relief mode derivatives are not implemented)");
  if (basis.modesFree.rows() != model.freeDofCount() || basis.modesFull.rows() != model.dofCount() ||
      basis.modesFree.cols() != basis.eigenmodeCount || basis.eigenvalues.size() != basis.eigenmodeCount)
    throw std::invalid_argument(
        "design gradient: the modal basis does not belong to this FeModel (sizes differ)");
}

// Free-DOF vector -(K' - lambda M') phi for design element e (K' = dE Ke0, M' = drho Me0) plus
// lambda' M phi; K' and M' are restricted to the free DOFs by dropping constrained rows.
Vector nelsonRightHandSide(const FeModel& model, const std::array<int, 8>& dofs,
                           const ElementVector& modeLocal, double stiffnessSlope, double densitySlope,
                           double eigenvalue, double eigenvalueDerivative, const Vector& massTimesMode) {
  Vector rhs = eigenvalueDerivative * massTimesMode;
  const ElementVector local =
      (stiffnessSlope * model.unitStiffness() - eigenvalue * densitySlope * model.unitMass()) * modeLocal;
  for (int a = 0; a < 8; ++a) {
    const int free = model.fullToFree()[dofs[a]];
    if (free >= 0) rhs(free) -= local(a);
  }
  return rhs;
}

}  // namespace

NelsonFactorizations::NelsonFactorizations(const FeModel& model, const ModalBasis& basis)
    : impl_(std::make_unique<Impl>()) {
  checkBasis(model, basis);
  const int n = basis.eigenmodeCount;
  impl_->ordering = nelsonOrdering(model);
  const PermutedOperators operators = permutedOperators(model, impl_->ordering);
  impl_->systems.resize(static_cast<std::size_t>(n));
  impl_->rows = model.freeDofCount();
  impl_->modes = n;
  // Each mode's factorisation on its own (its own slot): bitwise the same for any thread count.
  parallelFor(n, [&](int i) {
    impl_->systems[static_cast<std::size_t>(i)] = std::make_unique<NelsonSystem>(
        model, basis.eigenvalues(i), Vector(basis.modesFree.col(i)), impl_->ordering, operators);
  });
}

NelsonFactorizations::~NelsonFactorizations() = default;

DesignGradientResult computeDesignGradient(const FeModel& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras) {
  checkBasis(model, basis);
  const NelsonFactorizations factorizations(model, basis);
  return computeDesignGradient(model, basis, invariantGradient, options, extras, factorizations);
}

DesignGradientResult computeDesignGradient(const FeModel& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras,
                                           const NelsonFactorizations& factorizations) {
  const Stopwatch timer;
  checkBasis(model, basis);
  if (factorizations.impl().rows != model.freeDofCount() ||
      factorizations.impl().modes != basis.eigenmodeCount)
    throw std::invalid_argument(
        "computeDesignGradient: the Nelson factorisations belong to another model or basis");
  const int n = basis.eigenmodeCount;
  const InvariantLayout layout(n);
  if (invariantGradient.size() != layout.size) {
    std::ostringstream message;
    message << "computeDesignGradient: invariantGradient has " << invariantGradient.size()
            << " entries, expected " << layout.size << " (InertiaInvariants::packedSize(" << n << "))";
    throw std::invalid_argument(message.str());
  }
  if (extras.eigenvalueGradient.size() != 0 && extras.eigenvalueGradient.size() != n)
    throw std::invalid_argument("computeDesignGradient: extras.eigenvalueGradient has " +
                                std::to_string(extras.eigenvalueGradient.size()) +
                                " entries, expected 0 or " + std::to_string(n));
  if (extras.explicitDesignGradient.size() != 0 &&
      extras.explicitDesignGradient.size() != model.designCount())
    throw std::invalid_argument("computeDesignGradient: extras.explicitDesignGradient has " +
                                std::to_string(extras.explicitDesignGradient.size()) +
                                " entries, expected 0 or " + std::to_string(model.designCount()));
  const InertiaInvariants weights = InertiaInvariants::unpack(invariantGradient, n);
  const Vector eigenvalueWeights =
      extras.eigenvalueGradient.size() == n ? extras.eigenvalueGradient : Vector(Vector::Zero(n));

  const SparseMatrix& massFull = model.massFull();
  const SparseMatrix& stiffnessFull = model.stiffnessFull();
  const Matrix& modes = basis.modesFull;
  const Vector& coordinates = model.referenceCoordinates();
  const Vector rotatedCoordinates = rotateNodewise(coordinates);
  const Matrix rotatedModesTransposed = rotateNodewiseTransposedColumns(modes);

  // Explicit part: psi_explicit = sum_ab Gm_ab L_a^T M R_b + sum_ij Gk_ij phi_i^T K phi_j with
  // L = [e_x, e_y, X, S X, Phi], R = [e_x, e_y, X, Phi, S^T Phi].
  Matrix left(model.dofCount(), 4 + n), right(model.dofCount(), 3 + 2 * n);
  left << model.unitTranslationX(), model.unitTranslationY(), coordinates, rotatedCoordinates, modes;
  right << model.unitTranslationX(), model.unitTranslationY(), coordinates, modes, rotatedModesTransposed;
  Matrix massWeights = Matrix::Zero(4 + n, 3 + 2 * n);
  massWeights(0, 0) += weights.mass;
  massWeights(0, 2) += weights.massTimesCenter(0);
  massWeights(1, 2) += weights.massTimesCenter(1);
  massWeights(2, 2) += weights.polarMoment;
  massWeights.block(0, 3, 2, n) += weights.c1;
  massWeights.block(4, 2, n, 1) += weights.c2;
  massWeights.block(3, 3, 1, n) += weights.a0.transpose();
  massWeights.block(4, 3 + n, n, n) += weights.cTilde;
  massWeights.block(4, 3, n, n) += weights.mee;
  const Matrix& stiffnessWeights = weights.kee;

  DesignGradientResult result;
  result.gradient = Vector::Zero(model.designCount());
  // Every design variable's explicit part on its own: fixed blocks of variables in parallel threads.
  const int designs = model.designCount();
  parallelFor((designs + 255) / 256, [&](int block) {
    for (int d = block * 256; d < std::min(designs, (block + 1) * 256); ++d) {
      const int element = model.designToElement(d);
      const double x = model.design()(d);
      const std::array<int, 8> dofs = model.elementDofs(element);
      const auto leftLocal = gatherRows(left, dofs);
      const auto rightLocal = gatherRows(right, dofs);
      const auto modesLocal = gatherRows(modes, dofs);
      const double massPart =
          massWeights.cwiseProduct(leftLocal.transpose() * model.unitMass() * rightLocal).sum();
      const double stiffnessPart =
          stiffnessWeights.cwiseProduct(modesLocal.transpose() * model.unitStiffness() * modesLocal).sum();
      result.gradient(d) =
          model.simp().densityDerivative(x) * massPart + model.simp().stiffnessDerivative(x) * stiffnessPart;
    }
  });

  // dpsi/dphi_i as full-DOF columns, then restricted to the free DOFs.
  const Matrix massModes = massFull * modes;
  Matrix modeGradientFull = massFull * model.unitTranslationX() * weights.c1.row(0) +
                            massFull * model.unitTranslationY() * weights.c1.row(1) +
                            (massFull * coordinates) * weights.c2.transpose() +
                            (massFull * rotatedCoordinates) * weights.a0.transpose() +
                            (massFull * rotatedModesTransposed) * weights.cTilde.transpose() +
                            rotateNodewiseColumns(massModes) * weights.cTilde +
                            massModes * (weights.mee + weights.mee.transpose()) +
                            (stiffnessFull * modes) * (weights.kee + weights.kee.transpose());
  modeGradientFull.row(model.jointBAxialDof()) += weights.b.transpose();
  const Matrix modeGradient = model.restrictColumnsToFree(modeGradientFull);

  // The chain of every mode is independent (its own factorisation and solves): the modes run in
  // parallel (problems/rod/parallel.h), each writing its own contribution column, which are then
  // added in mode order, exactly the order of the serial loop -- bitwise equal for any thread count.
  const SparseMatrix& mass = model.mass();
  Matrix contributions(model.designCount(), n);
  std::vector<int> solves(static_cast<std::size_t>(n), 0);
  parallelFor(n, [&](int i) {
    auto contribution = contributions.col(i);
    int& linearSolves = solves[static_cast<std::size_t>(i)];
    const double eigenvalue = basis.eigenvalues(i);
    const Vector& modeFree = basis.modesFree.col(i);
    const Vector gradientOfMode = modeGradient.col(i);
    const Vector massTimesMode = mass * modeFree;
    const double projection = gradientOfMode.dot(modeFree);
    const NelsonSystem& system = *factorizations.impl().systems[static_cast<std::size_t>(i)];
    const Vector modeFull = modes.col(i);

    if (options.method == EigenvectorSensitivityMethod::AdjointNelson) {
      const Vector adjoint = system.solve(gradientOfMode - projection * massTimesMode);
      ++linearSolves;
      const Vector adjointFull = model.extendToFull(adjoint);
      const double adjointMassMode = adjoint.dot(massTimesMode);
      for (int d = 0; d < model.designCount(); ++d) {
        const double x = model.design()(d);
        const double stiffnessSlope = model.simp().stiffnessDerivative(x);
        const double densitySlope = model.simp().densityDerivative(x);
        const std::array<int, 8> dofs = model.elementDofs(model.designToElement(d));
        const ElementVector phi = gather(modeFull, dofs);
        const ElementVector z = gather(adjointFull, dofs);
        const ElementVector stiffnessPhi = model.unitStiffness() * phi;
        const ElementVector massPhi = model.unitMass() * phi;
        const double phiMassPhi = phi.dot(massPhi);
        const double eigenvalueDerivative =
            stiffnessSlope * phi.dot(stiffnessPhi) - eigenvalue * densitySlope * phiMassPhi;
        contribution(d) =
            -(stiffnessSlope * z.dot(stiffnessPhi) - eigenvalue * densitySlope * z.dot(massPhi)) +
            eigenvalueDerivative * (adjointMassMode + eigenvalueWeights(i)) -
            0.5 * projection * densitySlope * phiMassPhi;
      }
    } else {
      for (int d = 0; d < model.designCount(); ++d) {
        const double x = model.design()(d);
        const double stiffnessSlope = model.simp().stiffnessDerivative(x);
        const double densitySlope = model.simp().densityDerivative(x);
        const std::array<int, 8> dofs = model.elementDofs(model.designToElement(d));
        const ElementVector phi = gather(modeFull, dofs);
        const double phiMassPhi = phi.dot(model.unitMass() * phi);
        const double eigenvalueDerivative =
            stiffnessSlope * phi.dot(model.unitStiffness() * phi) - eigenvalue * densitySlope * phiMassPhi;
        const Vector v = system.solve(nelsonRightHandSide(model, dofs, phi, stiffnessSlope, densitySlope,
                                                          eigenvalue, eigenvalueDerivative, massTimesMode));
        ++linearSolves;
        const double c = -0.5 * densitySlope * phiMassPhi - massTimesMode.dot(v);
        contribution(d) =
            gradientOfMode.dot(v) + c * projection + eigenvalueWeights(i) * eigenvalueDerivative;
      }
    }
  });
  for (int i = 0; i < n; ++i) {
    ++result.factorizations;
    result.linearSolves += solves[static_cast<std::size_t>(i)];
    for (int d = 0; d < model.designCount(); ++d) result.gradient(d) += contributions(d, i);
  }
  if (extras.explicitDesignGradient.size() != 0) result.gradient += extras.explicitDesignGradient;
  result.seconds = timer.seconds();
  return result;
}

EigenpairDerivative computeEigenpairDerivative(const FeModel& model, const ModalBasis& basis, int mode,
                                               int designIndex) {
  checkBasis(model, basis);
  if (mode < 0 || mode >= basis.eigenmodeCount)
    throw std::invalid_argument("computeEigenpairDerivative: mode = " + std::to_string(mode) +
                                " is outside the allowed range [0, " +
                                std::to_string(basis.eigenmodeCount - 1) + "]");
  if (designIndex < 0 || designIndex >= model.designCount())
    throw std::invalid_argument("computeEigenpairDerivative: designIndex = " + std::to_string(designIndex) +
                                " is outside the allowed range [0, " +
                                std::to_string(model.designCount() - 1) + "]");
  const double eigenvalue = basis.eigenvalues(mode);
  const Vector modeFree = basis.modesFree.col(mode);
  const Vector massTimesMode = model.mass() * modeFree;
  const Permutation ordering = nelsonOrdering(model);
  const NelsonSystem system(model, eigenvalue, modeFree, ordering, permutedOperators(model, ordering));
  const double x = model.design()(designIndex);
  const double stiffnessSlope = model.simp().stiffnessDerivative(x);
  const double densitySlope = model.simp().densityDerivative(x);
  const std::array<int, 8> dofs = model.elementDofs(model.designToElement(designIndex));
  const ElementVector phi = gather(Vector(basis.modesFull.col(mode)), dofs);
  const double phiMassPhi = phi.dot(model.unitMass() * phi);
  EigenpairDerivative derivative;
  derivative.eigenvalue =
      stiffnessSlope * phi.dot(model.unitStiffness() * phi) - eigenvalue * densitySlope * phiMassPhi;
  const Vector v = system.solve(nelsonRightHandSide(model, dofs, phi, stiffnessSlope, densitySlope,
                                                    eigenvalue, derivative.eigenvalue, massTimesMode));
  const double c = -0.5 * densitySlope * phiMassPhi - massTimesMode.dot(v);
  derivative.modeFree = v + c * modeFree;
  return derivative;
}

}  // namespace rod
}  // namespace hindsight
