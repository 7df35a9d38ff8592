#include <hindsight/problems/rod/modal_reduction.h>

#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymGEigsShiftSolver.h>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
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

// Knuth's two-sum: s + error == a + b exactly.
inline void twoSum(double a, double b, double& s, double& error) {
  s = a + b;
  const double bVirtual = s - a;
  error = (a - (s - bVirtual)) + (b - bVirtual);
}

// Spectra's shift-invert operator y = (K - sigma M)^-1 x at the only shift used, sigma = 0, with the
// shared factorisation of K (the interface of Spectra::SymShiftInvert).
class StiffnessInverse {
 public:
  using Scalar = double;
  explicit StiffnessInverse(const StiffnessFactorization& k) : k_(k) {}
  Eigen::Index rows() const { return k_.size(); }
  Eigen::Index cols() const { return k_.size(); }
  void set_shift(const Scalar& sigma) {
    if (sigma != 0.0) throw std::logic_error("StiffnessInverse: only the shift 0 is factorised");
  }
  void perform_op(const Scalar* in, Scalar* out) const {
    Eigen::Map<Vector>(out, k_.size()).noalias() = k_.solver().solve(Eigen::Map<const Vector>(in, k_.size()));
  }

 private:
  const StiffnessFactorization& k_;
};

}  // namespace

StiffnessFactorization::StiffnessFactorization(const SparseMatrix& stiffness)
    : solver_(stiffness), size_(stiffness.rows()) {
  // LDL^T succeeds for indefinite matrices too: positive definiteness is a positive D.
  if (solver_.info() != Eigen::Success || !(solver_.vectorD().minCoeff() > 0.0))
    throw std::runtime_error("the constrained stiffness matrix is not positive definite");
}

Matrix compensatedResidual(ConstMatrixRef b, const SparseMatrix& a, ConstMatrixRef x) {
  if (a.rows() != b.rows() || a.cols() != x.rows() || b.cols() != x.cols())
    throw std::invalid_argument("compensatedResidual: shapes of B, A and X do not match");
  // Transposed, so that one matrix entry A_ik updates all columns of a row at once, in SIMD lanes: the
  // same operations per column as one column at a time (each column's sums keep their order), with
  // the product's rounding error from Dekker's exact split instead of fma (the same exact value; see
  // elementwiseStiffnessForm). A zero x_k contributes nothing exactly, as when it was skipped.
  constexpr double kSplitter = 134217729.0;  // 2^27 + 1
  const Eigen::Index columns = x.cols();
  Eigen::ArrayXXd high = b.transpose().array();
  Eigen::ArrayXXd low = Eigen::ArrayXXd::Zero(columns, b.rows());
  const Eigen::ArrayXXd xt = x.transpose().array();
  const Eigen::ArrayXXd split = kSplitter * xt;
  const Eigen::ArrayXXd xHigh = split - (split - xt);
  const Eigen::ArrayXXd xLow = xt - xHigh;
  Eigen::ArrayXd product(columns), productError(columns), sum(columns), virtualB(columns);
  for (Eigen::Index k = 0; k < a.outerSize(); ++k) {
    if ((xt.col(k) == 0.0).all()) continue;
    for (SparseMatrix::InnerIterator it(a, k); it; ++it) {
      // -(A_ik x_k) = product + productError exactly, then added to (high, low) exactly.
      const double v = -it.value();
      const double vSplit = kSplitter * v;
      const double vh = vSplit - (vSplit - v), vl = v - vh;
      product = v * xt.col(k);
      productError =
          ((vh * xHigh.col(k) - product) + vh * xLow.col(k) + vl * xHigh.col(k)) + vl * xLow.col(k);
      auto h = high.col(it.index());
      sum = h + product;
      virtualB = sum - h;
      low.col(it.index()) += ((h - (sum - virtualB)) + (product - virtualB)) + productError;
      h = sum;
    }
  }
  return (high + low).matrix().transpose();
}

