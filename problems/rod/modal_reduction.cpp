#include <hindsight/problems/rod/modal_reduction.h>

#include <hindsight/problems/rod/compensated_kernels.h>
#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/solid_member.h>
#include <hindsight/problems/rod/sparse_products.h>

#include <Spectra/SymEigsSolver.h>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace rod {

ModalReductionOptions ModalReductionOptions::fromConfig(const RodConfig& config) {
  ModalReductionOptions options;
  options.modeCount = config.modeCount;
  options.inertiaReliefModes = config.inertiaReliefModes;
  return options;
}

double ModalBasis::frequencyHz(int mode) const { return std::sqrt(eigenvalues(mode)) / (2.0 * M_PI); }

namespace {

// Sign rule documented in the header: the first entry with |v_k| >= 0.1 max |v| is made positive.
void applySignConvention(Eigen::Ref<Eigen::VectorXd> mode) {
  const double largest = mode.cwiseAbs().maxCoeff();
  for (Eigen::Index k = 0; k < mode.size(); ++k) {
    if (std::abs(mode(k)) >= 0.1 * largest) {
      if (mode(k) < 0.0) mode = -mode;
      return;
    }
  }
}

// Every entry zero or of magnitude in [2^-480, 2^480]: products of two such numbers then lie in
// [2^-960, 2^960], where Dekker's product error is exact (exponent sum >= emin + p - 1 = -970, no
// overflow; compensated_kernels.h).
template <typename Derived>
bool inDekkerRange(const Eigen::DenseBase<Derived>& values) {
  constexpr double kSmallest = 0x1p-480, kLargest = 0x1p480;
  const auto magnitude = values.derived().array().abs();
  return ((magnitude >= kSmallest && magnitude <= kLargest) || magnitude == 0.0).all();
}

// The generalized problem K phi = lambda M phi as a standard symmetric one, C y = (1 / lambda) y with
// C = D^{-1/2} L^{-1} P M P^T L^{-T} D^{-1/2}, from the shared factorisation P K P^T = L D L^T, and
// phi = P^T L^{-T} D^{-1/2} y. Lanczos on C needs one product with M and two triangular solves per
// step and plain Euclidean inner products, where the M-inner products of the generalized shift-invert
// form cost about two more products with M per step (measured: 204 M of the 347 M instructions of
// Spectra's generalized solver at 200 x 12 went to M).
class TransformedPencil {
 public:
  using Scalar = double;
  TransformedPencil(const StiffnessFactorization& k, const SparseMatrix& mass)
      : k_(k), mass_(mass), scale_(k.vectorD().cwiseSqrt().cwiseInverse()), work_(k.size()) {}
  Eigen::Index rows() const { return k_.size(); }
  Eigen::Index cols() const { return k_.size(); }
  void perform_op(const Scalar* in, Scalar* out) const {
    Eigen::Map<Vector> y(out, k_.size());
    // For the plate the back-substitution is Eigen's matrixU().solveInPlace() on the subtrees in parallel
    // and the forward sweep Eigen's matrixL().solveInPlace(), bit for bit (subtree_ldlt.h).
    work_ = scale_.cwiseProduct(Eigen::Map<const Vector>(in, k_.size()));
    k_.backwardSweep(work_.data(), 1, true);
    y.noalias() = mass_ * (k_.permutationPinv() * work_);
    work_ = k_.permutationP() * y;
    k_.forwardSweep(work_.data(), 1);
    y = scale_.cwiseProduct(work_);
  }
  /// phi = P^T L^{-T} D^{-1/2} y: one back-substitution sweep over the factor for all columns (bitwise
  /// the column-by-column solve).
  Matrix modes(const Matrix& y) const {
    StiffnessFactorization::RowBlock t = scale_.asDiagonal() * y, scratch;
    k_.backSubstituteInPlace(t, scratch);
    return t;
  }

 private:
  const StiffnessFactorization& k_;
  const SparseMatrix& mass_;
  Vector scale_;
  mutable Vector work_;
};

}  // namespace

StiffnessFactorization::StiffnessFactorization(const SparseMatrix& stiffness, FillOrdering ordering)
    : ordering_(ordering),
      simplicial_(SubtreeSchedule{}, ordering),
      size_(stiffness.rows()),
      outer_(stiffness.outerIndexPtr(), stiffness.outerIndexPtr() + stiffness.outerSize() + 1),
      inner_(stiffness.innerIndexPtr(), stiffness.innerIndexPtr() + stiffness.nonZeros()) {
  assert(stiffness.isCompressed());
  withFactor([&](auto& factor) { factor.compute(stiffness); });
  checkPositiveDefinite();
}

