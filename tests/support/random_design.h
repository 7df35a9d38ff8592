// Seeded random inputs shared by the tests: a vector of uniform entries, and the rod design of the rod
// tests, with about 30 % of the elements below the density-law threshold 0.1 (in [0.02, 0.098]), the rest
// in [0.102, 0.98], so that every element is at least 2e-3 from the kink and central differences never
// straddle it, and the stiffness contrast is ~1e5.
#pragma once

#include <hindsight/problems/rod/rod_config.h>

#include <hindsight/engine/types.h>

#include <random>

namespace hindsight::testing {

/// n entries drawn in index order from the uniform distribution on [low, high).
inline Vector randomVector(Eigen::Index n, std::mt19937& generator, double low = -1.0, double high = 1.0) {
  std::uniform_real_distribution<double> distribution(low, high);
  Vector v(n);
  for (Eigen::Index i = 0; i < n; ++i) v(i) = distribution(generator);
  return v;
}

inline Vector randomRodDesign(const rod::RodConfig& config, unsigned seed) {
  std::mt19937 generator(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Vector design(config.designCount());
  for (auto& x : design)
    x = unit(generator) < 0.3 ? 0.02 + 0.078 * unit(generator) : 0.102 + 0.878 * unit(generator);
  return design;
}

}  // namespace hindsight::testing
