// Density filter for topology optimization on a regular grid of square elements.
//
// The filtered density of a design element e is the weighted mean of the densities of the design
// elements around it (Bruns & Tortorelli 2001; Bourdin 2001):
//
//   xf_e = sum_k w_ek x_k / sum_k w_ek,   w_ek = max(0, R - |c_e - c_k|),
//
// with c_e the element centres measured in element widths and R the radius in element widths.
// Elements outside the design (the mask) are neither filtered nor used as neighbours: xf_e = x_e.
// The filter is linear, xf = F x, and the gradient of an objective phi(xf) with respect to x is
// F^T dphi/dxf, which `applyTranspose` computes (the chain rule of the sensitivity analysis).
// A radius below 1 reaches no neighbour and the filter is the identity; the default of docs/design.md §7
// is no filter, as in the paper.
//
// Element numbering (shared with problems/topopt/pictures.h): element (column, row) has index
// e = row * nx + column, column 0..nx-1 along the length, row 0..ny-1 upwards (row 0 at the bottom).
//
// References:
//   T. E. Bruns, D. A. Tortorelli, Topology optimization of non-linear elastic structures and
//     compliant mechanisms, Comput. Methods Appl. Mech. Engrg. 190 (2001) 3443-3459.
//   B. Bourdin, Filters in topology optimization, Int. J. Numer. Meth. Engng 50 (2001) 2143-2158.
#pragma once

#include <hindsight/engine/types.h>

#include <Eigen/SparseCore>

#include <vector>

namespace hindsight {

class DensityFilter final {
 public:
  /// nx x ny elements, radius R in element widths (>= 0; < 1 gives the identity), design_mask with
  /// nx * ny entries (true = design element) or empty for "every element is a design element".
  /// Throws std::invalid_argument naming the argument when nx < 1, ny < 1, radius < 0 or not finite,
  /// or the mask has the wrong length.
  DensityFilter(int nx, int ny, double radius, const std::vector<bool>& design_mask = {});

  /// filtered = F x. Both have length nx * ny and must not alias. Throws std::invalid_argument on a
  /// wrong length. Allocates nothing.
  void apply(ConstVectorRef x, VectorRef filtered) const;

  /// gradient = F^T gradient_filtered: turns dphi/dxf into dphi/dx. Both have length nx * ny and must
  /// not alias. Throws std::invalid_argument on a wrong length. Allocates nothing.
  void applyTranspose(ConstVectorRef gradient_filtered, VectorRef gradient) const;

  /// True when the filter does nothing (radius < 1 or no design element).
  bool isIdentity() const { return identity_; }
  int elementCount() const { return nx_ * ny_; }
  double radius() const { return radius_; }
  /// The filter matrix F (row-major sparse, nx*ny square); empty when isIdentity().
  const Eigen::SparseMatrix<double, Eigen::RowMajor>& matrix() const { return weights_; }

 private:
  int nx_;
  int ny_;
  double radius_;
  bool identity_;
  Eigen::SparseMatrix<double, Eigen::RowMajor> weights_;  // rows normalised to sum 1
};

}  // namespace hindsight
