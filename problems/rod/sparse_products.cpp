#include <hindsight/problems/rod/sparse_products.h>

#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {
namespace {

// The widths the members' products have (modes plus rigid columns, at most a few dozen) get a loop of
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

template <class Op>
void dispatchWidth(const SparseMatrix& a, const double* x, double* y, Eigen::Index width, Op op) {
  switch (width) {
    case 1: return forEachEntry<1>(a, x, y, width, op);
    case 2: return forEachEntry<2>(a, x, y, width, op);
    case 3: return forEachEntry<3>(a, x, y, width, op);
    case 4: return forEachEntry<4>(a, x, y, width, op);
    case 5: return forEachEntry<5>(a, x, y, width, op);
    case 6: return forEachEntry<6>(a, x, y, width, op);
    case 7: return forEachEntry<7>(a, x, y, width, op);
    case 8: return forEachEntry<8>(a, x, y, width, op);
    case 9: return forEachEntry<9>(a, x, y, width, op);
    case 10: return forEachEntry<10>(a, x, y, width, op);
    case 11: return forEachEntry<11>(a, x, y, width, op);
    case 12: return forEachEntry<12>(a, x, y, width, op);
    case 13: return forEachEntry<13>(a, x, y, width, op);
    case 14: return forEachEntry<14>(a, x, y, width, op);
    case 16: return forEachEntry<16>(a, x, y, width, op);
    default: return forEachEntry<0>(a, x, y, width, op);
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
