#include <hindsight/problems/rod/crank_motion.h>

#include <hindsight/problems/mechanism/mechanism.h>

namespace hindsight::rod {

void CrankMotion::at(double t, double& phi, double& phiDot, double& phiDdot) const {
  // The cycloidal ramp of the mechanism's drivers: one formula for the described and the full-order rod.
  mechanism::DriverLaw law;
  law.kind = mechanism::DriverLaw::Kind::CycloidalRamp;
  law.speed = omega;
  law.rampTime = rampTime;
  law.at(t, phi, phiDot, phiDdot);
}

}  // namespace hindsight::rod