const SubtreeParallelLdlt& StiffnessFactorization::solver() const {
  if (ordering_ != FillOrdering::Amd)
    throw std::logic_error("StiffnessFactorization::solver: a METIS-ordered factor is supernodal()");
  return simplicial_;
}

const SupernodalLdlt& StiffnessFactorization::supernodal() const {
  if (ordering_ != FillOrdering::Metis)
    throw std::logic_error("StiffnessFactorization::supernodal: an AMD-ordered factor is solver()");
  return supernodal_;
}

const StiffnessFactorization::Permutation& StiffnessFactorization::permutationP() const {
  return withFactor([](const auto& factor) -> const Permutation& { return factor.permutationP(); });
}

const StiffnessFactorization::Permutation& StiffnessFactorization::permutationPinv() const {
  return withFactor([](const auto& factor) -> const Permutation& { return factor.permutationPinv(); });
}

Vector StiffnessFactorization::vectorD() const {
  return withFactor([](const auto& factor) -> Vector { return factor.vectorD(); });
}

void StiffnessFactorization::forwardSweep(double* x, Eigen::Index columns) const {
  withFactor([&](const auto& factor) { factor.forwardSweep(x, columns); });
}

void StiffnessFactorization::backwardSweep(double* x, Eigen::Index columns, bool parallel) const {
  withFactor([&](const auto& factor) { factor.backwardSweep(x, columns, parallel); });
}

double StiffnessFactorization::parallelShare() const {
  return withFactor([](const auto& factor) { return factor.parallelShare(); });
}

Matrix StiffnessFactorization::solve(ConstMatrixRef b) const {
  return withFactor([&](const auto& factor) -> Matrix { return factor.solve(b); });
}

void StiffnessFactorization::checkPositiveDefinite() const {
  // LDL^T succeeds for indefinite matrices too: positive definiteness is a positive D.
  const Eigen::ComputationInfo info = withFactor([](const auto& factor) { return factor.info(); });
  if (info != Eigen::Success || !(vectorD().minCoeff() > 0.0))
    throw std::runtime_error("the constrained stiffness matrix is not positive definite");
}

bool StiffnessFactorization::samePattern(const SparseMatrix& stiffness) const {
  return stiffness.isCompressed() && stiffness.rows() == size_ && stiffness.cols() == size_ &&
         static_cast<std::size_t>(stiffness.nonZeros()) == inner_.size() &&
         std::equal(outer_.begin(), outer_.end(), stiffness.outerIndexPtr()) &&
         std::equal(inner_.begin(), inner_.end(), stiffness.innerIndexPtr());
}

void StiffnessFactorization::refactorize(const SparseMatrix& stiffness) {
  if (!samePattern(stiffness))
    throw std::invalid_argument("refactorize: the stiffness matrix has another sparsity pattern");
  withFactor([&](auto& factor) { factor.factorize(stiffness); });
  checkPositiveDefinite();
}

std::unique_ptr<StiffnessFactorization> StiffnessFactorizationPool::take(const SparseMatrix& stiffness,
                                                                         FillOrdering ordering) {
  std::unique_ptr<StiffnessFactorization> kept;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!kept_.empty()) {
      kept = std::move(kept_.back());
      kept_.pop_back();
    }
  }
  if (kept && kept->ordering() == ordering && kept->samePattern(stiffness)) {
    kept->refactorize(stiffness);
    return kept;
  }
  return std::make_unique<StiffnessFactorization>(stiffness, ordering);
}

void StiffnessFactorizationPool::give(std::unique_ptr<StiffnessFactorization> factorization) {
  if (!factorization) return;
  const std::lock_guard<std::mutex> lock(mutex_);
  kept_.push_back(std::move(factorization));
}

std::size_t StiffnessFactorizationPool::size() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return kept_.size();
}

void StiffnessFactorization::prepareBlock(const char* method, const RowBlock& block,
                                          RowBlock& scratch) const {
  if (block.rows() != size_)
    throw std::invalid_argument(std::string("StiffnessFactorization::") + method + ": the block has " +
                                std::to_string(block.rows()) + " rows, expected " + std::to_string(size_));
  if (scratch.rows() != size_ || scratch.cols() != block.cols()) scratch.resize(size_, block.cols());
}

void StiffnessFactorization::solveInPlace(RowBlock& block, RowBlock& scratch) const {
  prepareBlock("solveInPlace", block, scratch);
  withFactor([&](const auto& factor) { detail::ldltSolveInPlace(factor, block, scratch); });
}

