// Density filter for topology optimization on a structured grid of box elements, the 3-D solid member's
// counterpart of DensityFilter (density_filter.h), with the same rule:
//
//   xf_e = sum_k w_ek x_k / sum_k w_ek,   w_ek = max(0, R - |c_e - c_k| / h),
//
// with c_e the element centres in metres, h the element length along x and R the radius in those
// element lengths. On a grid of cubes (and on the plate's square elements, nz = 1) this is exactly the
// plate filter's distance in element widths; on the solid's flat boxes (t / nz < L / nx) the radius stays
// a physical length, so refining through the thickness does not shrink the filter there. Elements
// outside the design (the mask) are neither filtered nor used as neighbours: xf_e = x_e.
//
// Mid-plane symmetry: the grid is the half z >= 0 of a body symmetric about z = 0, layer 0 next to the
// mid-plane. Each element then also reaches the mirror images of its neighbours (layer k mirrors to
// -1 - k), so the filter of the half equals the full body's filter of the mirrored field restricted to
// the half (tested). The filter is linear, xf = F x, and the gradient of phi(xf) with respect to x is
// F^T dphi/dxf (applyTranspose). The Heaviside projection (heaviside_projection.h) acts element by
// element and serves the solid unchanged.
//
// Element numbering (shared with SolidModel's element order, problems/rod/solid_model.h):
// element (i, j, k) has index (i ny + j) nz + k, i along the length, j through the height, k through the
// thickness.
//
// References: Bruns & Tortorelli 2001; Bourdin 2001 (see density_filter.h).
#pragma once

#include <hindsight/engine/types.h>

#include <Eigen/SparseCore>

#include <vector>

namespace hindsight {

class DensityFilter3d final {
 public:
  struct Grid {
    int elementsAlongLength = 1;       ///< nx >= 1
    int elementsThroughHeight = 1;     ///< ny >= 1
    int elementsThroughThickness = 1;  ///< nz >= 1 (over the half with midPlaneSymmetry)
    double elementWidthX = 1.0;        ///< h, the unit of the radius [m], > 0
    double elementWidthY = 1.0;        ///< [m], > 0
    double elementWidthZ = 1.0;        ///< [m], > 0
    bool midPlaneSymmetry = false;     ///< layer 0 borders the symmetry plane z = 0
  };

  /// radius R in element lengths along x (>= 0; a radius reaching no neighbour gives the identity),
  /// design_mask with nx ny nz entries (true = design element) or empty for "all design elements".
  /// Throws std::invalid_argument naming the field when a count is < 1, a width is not positive and
  /// finite, the radius is negative or not finite, or the mask has the wrong length.
  DensityFilter3d(const Grid& grid, double radius, const std::vector<bool>& design_mask = {});

  /// filtered = F x; both of length elementCount(), not aliased. Throws std::invalid_argument on a wrong
  /// length. Allocates nothing.
  void apply(ConstVectorRef x, VectorRef filtered) const;
  /// gradient = F^T gradient_filtered. Same rules as apply.
  void applyTranspose(ConstVectorRef gradient_filtered, VectorRef gradient) const;

  bool isIdentity() const { return identity_; }
  int elementCount() const { return count_; }
  double radius() const { return radius_; }
  /// F (row-major, rows sum to 1); empty when isIdentity().
  const Eigen::SparseMatrix<double, Eigen::RowMajor>& matrix() const { return weights_; }

 private:
  int count_;
  double radius_;
  bool identity_;
  Eigen::SparseMatrix<double, Eigen::RowMajor> weights_;
};

}  // namespace hindsight
