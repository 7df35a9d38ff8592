#include <hindsight/problems/topopt/heaviside_projection.h>

#include <hindsight/engine/deterministic_math.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hindsight {

HeavisideProjection::HeavisideProjection(double beta, double eta, double lower)
    : beta_(beta), eta_(eta), lower_(lower) {
  if (!(beta > 0.0 && std::isfinite(beta))) {
    std::ostringstream out;
    out << "HeavisideProjection: beta = " << beta << " must be > 0 and finite";
    throw std::invalid_argument(out.str());
  }
  if (!(eta > 0.0 && eta < 1.0)) {
    std::ostringstream out;
    out << "HeavisideProjection: eta = " << eta << " must be in (0, 1)";
    throw std::invalid_argument(out.str());
  }
  if (!(lower >= 0.0 && lower < 1.0)) {
    std::ostringstream out;
    out << "HeavisideProjection: lower = " << lower << " must be in [0, 1)";
    throw std::invalid_argument(out.str());
  }
  tanhBetaEta_ = dmath::tanh(beta * eta);
  denominator_ = tanhBetaEta_ + dmath::tanh(beta * (1.0 - eta));
}

double HeavisideProjection::value(double filtered) const {
  const double h = (tanhBetaEta_ + dmath::tanh(beta_ * (filtered - eta_))) / denominator_;
  return lower_ + (1.0 - lower_) * h;
}

double HeavisideProjection::derivative(double filtered) const {
  const double t = dmath::tanh(beta_ * (filtered - eta_));
  return (1.0 - lower_) * beta_ * (1.0 - t * t) / denominator_;
}

double HeavisideProjection::continuationBeta(double beta0, double betaMax, int every, int iteration) {
  const int doublings = std::max(0, iteration) / std::max(1, every);
  double beta = beta0;
  for (int k = 0; k < doublings && beta < betaMax; ++k) beta *= 2.0;
  return std::min(beta, betaMax);
}

double grayness(ConstVectorRef densities) {
  if (densities.size() == 0) return 0.0;
  Eigen::Index gray = 0;
  for (Eigen::Index i = 0; i < densities.size(); ++i) {
    if (densities(i) > 0.1 && densities(i) < 0.9) ++gray;
  }
  return static_cast<double>(gray) / static_cast<double>(densities.size());
}

}  // namespace hindsight
