// The prescribed crank of the piston rod (docs/design.md §2): the cycloidal ramp from rest to Omega over
// the ramp time, then constant speed. The full-order rod's frame follows it (problems/rod/full_order_rod.h);
// the described slider-crank drives its crank with the same law (mechanism::sliderCrank, a
// mechanism::DriverLaw), and at() evaluates that law, so both models see the crank angle's same bits.
#pragma once

#include <cmath>

namespace hindsight::rod {

/// The prescribed crank: phi' = Omega (tau - sin(2 pi tau) / (2 pi)), tau = t / T, for t <= T (so
/// phi''(0) = phi''(T) = 0), then phi' = Omega; phi(0) = 0. Units: m, rad, s.
struct CrankMotion {
  double radius = 0.15;
  double omega = 10.0 * M_PI;
  double rampTime = 2.0;
  /// Angle, angular velocity and acceleration at time t.
  void at(double t, double& phi, double& phiDot, double& phiDdot) const;
};

}  // namespace hindsight::rod
