// Central finite-difference gradient checker shared by the rod tests (STYLE.md guideline 5).
//
// Step h_i = cbrt(eps) max(1, |x_i|); reports the finite-difference gradient, the relative error on the
// vector norm and the worst per-component error relative to max(|fd_i|, componentFloor ||fd||_inf).
#pragma once

#include "engine/types.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

namespace hindsight {
namespace testing {

struct GradientCheck {
  Vector finiteDifference;
  double normError = 0.0;       ///< ||fd - analytic|| / ||fd||
  double componentError = 0.0;  ///< max_i |fd_i - analytic_i| / max(|fd_i|, floor ||fd||_inf)
  Eigen::Index worstComponent = -1;
};

inline GradientCheck checkGradient(const std::function<double(const Vector&)>& function, const Vector& x,
                                   const Vector& analytic, double componentFloor = 1e-3) {
  const double step = std::cbrt(std::numeric_limits<double>::epsilon());
  GradientCheck check;
  check.finiteDifference.resize(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double h = step * std::max(1.0, std::abs(x(i)));
    Vector plus = x, minus = x;
    plus(i) += h;
    minus(i) -= h;
    check.finiteDifference(i) = (function(plus) - function(minus)) / (plus(i) - minus(i));
  }
  const Vector& fd = check.finiteDifference;
  check.normError = (fd - analytic).norm() / fd.norm();
  const double floor = componentFloor * fd.cwiseAbs().maxCoeff();
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double error = std::abs(fd(i) - analytic(i)) / std::max(std::abs(fd(i)), floor);
    if (error > check.componentError) {
      check.componentError = error;
      check.worstComponent = i;
    }
  }
  return check;
}

}  // namespace testing
}  // namespace hindsight
