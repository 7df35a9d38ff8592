#include <hindsight/engine/gradient_checker.h>

#include <cmath>
#include <limits>
#include <sstream>

namespace hindsight {

GradientCheckResult checkGradient(const std::function<double(const Vector&)>& objective, const Vector& x,
                                  const Vector& gradient, const GradientCheckOptions& options) {
  if (gradient.size() != x.size()) {
    throw std::invalid_argument("checkGradient: gradient has size " + std::to_string(gradient.size()) +
                                ", x has size " + std::to_string(x.size()));
  }
  std::vector<Eigen::Index> indices = options.indices;
  if (indices.empty()) {
    for (Eigen::Index i = 0; i < x.size(); ++i) indices.push_back(i);
  }
  GradientCheckResult result;
  result.finiteDifference = Vector::Zero(x.size());
  const double relativeStep =
      options.relativeStep > 0.0 ? options.relativeStep : std::cbrt(std::numeric_limits<double>::epsilon());
  Vector shifted = x;
  for (Eigen::Index i : indices) {
    if (i < 0 || i >= x.size()) {
      throw std::invalid_argument("checkGradient: index " + std::to_string(i) + " outside [0, " +
                                  std::to_string(x.size()) + ")");
    }
    const double h = relativeStep * std::max(1.0, std::abs(x(i)));
    shifted(i) = x(i) + h;
    const double plus = objective(shifted);
    shifted(i) = x(i) - h;
    const double minus = objective(shifted);
    shifted(i) = x(i);
    // Divide by the step actually represented in floating point.
    result.finiteDifference(i) = (plus - minus) / ((x(i) + h) - (x(i) - h));
  }
  double scale = 0.0;
  for (Eigen::Index i : indices) scale = std::max(scale, std::abs(result.finiteDifference(i)));
  const double floorValue = std::max(options.floor * scale, std::numeric_limits<double>::min());
  for (Eigen::Index i : indices) {
    const double fd = result.finiteDifference(i);
    const double error = std::abs(gradient(i) - fd) / std::max(std::abs(fd), floorValue);
    if (!(error <= result.maxError)) {  // also catches NaN
      result.maxError = std::isnan(error) ? std::numeric_limits<double>::infinity() : error;
      result.worstIndex = i;
    }
  }
  double differenceSquared = 0.0, fdSquared = 0.0;
  for (Eigen::Index i : indices) {
    differenceSquared +=
        (gradient(i) - result.finiteDifference(i)) * (gradient(i) - result.finiteDifference(i));
    fdSquared += result.finiteDifference(i) * result.finiteDifference(i);
  }
  result.normError = std::sqrt(differenceSquared) / std::sqrt(fdSquared);
  result.passed = result.maxError <= options.tolerance;
  std::ostringstream msg;
  msg.precision(12);
  if (result.worstIndex >= 0) {
    msg << "worst component " << result.worstIndex << ": analytic " << gradient(result.worstIndex)
        << ", finite difference " << result.finiteDifference(result.worstIndex) << ", error "
        << result.maxError << " (tolerance " << options.tolerance << ")";
  } else {
    msg << "all components agree exactly";
  }
  result.message = msg.str();
  return result;
}

}  // namespace hindsight
