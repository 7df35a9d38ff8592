// The seeded random rod design shared by the rod tests: about 30 % of the elements below the density-law
// threshold 0.1 (in [0.02, 0.098]), the rest in [0.102, 0.98], so that every element is at least 2e-3 from
// the kink and central differences never straddle it, and the stiffness contrast is ~1e5.
#pragma once

#include <hindsight/problems/rod/rod_config.h>

#include <hindsight/engine/types.h>

#include <random>

namespace hindsight::testing {

inline Vector randomRodDesign(const rod::RodConfig& config, unsigned seed) {
  std::mt19937 generator(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Vector design(config.designCount());
  for (auto& x : design)
    x = unit(generator) < 0.3 ? 0.02 + 0.078 * unit(generator) : 0.102 + 0.878 * unit(generator);
  return design;
}

}  // namespace hindsight::testing
