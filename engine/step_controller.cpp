#include <hindsight/engine/step_controller.h>

#include <hindsight/engine/deterministic_math.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hindsight {

double infNorm(ConstVectorRef v) { return v.size() == 0 ? 0.0 : v.cwiseAbs().maxCoeff(); }

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
  const double factor = norm > 0.0 ? 0.9 * dmath::pow(norm, exponent_) : 5.0;
  return h * std::min(5.0, std::max(0.2, factor));
}

double StepSizeController::afterRejected(double h, double norm) const {
  return h * std::min(0.9, std::max(0.1, 0.9 * dmath::pow(norm, exponent_)));
}

std::string invalidToleranceEntry(const std::vector<double>& tolerances, const std::string& field) {
  for (std::size_t i = 0; i < tolerances.size(); ++i) {
    if (!(tolerances[i] > 0.0) || !std::isfinite(tolerances[i])) {
      std::ostringstream msg;
      msg << field << "[" << i << "] = " << tolerances[i] << " must be positive and finite";
      return msg.str();
    }
  }
  return {};
}

void requireOneTolerancePerState(const std::vector<double>& tolerances, const std::string& field,
                                 const std::string& problemName, int stateSize, const std::string& meaning) {
  if (!tolerances.empty() && static_cast<int>(tolerances.size()) != stateSize) {
    throw std::invalid_argument(field + " has " + std::to_string(tolerances.size()) + " entries, problem '" +
                                problemName + "' has " + std::to_string(stateSize) + " states (" + meaning +
                                ")");
  }
}

}  // namespace hindsight
