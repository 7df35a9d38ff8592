#include <hindsight/engine/step_controller.h>

#include <algorithm>
#include <cmath>

namespace hindsight {

double weightedRmsNorm(ConstVectorRef error, ConstVectorRef y0, ConstVectorRef y1, double relativeTolerance,
                       double absoluteTolerance) {
  double sum = 0.0;
  for (Eigen::Index i = 0; i < error.size(); ++i) {
    const double scale = absoluteTolerance + relativeTolerance * std::max(std::abs(y0(i)), std::abs(y1(i)));
    const double r = error(i) / scale;
    sum += r * r;
  }
  return std::sqrt(sum / static_cast<double>(error.size()));
}

double weightedRmsNorm(ConstVectorRef error, ConstVectorRef y0, ConstVectorRef y1,
                       ConstVectorRef relativeTolerances, ConstVectorRef absoluteTolerances) {
  double sum = 0.0;
  for (Eigen::Index i = 0; i < error.size(); ++i) {
    const double scale =
        absoluteTolerances(i) + relativeTolerances(i) * std::max(std::abs(y0(i)), std::abs(y1(i)));
    const double r = error(i) / scale;
    sum += r * r;
  }
  return std::sqrt(sum / static_cast<double>(error.size()));
}

double StepSizeController::afterAccepted(double h, double norm) const {
  // A zero error estimate (e.g. a linear solution) allows the largest growth.
  const double factor = norm > 0.0 ? 0.9 * std::pow(norm, exponent_) : 5.0;
  return h * std::min(5.0, std::max(0.2, factor));
}

double StepSizeController::afterRejected(double h, double norm) const {
  return h * std::min(0.9, std::max(0.1, 0.9 * std::pow(norm, exponent_)));
}

}  // namespace hindsight
