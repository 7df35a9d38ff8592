// A reusable finite-difference gradient checker (docs/design.md P 5; after Ceres' GradientChecker).
//
// Central differences with step h_i = cbrt(eps) * max(1, |x_i|); the error of component i is
// |g_i - fd_i| / max(|fd_i|, floor * ||fd||_inf), so tiny components are judged against the
// gradient's scale. The checker itself is tested against a deliberately wrong gradient.
#pragma once

#include <hindsight/engine/types.h>

#include <functional>
#include <string>
#include <vector>

namespace hindsight {

struct GradientCheckOptions {
  /// Largest accepted error (see above).
  double tolerance = 1e-6;
  /// Components smaller than floor * ||fd||_inf are judged against floor * ||fd||_inf.
  double floor = 1e-3;
  /// Components to check; empty means all.
  std::vector<Eigen::Index> indices;
  /// Overrides the step h_i when positive (relative to max(1, |x_i|)).
  double relativeStep = 0.0;
};

struct GradientCheckResult {
  bool passed = false;
  double maxError = 0.0;  ///< the largest component error (see above)
  Eigen::Index worstIndex = -1;
  /// ||g - fd|| / ||fd|| over the checked components: one number for the whole vector.
  double normError = 0.0;
  Vector finiteDifference;  ///< same size as x; unchecked components are 0
  std::string message;      ///< names the worst component, both values and the error
};

/// Compares `gradient` with central differences of `objective` at x. Throws std::invalid_argument
/// if the sizes differ or an index is out of range.
GradientCheckResult checkGradient(const std::function<double(const Vector&)>& objective, const Vector& x,
                                  const Vector& gradient, const GradientCheckOptions& options = {});

}  // namespace hindsight
