// Half of a solid bar (mid-plane symmetry) with the seeded random design of random_design.h: the member
// whose K is factorised in METIS's ordering (tests/problems/rod/subtree_ldlt_test.cpp,
// supernodal_ldlt_test.cpp).
#pragma once

#include <hindsight/problems/rod/solid_member.h>

#include "support/random_design.h"

namespace hindsight::testing {

inline rod::SolidMember randomSolidHalf(int along, int through, int thickness, unsigned seed) {
  rod::RodConfig config;
  config.elementsAlongLength = along;
  config.elementsThroughHeight = through;
  config.elementsThroughThickness = thickness;
  config.midPlaneSymmetry = true;
  return rod::SolidMember(config, randomRodDesign(config, seed));
}

}  // namespace hindsight::testing
