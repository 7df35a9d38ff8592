// Smoothed Heaviside projection of filtered densities (Wang, Lazarov & Sigmund 2011), for crisp
// black-and-white designs:
//
//   H(xf) = (tanh(beta eta) + tanh(beta (xf - eta))) / (tanh(beta eta) + tanh(beta (1 - eta))),
//
// mapping [0, 1] onto [0, 1] with H(0) = 0, H(1) = 1 and H(eta) near eta; beta -> infinity gives the
// step at the threshold eta. The physical density is xMin + (1 - xMin) H(xf), so it stays in the
// design box [xMin, 1] the finite-element model accepts. dH/dxf = beta (1 - tanh^2(beta (xf - eta))) /
// denominator. Projection without a filter is allowed but pointless (it only rescales the design
// variables); the optimizer chains design -> filter -> projection -> model and the gradient back
// through both (problems/topopt/topology_optimizer.h).
//
// beta-continuation: beta_k = min(beta0 2^floor(k / every), betaMax) at iteration k, a function of the
// iteration only, so restart stays bit-identical.
//
// Reference: F. Wang, B. S. Lazarov, O. Sigmund, On projection methods, convergence and robust
// formulations in topology optimization, Struct. Multidisc. Optim. 43 (2011) 767-784.
#pragma once

#include <hindsight/engine/types.h>

namespace hindsight {

class HeavisideProjection final {
 public:
  /// beta > 0, eta in (0, 1), lower in [0, 1). Throws std::invalid_argument naming the argument.
  HeavisideProjection(double beta, double eta, double lower);

  /// xMin + (1 - xMin) H(xf), entry by entry (xf in [0, 1]).
  double value(double filtered) const;
  /// d value / d xf.
  double derivative(double filtered) const;

  double beta() const { return beta_; }
  double eta() const { return eta_; }

  /// beta of iteration k under continuation (see above); every >= 1, betaMax >= beta0 > 0.
  static double continuationBeta(double beta0, double betaMax, int every, int iteration);

 private:
  double beta_, eta_, lower_, tanhBetaEta_, denominator_;
};

/// Fraction of the entries strictly inside (0.1, 0.9): the grayness of a design (0 = black and white).
double grayness(ConstVectorRef densities);

}  // namespace hindsight
