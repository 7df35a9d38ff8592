#include <hindsight/problems/rod/design_gradient.h>

#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/rod/invariants.h>
#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/solid_member.h>
#include <hindsight/problems/rod/sparse_products.h>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace hindsight {
namespace rod {
namespace {

// Gathers the rows of the element DOFs of a full-DOF matrix.
template <std::size_t N>
Eigen::Matrix<double, static_cast<int>(N), Eigen::Dynamic> gatherRows(const Matrix& full,
                                                                      const std::array<int, N>& dofs) {
  Eigen::Matrix<double, static_cast<int>(N), Eigen::Dynamic> local(static_cast<int>(N), full.cols());
  for (int a = 0; a < static_cast<int>(N); ++a) local.row(a) = full.row(dofs[a]);
  return local;
}

template <std::size_t N>
Eigen::Matrix<double, static_cast<int>(N), 1> gather(const Vector& full, const std::array<int, N>& dofs) {
  Eigen::Matrix<double, static_cast<int>(N), 1> local;
  for (int a = 0; a < static_cast<int>(N); ++a) local(a) = full(dofs[a]);
  return local;
}

using Permutation = Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>;

// The fill-reducing ordering (AMD) of the pattern of K - lambda M, the same for every mode: computed
// once per design and shared by all Nelson systems, so each factorisation does only its numeric part
// (and the cheap elimination tree of the permuted pattern).
template <class Member>
Permutation nelsonOrdering(const Member& model) {
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

template <class Member>
PermutedOperators permutedOperators(const Member& model, const Permutation& ordering) {
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
  template <class Member>
  NelsonSystem(const Member& model, double eigenvalue, const Vector& modeFree, const Permutation& ordering,
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

// The adjoint Nelson systems of every mode, (K - lambda_i M) z_i = h_i with h_i = g_i - (g_i^T phi_i) M phi_i
// (singular but consistent: h_i is orthogonal to phi_i; any solution serves, the chain's formula is
// invariant under z_i + t phi_i), solved with the one factorisation of K instead of one factorisation
// of K - lambda_i M per mode. The kept modes Phi split the space M-orthogonally:
//   z_i = sum_{j != i} phi_j (phi_j^T h_i) / (lambda_j - lambda_i) + x_i,   Phi^T M x_i = 0,
// the first part exact from the eigenpairs, x_i from the deflated system Q^T (K - lambda_i M) Q x = Q^T h_i
// with Q = I - Phi Phi^T M. On range(Q) the operator's eigenvalues are lambda_j - lambda_i > 0 for the
// discarded modes j > n, so it is positive definite and conjugate gradients apply, preconditioned by
// Q K^-1 Q^T: the preconditioned spectrum is 1 - lambda_i / lambda_j in [1 - lambda_i / lambda_{n+1}, 1),
// condition at most lambda_{n+1} / (lambda_{n+1} - lambda_n) (5 for the rod's gap of 1.26; 4 to 18
// iterations per mode to 1e-14). This is the deflated (projected) conjugate gradient of Saad, Yeung,
// Erhel and Guyomarc'h ("A deflated version of the conjugate gradient algorithm", SIAM J. Sci. Comput.
// 21, 2000) with the exact eigenvectors of the pencil as the deflation space. All modes advance together
// so that each triangular sweep of K's factor serves every mode still iterating
// (StiffnessFactorization::solveInPlace): at 800 x 48 one sweep streams 60 MB, and ten factorisations of
// K - lambda_i M cost 4.6 s where the deflated solves cost about 1 s.
//
// A mode whose iteration does not reach the tolerance within the iteration limit (a gap lambda_{n+1} /
// lambda_n close to 1), or meets a direction of non-positive curvature (an operator that is not positive
// definite on range(Q)), is solved directly with Nelson's modified operator instead. Every column's
// arithmetic is its own, in a fixed order: the same bits for any thread count and any grouping.
struct DeflatedAdjoint {
  static constexpr double kTolerance = 1e-14;  // on ||r_k|| / ||r_0||, r = Q^T (h - (K - lambda M) x)
  Matrix solutions;
  std::vector<int> iterations;  // per mode; -1 when solved directly
};

template <class Member>
DeflatedAdjoint solveAdjointNelson(const Member& model, const ModalBasis& basis,
                                   const StiffnessFactorization& stiffnessFactorization,
                                   const Matrix& massModes, const Matrix& rightHandSides,
                                   int iterationLimit) {
  const int n = basis.eigenmodeCount;
  const Eigen::Index rows = model.freeDofCount();
  const SparseMatrix& stiffness = model.stiffness();
  const SparseMatrix& mass = model.mass();
  const Matrix& modes = basis.modesFree;
  DeflatedAdjoint out;
  out.solutions.resize(rows, n);
  out.iterations.assign(static_cast<std::size_t>(n), 0);

  // One interleaved group of modes per thread (the slow high modes shared out), each its own block
  // iteration: a sweep streams the whole factor whatever its column count, so one thread does best with
  // all modes in one block (every column's arithmetic is its own: the same bits for any grouping).
  const int groups = std::max(1, std::min(parallelConcurrency(), n));
  parallelFor(groups, [&](int group) {
    std::vector<int> members;
    for (int i = group; i < n; i += groups) members.push_back(i);
    const auto count = static_cast<Eigen::Index>(members.size());
    Matrix x = Matrix::Zero(rows, count), r(rows, count), z(rows, count), p(rows, count), w(rows, count);
    Vector rho(count), initialNorm(count);
    std::vector<char> active(static_cast<std::size_t>(count), 1), failed(static_cast<std::size_t>(count), 0);
    StiffnessFactorization::RowBlock block, scratch, operatorTimes;
    Vector ones, shifts;
    std::vector<Eigen::Index> columns;
    columns.reserve(static_cast<std::size_t>(count));
    Vector coefficients(n);
    auto activeColumns = [&]() {
      columns.clear();
      for (Eigen::Index c = 0; c < count; ++c)
        if (active[static_cast<std::size_t>(c)]) columns.push_back(c);
    };
    // z = Q K^-1 r for the active columns.
    auto precondition = [&]() {
      activeColumns();
      block.resize(rows, static_cast<Eigen::Index>(columns.size()));
      for (std::size_t k = 0; k < columns.size(); ++k)
        block.col(static_cast<Eigen::Index>(k)) = r.col(columns[k]);
      stiffnessFactorization.solveInPlace(block, scratch);
      for (std::size_t k = 0; k < columns.size(); ++k) {
        auto zc = z.col(columns[k]);
        zc = block.col(static_cast<Eigen::Index>(k));
        coefficients.noalias() = massModes.transpose() * zc;
        zc.noalias() -= modes * coefficients;
      }
    };
    for (Eigen::Index c = 0; c < count; ++c) {
      const int i = members[static_cast<std::size_t>(c)];
      r.col(c) = rightHandSides.col(i) - massModes * (modes.transpose() * rightHandSides.col(i));
      initialNorm(c) = r.col(c).norm();
      if (!(initialNorm(c) > 0.0)) active[static_cast<std::size_t>(c)] = 0;
    }
    precondition();
    for (Eigen::Index c = 0; c < count; ++c) {
      p.col(c) = z.col(c);
      rho(c) = r.col(c).dot(z.col(c));
    }
    for (int iteration = 1; iteration <= iterationLimit; ++iteration) {
      bool any = false;
      // w = K p - lambda_i M p for every active column in one pass over K and one over M (each column
      // bitwise Eigen's w = K p; w -= lambda_i (M p): addScaledSparseProduct).
      activeColumns();
      block.resize(rows, static_cast<Eigen::Index>(columns.size()));
      for (std::size_t k = 0; k < columns.size(); ++k)
        block.col(static_cast<Eigen::Index>(k)) = p.col(columns[k]);
      const auto width = static_cast<Eigen::Index>(columns.size());
      ones.setOnes(width);
      shifts.resize(width);
      for (Eigen::Index k = 0; k < width; ++k)
        shifts(k) =
            basis.eigenvalues(members[static_cast<std::size_t>(columns[static_cast<std::size_t>(k)])]);
      operatorTimes.setZero(rows, width);
      addScaledSparseProduct(stiffness, block, ones, operatorTimes);
      block = -block;
      addScaledSparseProduct(mass, block, shifts, operatorTimes);
      for (std::size_t k = 0; k < columns.size(); ++k) {
        const Eigen::Index c = columns[k];
        const int i = members[static_cast<std::size_t>(c)];
        auto pc = p.col(c);
        auto wc = w.col(c);
        wc = operatorTimes.col(static_cast<Eigen::Index>(k));
        const double curvature = pc.dot(wc);
        if (!(curvature > 0.0 && std::isfinite(curvature) && rho(c) > 0.0)) {
          // Not positive definite on range(Q) after all (the modes are not the lowest, or a gap of ~1):
          // stop at once and leave the mode to the direct solve below.
          active[static_cast<std::size_t>(c)] = 0;
          failed[static_cast<std::size_t>(c)] = 1;
          continue;
        }
        const double alpha = rho(c) / curvature;
        x.col(c) += alpha * pc;
        auto rc = r.col(c);
        rc -= alpha * wc;
        coefficients.noalias() = modes.transpose() * rc;
        rc.noalias() -= massModes * coefficients;  // back onto range(Q^T) against drift
        if (rc.norm() <= DeflatedAdjoint::kTolerance * initialNorm(c)) {
          active[static_cast<std::size_t>(c)] = 0;
          out.iterations[static_cast<std::size_t>(i)] = iteration;
        } else {
          any = true;
        }
      }
      if (!any) break;
      precondition();
      for (Eigen::Index c = 0; c < count; ++c) {
        if (!active[static_cast<std::size_t>(c)]) continue;
        const double next = r.col(c).dot(z.col(c));
        p.col(c) = z.col(c) + (next / rho(c)) * p.col(c);
        rho(c) = next;
      }
    }
    for (Eigen::Index c = 0; c < count; ++c) {
      const int i = members[static_cast<std::size_t>(c)];
      auto solution = out.solutions.col(i);
      if (active[static_cast<std::size_t>(c)] || failed[static_cast<std::size_t>(c)]) {
        out.iterations[static_cast<std::size_t>(i)] = -1;  // not converged: solved directly below
        continue;
      }
      solution = x.col(c);
      for (int j = 0; j < n; ++j) {
        if (j == i) continue;
        solution += modes.col(j) *
                    (modes.col(j).dot(rightHandSides.col(i)) / (basis.eigenvalues(j) - basis.eigenvalues(i)));
      }
    }
  });
  bool direct = false;
  for (int i = 0; i < n; ++i) direct = direct || out.iterations[static_cast<std::size_t>(i)] < 0;
  if (direct) {
    const Permutation ordering = nelsonOrdering(model);
    const PermutedOperators operators = permutedOperators(model, ordering);
    for (int i = 0; i < n; ++i) {
      if (out.iterations[static_cast<std::size_t>(i)] >= 0) continue;
      const NelsonSystem system(model, basis.eigenvalues(i), Vector(modes.col(i)), ordering, operators);
      out.solutions.col(i) = system.solve(rightHandSides.col(i));
    }
  }
  return out;
}

template <class Member>
void checkBasis(const Member& model, const ModalBasis& basis) {
  if (basis.reliefModeCount != 0)
    throw std::invalid_argument(
        "design gradient: basis.reliefModeCount = " + std::to_string(basis.reliefModeCount) +
        " is outside the allowed range {0} (inertia-relief mode derivatives are not implemented)");
  if (basis.modesFree.rows() != model.freeDofCount() || basis.modesFull.rows() != model.dofCount() ||
      basis.modesFree.cols() != basis.eigenmodeCount || basis.eigenvalues.size() != basis.eigenmodeCount)
    throw std::invalid_argument(
        "design gradient: the modal basis does not belong to this member model (sizes differ)");
}

// Free-DOF vector -(K' - lambda M') phi for design element e (K' = dE Ke0, M' = drho Me0) plus
// lambda' M phi; K' and M' are restricted to the free DOFs by dropping constrained rows.
template <class Member>
Vector nelsonRightHandSide(const Member& model, const std::array<int, Member::kElementDofs>& dofs,
                           const typename Member::ElementVectorType& modeLocal, double stiffnessSlope,
                           double densitySlope, double eigenvalue, double eigenvalueDerivative,
                           const Vector& massTimesMode) {
  Vector rhs = eigenvalueDerivative * massTimesMode;
  const typename Member::ElementVectorType local =
      (stiffnessSlope * model.unitStiffness() - eigenvalue * densitySlope * model.unitMass()) * modeLocal;
  for (int a = 0; a < Member::kElementDofs; ++a) {
    const int free = model.fullToFree()[dofs[a]];
    if (free >= 0) rhs(free) -= local(a);
  }
  return rhs;
}

template <class Member>
DesignGradientResult designGradientOf(const Member& model, const ModalBasis& basis,
                                      ConstVectorRef invariantGradient, const DesignGradientOptions& options,
                                      const DesignGradientExtras& extras,
                                      const StiffnessFactorization& stiffnessFactorization) {
  constexpr int kComponents = Member::kComponents, kDofs = Member::kElementDofs;
  using ElementVectorType = typename Member::ElementVectorType;
  const Stopwatch timer;
  checkBasis(model, basis);
  if (options.adjointIterationLimit < 0)
    throw std::invalid_argument("computeDesignGradient: options.adjointIterationLimit = " +
                                std::to_string(options.adjointIterationLimit) +
                                " is outside the allowed range [0, inf)");
  if (stiffnessFactorization.size() != model.freeDofCount())
    throw std::invalid_argument(
        "computeDesignGradient: the stiffness factorisation belongs to another model");
  const int n = basis.eigenmodeCount;
  const InvariantLayout layout(n, kComponents == 3);
  if (invariantGradient.size() != layout.size) {
    std::ostringstream message;
    message << "computeDesignGradient: invariantGradient has " << invariantGradient.size()
            << " entries, expected " << layout.size << " (InertiaInvariants::packedSize(" << n << ", "
            << (layout.spatial ? "true" : "false") << "))";
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
  const Vector rotatedCoordinates = rotateNodewise(coordinates, kComponents);
  const Matrix rotatedModesTransposed = rotateNodewiseTransposedColumns(modes, kComponents);
  // The solid's rotational modal mass MeeRot = Phi_xy^T M Phi_xy (invariants.h); empty for the plate.
  const Matrix planarModes = kComponents == 3 ? planarComponents(modes, kComponents) : Matrix();

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
      const std::array<int, kDofs> dofs = model.elementDofs(element);
      const auto leftLocal = gatherRows(left, dofs);
      const auto rightLocal = gatherRows(right, dofs);
      const auto modesLocal = gatherRows(modes, dofs);
      double massPart = massWeights.cwiseProduct(leftLocal.transpose() * model.unitMass() * rightLocal).sum();
      if constexpr (kComponents == 3) {
        const auto planarLocal = gatherRows(planarModes, dofs);
        massPart +=
            weights.meeRotation.cwiseProduct(planarLocal.transpose() * model.unitMass() * planarLocal).sum();
      }
      const double stiffnessPart =
          stiffnessWeights.cwiseProduct(modesLocal.transpose() * model.unitStiffness() * modesLocal).sum();
      result.gradient(d) =
          model.simp().densityDerivative(x) * massPart + model.simp().stiffnessDerivative(x) * stiffnessPart;
    }
  });

  // dpsi/dphi_i as full-DOF columns, then restricted to the free DOFs.
  const Matrix massModes = sparseTimesDense(massFull, modes);
  Matrix modeGradientFull = massFull * model.unitTranslationX() * weights.c1.row(0) +
                            massFull * model.unitTranslationY() * weights.c1.row(1) +
                            (massFull * coordinates) * weights.c2.transpose() +
                            (massFull * rotatedCoordinates) * weights.a0.transpose() +
                            sparseTimesDense(massFull, rotatedModesTransposed) * weights.cTilde.transpose() +
                            rotateNodewiseColumns(massModes, kComponents) * weights.cTilde +
                            massModes * (weights.mee + weights.mee.transpose()) +
                            sparseTimesDense(stiffnessFull, modes) * (weights.kee + weights.kee.transpose());
  if constexpr (kComponents == 2) {
    modeGradientFull.row(model.jointBAxialDof()) += weights.b.transpose();
  } else {
    const std::vector<int> axis = model.jointBAxialDofs();
    for (int dof : axis)
      modeGradientFull.row(dof) += weights.b.transpose() / static_cast<double>(axis.size());
    modeGradientFull +=
        sparseTimesDense(massFull, planarModes) * (weights.meeRotation + weights.meeRotation.transpose());
  }
  const Matrix modeGradient = model.restrictColumnsToFree(modeGradientFull);

  // The adjoint route solves every mode's system first (solveAdjointNelson, all modes in one block
  // iteration); then the chain of every mode is independent: the modes run in parallel
  // (problems/rod/parallel.h), each writing its own contribution column, which are then added in mode
  // order, exactly the order of the serial loop -- bitwise equal for any thread count.
  const bool adjointRoute = options.method == EigenvectorSensitivityMethod::AdjointNelson;
  DeflatedAdjoint adjoints;
  // M phi_i on the free DOFs, once for the right-hand sides, the deflation and the per-mode chain: the free
  // rows of M_full Phi_full, bitwise M Phi_free (Phi_full is zero at the constrained DOFs, whose terms add
  // +-0 to sums that start at +0, and removeDofs keeps the other terms in their order).
  const Matrix massModesFree = model.restrictColumnsToFree(massModes);
  if (adjointRoute) {
    Matrix rightHandSides(model.freeDofCount(), n);
    for (int i = 0; i < n; ++i) {
      rightHandSides.col(i) =
          modeGradient.col(i) - modeGradient.col(i).dot(basis.modesFree.col(i)) * massModesFree.col(i);
    }
    adjoints = solveAdjointNelson(model, basis, stiffnessFactorization, massModesFree, rightHandSides,
                                  options.adjointIterationLimit);
  }
  std::unique_ptr<Permutation> ordering;
  std::unique_ptr<PermutedOperators> operators;
  if (!adjointRoute) {
    ordering = std::make_unique<Permutation>(nelsonOrdering(model));
    operators = std::make_unique<PermutedOperators>(permutedOperators(model, *ordering));
  }
  Matrix contributions(model.designCount(), n);
  // The SIMP slopes per design variable, once for all modes (two calls of pow each).
  Vector stiffnessSlopes(model.designCount()), densitySlopes(model.designCount());
  for (int d = 0; d < model.designCount(); ++d) {
    stiffnessSlopes(d) = model.simp().stiffnessDerivative(model.design()(d));
    densitySlopes(d) = model.simp().densityDerivative(model.design()(d));
  }
  std::vector<int> solves(static_cast<std::size_t>(n), 0);
  parallelFor(n, [&](int i) {
    auto contribution = contributions.col(i);
    int& linearSolves = solves[static_cast<std::size_t>(i)];
    const double eigenvalue = basis.eigenvalues(i);
    const Vector& modeFree = basis.modesFree.col(i);
    const Vector gradientOfMode = modeGradient.col(i);
    const Vector massTimesMode = massModesFree.col(i);
    const double projection = gradientOfMode.dot(modeFree);
    const Vector modeFull = modes.col(i);

    if (adjointRoute) {
      const Vector adjoint = adjoints.solutions.col(i);
      linearSolves = adjoints.iterations[static_cast<std::size_t>(i)] < 0
                         ? 1
                         : adjoints.iterations[static_cast<std::size_t>(i)] + 1;
      const Vector adjointFull = model.extendToFull(adjoint);
      const double adjointMassMode = adjoint.dot(massTimesMode);
      for (int d = 0; d < model.designCount(); ++d) {
        const double stiffnessSlope = stiffnessSlopes(d);
        const double densitySlope = densitySlopes(d);
        const std::array<int, kDofs> dofs = model.elementDofs(model.designToElement(d));
        const ElementVectorType phi = gather(modeFull, dofs);
        const ElementVectorType z = gather(adjointFull, dofs);
        const ElementVectorType stiffnessPhi = model.unitStiffness() * phi;
        const ElementVectorType massPhi = model.unitMass() * phi;
        const double phiMassPhi = phi.dot(massPhi);
        const double eigenvalueDerivative =
            stiffnessSlope * phi.dot(stiffnessPhi) - eigenvalue * densitySlope * phiMassPhi;
        contribution(d) =
            -(stiffnessSlope * z.dot(stiffnessPhi) - eigenvalue * densitySlope * z.dot(massPhi)) +
            eigenvalueDerivative * (adjointMassMode + eigenvalueWeights(i)) -
            0.5 * projection * densitySlope * phiMassPhi;
      }
    } else {
      const NelsonSystem system(model, eigenvalue, modeFree, *ordering, *operators);
      for (int d = 0; d < model.designCount(); ++d) {
        const double stiffnessSlope = stiffnessSlopes(d);
        const double densitySlope = densitySlopes(d);
        const std::array<int, kDofs> dofs = model.elementDofs(model.designToElement(d));
        const ElementVectorType phi = gather(modeFull, dofs);
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
    if (!adjointRoute || adjoints.iterations[static_cast<std::size_t>(i)] < 0) ++result.factorizations;
    result.linearSolves += solves[static_cast<std::size_t>(i)];
    for (int d = 0; d < model.designCount(); ++d) result.gradient(d) += contributions(d, i);
  }
  if (extras.explicitDesignGradient.size() != 0) result.gradient += extras.explicitDesignGradient;
  result.seconds = timer.seconds();
  return result;
}

template <class Member>
EigenpairDerivative eigenpairDerivativeOf(const Member& model, const ModalBasis& basis, int mode,
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
  const std::array<int, Member::kElementDofs> dofs = model.elementDofs(model.designToElement(designIndex));
  const typename Member::ElementVectorType phi = gather(Vector(basis.modesFull.col(mode)), dofs);
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

template <class Member>
DesignGradientResult designGradientOf(const Member& model, const ModalBasis& basis,
                                      ConstVectorRef invariantGradient, const DesignGradientOptions& options,
                                      const DesignGradientExtras& extras) {
  checkBasis(model, basis);
  const StiffnessFactorization stiffnessFactorization(model.stiffness(), stiffnessOrdering(model));
  return designGradientOf(model, basis, invariantGradient, options, extras, stiffnessFactorization);
}

}  // namespace

DesignGradientResult computeDesignGradient(const FeModel& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras) {
  return designGradientOf(model, basis, invariantGradient, options, extras);
}
DesignGradientResult computeDesignGradient(const SolidMember& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras) {
  return designGradientOf(model, basis, invariantGradient, options, extras);
}
DesignGradientResult computeDesignGradient(const FeModel& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras,
                                           const StiffnessFactorization& stiffnessFactorization) {
  return designGradientOf(model, basis, invariantGradient, options, extras, stiffnessFactorization);
}
DesignGradientResult computeDesignGradient(const SolidMember& model, const ModalBasis& basis,
                                           ConstVectorRef invariantGradient,
                                           const DesignGradientOptions& options,
                                           const DesignGradientExtras& extras,
                                           const StiffnessFactorization& stiffnessFactorization) {
  return designGradientOf(model, basis, invariantGradient, options, extras, stiffnessFactorization);
}
EigenpairDerivative computeEigenpairDerivative(const FeModel& model, const ModalBasis& basis, int mode,
                                               int designIndex) {
  return eigenpairDerivativeOf(model, basis, mode, designIndex);
}
EigenpairDerivative computeEigenpairDerivative(const SolidMember& model, const ModalBasis& basis, int mode,
                                               int designIndex) {
  return eigenpairDerivativeOf(model, basis, mode, designIndex);
}

}  // namespace rod
}  // namespace hindsight
