// The coarse solid connecting rod of the solid member's tests (tests/problems/rod/solid_member_test.cpp,
// tests/problems/topopt/solid_motion_export_test.cpp): 12 x 4 elements through `layers` layers (0: the
// plate), 4 modes, one second of motion ramped up over all of it at a 0.2 ms step.
#pragma once

#include <hindsight/problems/app/config.h>

namespace hindsight::testing {

inline Config coarseSolidConfig(int layers, bool midPlaneSymmetry = false) {
  Config config;
  config.rod.elementsAlongLength = 12;
  config.rod.elementsThroughHeight = 4;
  config.rod.elementsThroughThickness = layers;
  config.rod.midPlaneSymmetry = midPlaneSymmetry;
  config.rod.modeCount = 4;
  config.rod.endTime = 1.0;
  config.rod.rampTime = 1.0;
  config.simulation.step = 2e-4;
  return config;
}

}  // namespace hindsight::testing