void StiffnessFactorization::backSubstituteInPlace(RowBlock& block, RowBlock& scratch) const {
  prepareBlock("backSubstituteInPlace", block, scratch);
  // L^-T on all columns (for the plate solver().matrixU().solveInPlace() column by column, bitwise), then
  // P^-1.
  backwardSweep(block.data(), block.cols(), true);
  scratch.noalias() = permutationPinv() * block;
  block.swap(scratch);
}

Matrix compensatedResidual(ConstMatrixRef b, const SparseMatrix& a, ConstMatrixRef x) {
  if (a.rows() != b.rows() || a.cols() != x.rows() || b.cols() != x.cols())
    throw std::invalid_argument("compensatedResidual: shapes of B, A and X do not match");
  // Row-major blocks, so that the kernel's innermost loop runs over the columns of X (contiguous).
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  SparseMatrix compressed;
  const SparseMatrix* stored = &a;
  if (!a.isCompressed()) {
    compressed = a;
    compressed.makeCompressed();
    stored = &compressed;
  }
  RowMajor high = b;
  RowMajor low = RowMajor::Zero(b.rows(), b.cols());
  const RowMajor xRows = x;
  const Eigen::Map<const Vector> values(stored->valuePtr(), stored->nonZeros());
  compensatedSparseUpdate(static_cast<int>(stored->outerSize()), stored->outerIndexPtr(),
                          stored->innerIndexPtr(), stored->valuePtr(), xRows.data(),
                          static_cast<int>(x.cols()), inDekkerRange(values) && inDekkerRange(x), high.data(),
                          low.data(), defaultKernelIsa());
  return Matrix(high + low);
}

