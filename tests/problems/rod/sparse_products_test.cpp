// The one-pass sparse products (problems/rod/sparse_products.h) against Eigen's own, bit for bit: every
// width the dispatch names and one past them, a compressed and an uncompressed matrix with explicit
// zeros, values spread over many binades so that a reordered sum or a fused multiply-add would show.
#include <hindsight/problems/rod/sparse_products.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <stdexcept>

namespace hindsight {
namespace rod {
namespace {

SparseMatrix randomSparse(int rows, int cols, std::mt19937& random) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-30, 30);
  SparseMatrix a(rows, cols);
  for (int j = 0; j < cols; ++j) {
    for (int i = 0; i < rows; ++i) {
      if ((i * 7 + j * 3) % 5 > 1) continue;
      a.insert(i, j) = (i + j) % 11 == 0 ? 0.0 : std::ldexp(unit(random), exponent(random));
    }
  }
  return a;
}

Matrix randomDense(int rows, int cols, std::mt19937& random) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-30, 30);
  Matrix x(rows, cols);
  for (Eigen::Index c = 0; c < x.cols(); ++c)
    for (Eigen::Index r = 0; r < x.rows(); ++r) x(r, c) = std::ldexp(unit(random), exponent(random));
  return x;
}

bool sameBits(const Matrix& a, const Matrix& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<std::size_t>(a.size())) == 0;
}

TEST(SparseProducts, SparseTimesDenseIsEigensProductBitForBit) {
  std::mt19937 random(7);
  SparseMatrix compressed = randomSparse(57, 43, random);
  SparseMatrix uncompressed = compressed;
  uncompressed.uncompress();
  uncompressed.reserve(Eigen::VectorXi::Constant(43, 3));  // gaps after each column's entries
  ASSERT_FALSE(uncompressed.isCompressed());
  for (const SparseMatrix* a : {&compressed, &uncompressed}) {
    for (int width = 1; width <= 17; ++width) {
      const Matrix x = randomDense(43, width, random);
      const Matrix expected = *a * x;
      EXPECT_TRUE(sameBits(sparseTimesDense(*a, x), expected)) << "width " << width;
    }
  }
  // Rows of zeros in X (the z components the planar part of a solid's modes zeroes), signed zeros in A.
  {
    Matrix x = randomDense(43, 10, random);
    for (Eigen::Index r = 0; r < 43; r += 3) x.row(r).setZero();
    x(1, 1) = -0.0;
    SparseMatrix withZeros = compressed;
    withZeros.valuePtr()[3] = -0.0;
    const Matrix expected = withZeros * x;
    EXPECT_TRUE(sameBits(sparseTimesDense(withZeros, x), expected));
    const Matrix form = x.transpose() * (withZeros * x);
    EXPECT_TRUE(sameBits(x.transpose() * sparseTimesDense(withZeros, x), form));
  }
  // The data are such that order matters: the same sums taken over A's columns in decreasing order
  // differ from Eigen's bits, so a kernel that reordered them would fail above.
  const Matrix x = randomDense(43, 5, random);
  Matrix backwards = Matrix::Zero(57, 5);
  for (Eigen::Index j = 42; j >= 0; --j)
    for (SparseMatrix::InnerIterator it(compressed, j); it; ++it)
      for (Eigen::Index c = 0; c < 5; ++c) backwards(it.row(), c) += it.value() * x(j, c);
  EXPECT_FALSE(sameBits(backwards, Matrix(compressed * x)));
  EXPECT_THROW(sparseTimesDense(compressed, Matrix(42, 2)), std::invalid_argument);
}

TEST(SparseProducts, AddScaledSparseProductIsEigensUpdateBitForBit) {
  std::mt19937 random(11);
  const SparseMatrix a = randomSparse(40, 40, random);
  for (int width : {1, 3, 8, 10, 15, 16, 21}) {
    const Matrix p = randomDense(40, width, random);
    const Matrix start = randomDense(40, width, random);
    Vector scales = randomDense(width, 1, random);
    // Eigen: w = start; w -= s_c (A p_c) without a temporary (noalias), column by column.
    Matrix expected = start;
    for (int c = 0; c < width; ++c) expected.col(c).noalias() -= scales(c) * (a * p.col(c));
    RowMajorBlock y = start, x = -p;
    addScaledSparseProduct(a, x, scales, y);
    EXPECT_TRUE(sameBits(Matrix(y), expected)) << "width " << width;
  }
  RowMajorBlock y(40, 2), x(40, 3);
  EXPECT_THROW(addScaledSparseProduct(a, x, Vector::Ones(3), y), std::invalid_argument);
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
