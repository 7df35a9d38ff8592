// Products of the members' sparse K and M with blocks of vectors, bitwise Eigen's own, in one pass over the
// matrix.
//
// Why by hand: Eigen evaluates (column-major sparse) x (dense block) one column of the block at a time
// (SparseDenseProduct.h, sparse_time_dense_product_impl: for each column c, for each column j of A in
// increasing j, y_rc += a_rj (alpha x_jc)), so a block of 14 columns streams A fourteen times: 4.7 % of a
// gradient of the solid at 400 x 16 x 8, where A (12.6 M entries, 150 MB) is read from memory each time
// (bench/RESULTS.md, "The solid's assembly and sparse products"). These kernels read A once and give each
// column exactly Eigen's operations in Eigen's order, so no bit moves (tests/problems/rod/
// sparse_products_test.cpp compares them with Eigen's products bit for bit).
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/member.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace hindsight {
namespace rod {

/// Columns stored by rows (x[i * width + c]), the layout of the factor's block solves.
using RowMajorBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// A X, bitwise Eigen's Matrix(A * X) for a compressed or uncompressed column-major A.
Matrix sparseTimesDense(const SparseMatrix& a, const Eigen::Ref<const Matrix>& x);

/// y_rc += (s_c a_rj) x_jc for X and Y stored by rows, in one pass over A: each column bitwise Eigen's
/// y.col(c).noalias() += (s_c A) x.col(c) (y_r += (s_c a_rj) x_j in increasing j). Eigen evaluates
/// w.noalias() -= s (A p) as w += (s A)(-p) (ProductEvaluators.h, "Dense ?= scalar * Product"), which this
/// is with -p as X. (Without noalias Eigen sums s A p into a temporary first: other bits.)
void addScaledSparseProduct(const SparseMatrix& a, const RowMajorBlock& x, const Vector& scales,
                            RowMajorBlock& y);

}  // namespace rod
}  // namespace hindsight
