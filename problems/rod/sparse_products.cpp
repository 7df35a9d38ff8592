#include <hindsight/problems/rod/sparse_products.h>

#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {
namespace {

// The widths the members' products have (modes plus rigid columns, up to kWidestFixed) get a loop of
// fixed length, which the compiler unrolls and vectorises lane by lane (SSE2, no FMA contraction: each
// y_rc is still one multiplication and one addition, rounded as Eigen's scalar loop rounds them).
template <int W, class Op>
void forEachEntry(const SparseMatrix& a, const double* x, double* y, Eigen::Index width, Op op) {
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  const double* values = a.valuePtr();
  const int* nonZeros = a.innerNonZeroPtr();
  const Eigen::Index w = W > 0 ? W : width;
  for (Eigen::Index j = 0; j < a.outerSize(); ++j) {
    const double* __restrict xj = x + j * w;
    const int end = nonZeros ? outer[j] + nonZeros[j] : outer[j + 1];
    for (int k = outer[j]; k < end; ++k) {
      double* __restrict yr = y + static_cast<Eigen::Index>(inner[k]) * w;
      const double v = values[k];
      for (Eigen::Index c = 0; c < w; ++c) yr[c] = op(yr[c], v, xj[c], c);
    }
  }
}

constexpr int kWidestFixed = 16;

// forEachEntry with the width fixed at compile time for 1 ... kWidestFixed columns, else at run time.
template <int W = 1, class Op>
void dispatchWidth(const SparseMatrix& a, const double* x, double* y, Eigen::Index width, Op op) {
  if constexpr (W > kWidestFixed) {
    forEachEntry<0>(a, x, y, width, op);
  } else {
    if (width == W)
      forEachEntry<W>(a, x, y, width, op);
    else
      dispatchWidth<W + 1>(a, x, y, width, op);
  }
}

}  // namespace

Matrix sparseTimesDense(const SparseMatrix& a, const Eigen::Ref<const Matrix>& x) {
  if (a.cols() != x.rows())
    throw std::invalid_argument("sparseTimesDense: A has " + std::to_string(a.cols()) + " columns, X " +
                                std::to_string(x.rows()) + " rows");
  const RowMajorBlock byRows = x;
  RowMajorBlock result = RowMajorBlock::Zero(a.rows(), x.cols());
  // Eigen: y_rc += a_rj * (alpha x_jc) with alpha = 1, which leaves x_jc as it is.
  dispatchWidth(a, byRows.data(), result.data(), x.cols(),
                [](double y, double v, double xj, Eigen::Index) { return y + v * xj; });
  return result;
}

void addScaledSparseProduct(const SparseMatrix& a, const RowMajorBlock& x, const Vector& scales,
                            RowMajorBlock& y) {
  if (a.cols() != x.rows() || a.rows() != y.rows() || x.cols() != y.cols() || scales.size() != x.cols())
    throw std::invalid_argument("addScaledSparseProduct: the sizes of A, X, Y and the scales do not agree");
  const double* s = scales.data();
  dispatchWidth(a, x.data(), y.data(), x.cols(),
                [s](double yr, double v, double xj, Eigen::Index c) { return yr + (s[c] * v) * xj; });
}

}  // namespace rod
}  // namespace hindsight