Matrix elementwiseStiffnessForm(const FeModel& model, ConstMatrixRef xFull) {
  if (xFull.rows() != model.dofCount())
    throw std::invalid_argument("elementwiseStiffnessForm: X has " + std::to_string(xFull.rows()) +
                                " rows, expected dofCount() = " + std::to_string(model.dofCount()));
  const ElementMatrix& unit = model.unitStiffness();
  const Eigen::Index columns = xFull.cols();
  // Ke0 X_e nearly cancels for the rigid-body part of X_e: it is accumulated in double-double, with the
  // rounding error of each product a * x from Dekker's exact split (Veltkamp) instead of fma: the same
  // exact error, so the same bits, but the columns go through SIMD lanes together where fma would be a
  // library call per term (no FMA instructions are compiled in, docs/guides/reproducibility.md). Exact
  // for |a|, |x| < 2^996 and products above the subnormal range.
  using Row = Eigen::Array<double, 1, Eigen::Dynamic>;
  constexpr double kSplitter = 134217729.0;  // 2^27 + 1
  ElementMatrix unitHigh, unitLow;
  for (int a = 0; a < 8; ++a) {
    for (int b = 0; b < 8; ++b) {
      const double c = kSplitter * unit(a, b);
      unitHigh(a, b) = c - (c - unit(a, b));
      unitLow(a, b) = unit(a, b) - unitHigh(a, b);
    }
  }
  Matrix form = Matrix::Zero(columns, columns);
  // local and product as in the plain form, so that local^T product is the same matrix product.
  Matrix local(8, columns), product(8, columns);
  Eigen::ArrayXXd split(8, columns), localHigh(8, columns), localLow(8, columns);
  Row high(columns), low(columns), term(columns), termError(columns), sum(columns), virtualB(columns);
  for (int e = 0; e < model.elementCount(); ++e) {
    const std::array<int, 8> dofs = model.elementDofs(e);
    for (int a = 0; a < 8; ++a) local.row(a) = xFull.row(dofs[a]);
    split = kSplitter * local.array();
    localHigh = split - (split - local.array());
    localLow = local.array() - localHigh;
    for (int a = 0; a < 8; ++a) {
      high.setZero();
      low.setZero();
      for (int b = 0; b < 8; ++b) {
        const double u = unit(a, b), uh = unitHigh(a, b), ul = unitLow(a, b);
        term = u * local.row(b).array();
        // u x - term exactly (Dekker's TwoProduct).
        termError = ((uh * localHigh.row(b) - term) + uh * localLow.row(b) + ul * localHigh.row(b)) +
                    ul * localLow.row(b);
        // Knuth's TwoSum of (high, term).
        sum = high + term;
        virtualB = sum - high;
        low += ((high - (sum - virtualB)) + (term - virtualB)) + termError;
        high = sum;
      }
      product.row(a) = (high + low).matrix();
    }
    form.noalias() += model.simp().stiffness(model.elementDesignValue(e)) * (local.transpose() * product);
  }
  return 0.5 * (form + form.transpose());
}

ModalBasis computeModalBasis(const FeModel& model, const ModalReductionOptions& options) {
  const StiffnessFactorization stiffnessFactorization(model.stiffness());
  return computeModalBasis(model, options, stiffnessFactorization);
}

ModalBasis computeModalBasis(const FeModel& model, const ModalReductionOptions& options,
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
  using MassProduct = Spectra::SparseSymMatProd<double>;
  StiffnessInverse shiftInvert(factorization);
  MassProduct massProduct(mass);
  Spectra::SymGEigsShiftSolver<StiffnessInverse, MassProduct, Spectra::GEigsMode::ShiftInvert> solver(
      shiftInvert, massProduct, requested, subspace, 0.0);
  solver.init();
  const Eigen::Index converged =
      solver.compute(Spectra::SortRule::LargestMagn, options.maxIterations, options.tolerance);
  if (solver.info() != Spectra::CompInfo::Successful || converged < requested) {
    std::ostringstream message;
    message << "computeModalBasis: Spectra shift-invert solver converged " << converged << " of " << requested
            << " eigenpairs (info " << static_cast<int>(solver.info()) << ")";
    throw std::runtime_error(message.str());
  }
  Vector values = solver.eigenvalues();
  Matrix vectors = solver.eigenvectors();
  if (options.refinementSteps > 0) {
    // Block inverse iteration with K followed by Rayleigh-Ritz on span(K^-1 M V). The factorization's
    // backward error (~eps |K|) would leave eigenvalues off by ~eps lambda_max in absolute terms, an
    // error that changes erratically with the design; one sweep of iterative refinement with a
    // compensated residual makes S accurate to working precision, and S^T K S summed over elements keeps it.
    for (int step = 0; step < options.refinementSteps; ++step) {
      const Matrix load = mass * vectors;
      Matrix subspace = factorization.solve(load);
      subspace += factorization.solve(compensatedResidual(load, stiffness, subspace));
      // Columns of K^-1 M V scale like 1/lambda_i (1e-4 ... 1e-7 here): unscaled, S^T M S has condition
      // (lambda_{n+1} / lambda_1)^2 and the dense Ritz solve would lose that factor in accuracy.
      for (Eigen::Index j = 0; j < subspace.cols(); ++j)
        subspace.col(j) /= std::sqrt(subspace.col(j).dot(mass * subspace.col(j)));
      const Matrix projectedStiffness = elementwiseStiffnessForm(model, model.extendColumnsToFull(subspace));
      const Matrix projectedMass = subspace.transpose() * (mass * subspace);
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
        elementwiseStiffnessForm(model, model.extendColumnsToFull(basis.modesFree.leftCols(n)));
    basis.eigenvalues.head(n) = rayleigh.diagonal();
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
                             massFull * rotateNodewise(model.referenceCoordinates())};
    for (int r = 0; r < 3; ++r) {
      Vector mode = factorization.solver().solve(model.restrictToFree(loads[r]));
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
      basis.eigenvalues(n + r) = elementwiseStiffnessForm(model, model.extendToFull(mode))(0, 0);
    }
  }
  basis.modesFull = model.extendColumnsToFull(basis.modesFree);
  return basis;
}

}  // namespace rod
}  // namespace hindsight