namespace {

template <class Member>
Matrix elementwiseStiffnessFormOf(const Member& model, ConstMatrixRef xFull) {
  constexpr int kDofs = Member::kElementDofs;
  if (xFull.rows() != model.dofCount())
    throw std::invalid_argument("elementwiseStiffnessForm: X has " + std::to_string(xFull.rows()) +
                                " rows, expected dofCount() = " + std::to_string(model.dofCount()));
  const typename Member::ElementMatrixType& unit = model.unitStiffness();
  const Eigen::Index columns = xFull.cols();
  const bool dekker = inDekkerRange(unit) && inDekkerRange(xFull);
  const KernelIsa isa = defaultKernelIsa();
  // Each element's term E(x_e) X_e^T (Ke0 X_e) is its own arithmetic: the terms of a chunk of elements
  // are formed in fixed blocks in parallel (problems/rod/parallel.h), then added to the form in element
  // order, so the sum has the bits of the serial loop for any thread count. T = s (A^T B) and then
  // F += T round as F += s (A^T B) does (Eigen's product kernel scales the finished dot products by s
  // and adds them; a test holds the two equal bit for bit).
  constexpr int kChunk = 2048, kBlock = 256;
  const int elements = model.elementCount();
  Matrix form = Matrix::Zero(columns, columns);
  Matrix terms(columns * columns, std::min(kChunk, std::max(elements, 1)));
  for (int start = 0; start < elements; start += kChunk) {
    const int count = std::min(kChunk, elements - start);
    parallelFor((count + kBlock - 1) / kBlock, [&](int block) {
      Matrix local(kDofs, columns), product(kDofs, columns);
      Eigen::Matrix<double, kDofs, Eigen::Dynamic, Eigen::RowMajor> localRows(kDofs, columns);
      Vector high(columns), low(columns);
      for (int i = block * kBlock; i < std::min(count, (block + 1) * kBlock); ++i) {
        const int e = start + i;
        const std::array<int, kDofs> dofs = model.elementDofs(e);
        for (int a = 0; a < kDofs; ++a) local.row(a) = xFull.row(dofs[a]);
        // Ke0 X_e nearly cancels for the rigid-body part of X_e: accumulate in double-double
        // (compensated_kernels.h), on a row-major copy of X_e.
        localRows = local;
        compensatedElementProducts(unit.data(), kDofs, localRows.data(), static_cast<int>(columns), dekker,
                                   product.data(), high.data(), low.data(), isa);
        Eigen::Map<Matrix> term(terms.col(i).data(), columns, columns);
        term.noalias() = model.simp().stiffness(model.elementDesignValue(e)) * (local.transpose() * product);
      }
    });
    for (int i = 0; i < count; ++i) form += Eigen::Map<const Matrix>(terms.col(i).data(), columns, columns);
  }
  return 0.5 * (form + form.transpose());
}

template <class Member>
ModalBasis computeModalBasisOf(const Member& model, const ModalReductionOptions& options,
                               const StiffnessFactorization& factorization) {
  const int freeDofs = model.freeDofCount();
  const int n = options.modeCount;
  if (n < 1 || n + 1 >= freeDofs) {
    std::ostringstream message;
    message << "ModalReductionOptions.modeCount = " << n << " is outside the allowed range [1, "
            << freeDofs - 2 << "] (free DOFs minus 2)";
    throw std::invalid_argument(message.str());
  }
  if (!(options.gapWarningThreshold >= 1.0)) {
    std::ostringstream message;
    message << "ModalReductionOptions.gapWarningThreshold = " << options.gapWarningThreshold
            << " is outside the allowed range [1, inf)";
    throw std::invalid_argument(message.str());
  }
  if (!(options.tolerance > 0.0) || options.maxIterations < 1 || options.refinementSteps < 0) {
    std::ostringstream message;
    message << "ModalReductionOptions: tolerance = " << options.tolerance
            << " must be in (0, inf) and maxIterations = " << options.maxIterations
            << " in [1, inf), refinementSteps = " << options.refinementSteps << " in [0, inf)";
    throw std::invalid_argument(message.str());
  }

  const SparseMatrix& stiffness = model.stiffness();
  const SparseMatrix& mass = model.mass();
  const int requested = n + 1;
  const int subspace = std::min(freeDofs, std::max(2 * requested + 1, requested + 20));

  if (factorization.size() != stiffness.rows())
    throw std::invalid_argument(
        "computeModalBasis: the stiffness factorisation does not belong to this model");
  TransformedPencil pencil(factorization, mass);
  Spectra::SymEigsSolver<TransformedPencil> solver(pencil, requested, subspace);
  solver.init();
  const Eigen::Index converged =
      solver.compute(Spectra::SortRule::LargestAlge, options.maxIterations, options.tolerance);
  if (solver.info() != Spectra::CompInfo::Successful || converged < requested) {
    std::ostringstream message;
    message << "computeModalBasis: Spectra's Lanczos solver converged " << converged << " of " << requested
            << " eigenpairs (info " << static_cast<int>(solver.info()) << ")";
    throw std::runtime_error(message.str());
  }
  Vector values = solver.eigenvalues().cwiseInverse();
  Matrix vectors = pencil.modes(solver.eigenvectors());
  if (options.refinementSteps > 0) {
    // Block inverse iteration with K followed by Rayleigh-Ritz on span(K^-1 M V). The factorization's
    // backward error (~eps |K|) would leave eigenvalues off by ~eps lambda_max in absolute terms, an
    // error that changes erratically with the design; one sweep of iterative refinement with a
    // compensated residual makes S accurate to working precision, and S^T K S summed over elements keeps it.
    for (int step = 0; step < options.refinementSteps; ++step) {
      const Matrix load = sparseTimesDense(mass, vectors);
      // Each column's solve and compensated residual is its own arithmetic, in the same order in any
      // block: two fixed halves of the columns, in parallel when threads are available
      // (problems/rod/parallel.h), give the bits of one block for any thread count.
      Matrix subspace(load.rows(), load.cols());
      const Eigen::Index half = (load.cols() + 1) / 2;
      parallelFor(2, [&](int part) {
        const Eigen::Index first = part == 0 ? 0 : half;
        const Eigen::Index count = part == 0 ? half : load.cols() - half;
        if (count == 0) return;
        StiffnessFactorization::RowBlock block = load.middleCols(first, count), scratch;
        factorization.solveInPlace(block, scratch);
        const Matrix solution = block;
        block = compensatedResidual(load.middleCols(first, count), stiffness, solution);
        factorization.solveInPlace(block, scratch);
        subspace.middleCols(first, count) = solution + block;
      });
      // Columns of K^-1 M V scale like 1/lambda_i (1e-4 ... 1e-7 here): unscaled, S^T M S has condition
      // (lambda_{n+1} / lambda_1)^2 and the dense Ritz solve would lose that factor in accuracy.
      for (Eigen::Index j = 0; j < subspace.cols(); ++j)
        subspace.col(j) /= std::sqrt(subspace.col(j).dot(mass * subspace.col(j)));
      const Matrix projectedStiffness =
          elementwiseStiffnessFormOf(model, model.extendColumnsToFull(subspace));
      const Matrix projectedMass = subspace.transpose() * sparseTimesDense(mass, subspace);
      const Eigen::GeneralizedSelfAdjointEigenSolver<Matrix> ritz(
          projectedStiffness, 0.5 * (projectedMass + projectedMass.transpose()));
      if (ritz.info() != Eigen::Success)
        throw std::runtime_error("computeModalBasis: Rayleigh-Ritz refinement failed");
      values = ritz.eigenvalues();
      vectors = subspace * ritz.eigenvectors();
    }
  }
  std::vector<int> order(values.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return values(a) < values(b); });

