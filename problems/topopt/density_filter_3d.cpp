#include <hindsight/problems/topopt/density_filter_3d.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

void checkCount(const char* name, int value) {
  if (value < 1)
    throw std::invalid_argument("DensityFilter3d: " + std::string(name) + " = " + std::to_string(value) +
                                " must be >= 1");
}

void checkWidth(const char* name, double value) {
  if (!(value > 0.0 && std::isfinite(value))) {
    std::ostringstream out;
    out << "DensityFilter3d: " << name << " = " << value << " must be finite and > 0 [m]";
    throw std::invalid_argument(out.str());
  }
}

void checkLength(const char* function, const char* name, Eigen::Index actual, int expected) {
  if (actual != expected) {
    std::ostringstream out;
    out << "DensityFilter3d::" << function << ": " << name << " has length " << actual
        << ", expected nx * ny * nz = " << expected;
    throw std::invalid_argument(out.str());
  }
}

}  // namespace

DensityFilter3d::DensityFilter3d(const Grid& grid, double radius, const std::vector<bool>& design_mask)
    : count_(0), radius_(radius), identity_(false) {
  checkCount("elementsAlongLength", grid.elementsAlongLength);
  checkCount("elementsThroughHeight", grid.elementsThroughHeight);
  checkCount("elementsThroughThickness", grid.elementsThroughThickness);
  checkWidth("elementWidthX", grid.elementWidthX);
  checkWidth("elementWidthY", grid.elementWidthY);
  checkWidth("elementWidthZ", grid.elementWidthZ);
  if (!(radius >= 0.0 && std::isfinite(radius))) {
    std::ostringstream out;
    out << "DensityFilter3d: radius = " << radius << " must be finite and >= 0 (element lengths along x)";
    throw std::invalid_argument(out.str());
  }
  const int nx = grid.elementsAlongLength, ny = grid.elementsThroughHeight,
            nz = grid.elementsThroughThickness;
  count_ = nx * ny * nz;
  if (!design_mask.empty() && static_cast<int>(design_mask.size()) != count_) {
    throw std::invalid_argument("DensityFilter3d: design_mask has length " +
                                std::to_string(design_mask.size()) +
                                ", expected nx * ny * nz = " + std::to_string(count_) + " (or empty)");
  }
  auto isDesign = [&design_mask](int e) {
    return design_mask.empty() || design_mask[static_cast<std::size_t>(e)];
  };
  // Distances in element lengths along x; the reach along each axis is the largest offset whose centre
  // distance along that axis alone stays below R (distance exactly R has weight 0).
  const double scaleY = grid.elementWidthY / grid.elementWidthX,
               scaleZ = grid.elementWidthZ / grid.elementWidthX;
  auto reachOf = [radius](double scale) { return static_cast<int>(std::ceil(radius / scale)) - 1; };
  const int reachX = reachOf(1.0), reachY = reachOf(scaleY), reachZ = reachOf(scaleZ);
  const bool noDesign =
      !design_mask.empty() && std::none_of(design_mask.begin(), design_mask.end(), [](bool b) { return b; });
  identity_ = noDesign;
  if (identity_) return;

  std::vector<Eigen::Triplet<double>> entries;
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) {
        const int e = (i * ny + j) * nz + k;
        if (!isDesign(e)) {
          entries.emplace_back(e, e, 1.0);
          continue;
        }
        double total = 0.0;
        const std::size_t first = entries.size();
        const int kLow = std::max(grid.midPlaneSymmetry ? -nz : 0, k - reachZ);
        for (int ii = std::max(0, i - reachX); ii <= std::min(nx - 1, i + reachX); ++ii) {
          for (int jj = std::max(0, j - reachY); jj <= std::min(ny - 1, j + reachY); ++jj) {
            for (int kk = kLow; kk <= std::min(nz - 1, k + reachZ); ++kk) {
              // kk < 0 is the mirror image of layer -1 - kk across the symmetry plane.
              const int layer = kk < 0 ? -1 - kk : kk;
              const int neighbour = (ii * ny + jj) * nz + layer;
              if (!isDesign(neighbour)) continue;
              const double dx = ii - i, dy = (jj - j) * scaleY, dz = (kk - k) * scaleZ;
              const double weight = radius - std::sqrt(dx * dx + dy * dy + dz * dz);
              if (weight <= 0.0) continue;
              entries.emplace_back(e, neighbour, weight);
              total += weight;
            }
          }
        }
        for (std::size_t n = first; n < entries.size(); ++n)
          entries[n] = Eigen::Triplet<double>(entries[n].row(), entries[n].col(), entries[n].value() / total);
      }
    }
  }
  // A radius that reaches no neighbour (every row holds only its own element) is the identity.
  if (entries.size() == static_cast<std::size_t>(count_)) {
    identity_ = true;
    return;
  }
  // setFromTriplets sums the two entries of an element that is its own mirror's neighbour.
  weights_.resize(count_, count_);
  weights_.setFromTriplets(entries.begin(), entries.end());
  weights_.makeCompressed();
}

void DensityFilter3d::apply(ConstVectorRef x, VectorRef filtered) const {
  checkLength("apply", "x", x.size(), count_);
  checkLength("apply", "filtered", filtered.size(), count_);
  if (identity_) {
    filtered = x;
    return;
  }
  filtered.noalias() = weights_ * x;
}

void DensityFilter3d::applyTranspose(ConstVectorRef gradient_filtered, VectorRef gradient) const {
  checkLength("applyTranspose", "gradient_filtered", gradient_filtered.size(), count_);
  checkLength("applyTranspose", "gradient", gradient.size(), count_);
  if (identity_) {
    gradient = gradient_filtered;
    return;
  }
  gradient.noalias() = weights_.transpose() * gradient_filtered;
}

}  // namespace hindsight
