#include <hindsight/problems/topopt/density_filter.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

void CheckLength(const char* function, const char* name, Eigen::Index actual, int expected) {
  if (actual != expected) {
    std::ostringstream out;
    out << "DensityFilter::" << function << ": " << name << " has length " << actual
        << ", expected nx * ny = " << expected;
    throw std::invalid_argument(out.str());
  }
}

}  // namespace

DensityFilter::DensityFilter(int nx, int ny, double radius, const std::vector<bool>& design_mask)
    : nx_(nx), ny_(ny), radius_(radius), identity_(false) {
  if (nx < 1) throw std::invalid_argument("DensityFilter: nx = " + std::to_string(nx) + " must be >= 1");
  if (ny < 1) throw std::invalid_argument("DensityFilter: ny = " + std::to_string(ny) + " must be >= 1");
  if (!(radius >= 0.0 && std::isfinite(radius))) {
    std::ostringstream out;
    out << "DensityFilter: radius = " << radius << " must be finite and >= 0 (element widths)";
    throw std::invalid_argument(out.str());
  }
  const int count = nx * ny;
  if (!design_mask.empty() && static_cast<int>(design_mask.size()) != count) {
    throw std::invalid_argument("DensityFilter: design_mask has length " +
                                std::to_string(design_mask.size()) +
                                ", expected nx * ny = " + std::to_string(count) + " (or empty)");
  }
  auto isDesign = [&design_mask](int e) { return design_mask.empty() || design_mask[e]; };
  const bool noDesign =
      !design_mask.empty() && std::none_of(design_mask.begin(), design_mask.end(), [](bool b) { return b; });
  identity_ = radius < 1.0 || noDesign;
  if (identity_) return;

  // Neighbours lie within ceil(R) - 1 columns and rows: a centre distance of exactly R has weight 0.
  const int reach = static_cast<int>(std::ceil(radius)) - 1;
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(count) * (2 * reach + 1) * (2 * reach + 1));
  for (int row = 0; row < ny; ++row) {
    for (int column = 0; column < nx; ++column) {
      const int e = row * nx + column;
      if (!isDesign(e)) {
        entries.emplace_back(e, e, 1.0);
        continue;
      }
      double total = 0.0;
      const std::size_t first = entries.size();
      for (int r = std::max(0, row - reach); r <= std::min(ny - 1, row + reach); ++r) {
        for (int c = std::max(0, column - reach); c <= std::min(nx - 1, column + reach); ++c) {
          const int k = r * nx + c;
          if (!isDesign(k)) continue;
          // sqrt of an integer sum is exactly rounded on every CPU; std::hypot is a libm call.
          const int dc = c - column, dr = r - row;
          const double weight = radius - std::sqrt(double(dc * dc + dr * dr));
          if (weight <= 0.0) continue;
          entries.emplace_back(e, k, weight);
          total += weight;
        }
      }
      for (std::size_t i = first; i < entries.size(); ++i)
        entries[i] = Eigen::Triplet<double>(entries[i].row(), entries[i].col(), entries[i].value() / total);
    }
  }
  weights_.resize(count, count);
  weights_.setFromTriplets(entries.begin(), entries.end());
  weights_.makeCompressed();
}

void DensityFilter::apply(ConstVectorRef x, VectorRef filtered) const {
  CheckLength("apply", "x", x.size(), nx_ * ny_);
  CheckLength("apply", "filtered", filtered.size(), nx_ * ny_);
  if (identity_) {
    filtered = x;
    return;
  }
  filtered.noalias() = weights_ * x;
}

void DensityFilter::applyTranspose(ConstVectorRef gradient_filtered, VectorRef gradient) const {
  CheckLength("applyTranspose", "gradient_filtered", gradient_filtered.size(), nx_ * ny_);
  CheckLength("applyTranspose", "gradient", gradient.size(), nx_ * ny_);
  if (identity_) {
    gradient = gradient_filtered;
    return;
  }
  gradient.noalias() = weights_.transpose() * gradient_filtered;
}

}  // namespace hindsight