  ModalBasis basis;
  basis.eigenmodeCount = n;
  basis.reliefModeCount = options.inertiaReliefModes ? 3 : 0;
  basis.iterations = static_cast<int>(solver.num_iterations());
  basis.operations = static_cast<int>(solver.num_operations());
  basis.eigenvalues.resize(basis.columnCount());
  basis.modesFree.resize(freeDofs, basis.columnCount());
  for (int i = 0; i < n; ++i) {
    basis.eigenvalues(i) = values(order[i]);
    Vector mode = vectors.col(order[i]);
    mode /= std::sqrt(mode.dot(mass * mode));
    applySignConvention(mode);
    basis.modesFree.col(i) = mode;
  }
  if (options.refinementSteps > 0) {
    // The dense Ritz solve returns lambda_i with an absolute error ~eps lambda_{n+1} (5e-13 relative in
    // lambda_1 here); the Rayleigh quotients of the refined, M-normalised modes are accurate to ~eps
    // relative and equal the diagonal of Kee (invariants), so the Nelson chain sees the same numbers.
    const Matrix rayleigh =
        elementwiseStiffnessFormOf(model, model.extendColumnsToFull(basis.modesFree.leftCols(n)));
    basis.eigenvalues.head(n) = rayleigh.diagonal();
    if (!options.inertiaReliefModes) basis.stiffnessForm = rayleigh;
  }
  basis.firstDiscardedEigenvalue = values(order[n]);
  basis.gapRatio = basis.firstDiscardedEigenvalue / basis.eigenvalues(n - 1);
  if (basis.gapRatio < options.gapWarningThreshold) {
    std::ostringstream message;
    message << "modal truncation inside an eigenvalue cluster: lambda_" << n + 1 << " / lambda_" << n << " = "
            << basis.gapRatio << " < " << options.gapWarningThreshold
            << "; eigenvector sensitivities may be inaccurate";
    basis.warning = message.str();
  }

  if (options.inertiaReliefModes) {
    const SparseMatrix& massFull = model.massFull();
    const Vector loads[3] = {massFull * model.unitTranslationX(), massFull * model.unitTranslationY(),
                             massFull * rotateNodewise(model.referenceCoordinates(), Member::kComponents)};
    for (int r = 0; r < 3; ++r) {
      Vector mode = factorization.solve(model.restrictToFree(loads[r]));
      for (int pass = 0; pass < 2; ++pass) {
        for (int j = 0; j < n + r; ++j) {
          const Vector column = basis.modesFree.col(j);
          mode -= column.dot(mass * mode) * column;
        }
      }
      const double norm = std::sqrt(mode.dot(mass * mode));
      if (!(norm > 0.0) || !std::isfinite(norm))
        throw std::runtime_error("computeModalBasis: inertia-relief mode " + std::to_string(r) +
                                 " is linearly dependent on the eigenmodes");
      mode /= norm;
      applySignConvention(mode);
      basis.modesFree.col(n + r) = mode;
      basis.eigenvalues(n + r) = elementwiseStiffnessFormOf(model, model.extendToFull(mode))(0, 0);
    }
  }
  basis.modesFull = model.extendColumnsToFull(basis.modesFree);
  return basis;
}

}  // namespace

Matrix elementwiseStiffnessForm(const FeModel& model, ConstMatrixRef xFull) {
  return elementwiseStiffnessFormOf(model, xFull);
}
Matrix elementwiseStiffnessForm(const SolidMember& model, ConstMatrixRef xFull) {
  return elementwiseStiffnessFormOf(model, xFull);
}

ModalBasis computeModalBasis(const FeModel& model, const ModalReductionOptions& options) {
  const StiffnessFactorization stiffnessFactorization(model.stiffness(), stiffnessOrdering(model));
  return computeModalBasisOf(model, options, stiffnessFactorization);
}
ModalBasis computeModalBasis(const SolidMember& model, const ModalReductionOptions& options) {
  const StiffnessFactorization stiffnessFactorization(model.stiffness(), stiffnessOrdering(model));
  return computeModalBasisOf(model, options, stiffnessFactorization);
}
ModalBasis computeModalBasis(const FeModel& model, const ModalReductionOptions& options,
                             const StiffnessFactorization& factorization) {
  return computeModalBasisOf(model, options, factorization);
}
ModalBasis computeModalBasis(const SolidMember& model, const ModalReductionOptions& options,
                             const StiffnessFactorization& factorization) {
  return computeModalBasisOf(model, options, factorization);
}

}  // namespace rod
}  // namespace hindsight
