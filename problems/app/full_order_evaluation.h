// The full-order piston rod (problems/rod/full_order_rod.h, docs/design.md §9) evaluated as a
// configuration describes it: the integrator, step and storage of `simulation`, the design gradient by
// the discrete adjoint. The application layer's counterpart of PistonRod::evaluate for
// simulation.model = full (the CLI's `evaluate --model full`).
#pragma once

#include <hindsight/engine/adjoint.h>
#include <hindsight/problems/app/config.h>

namespace hindsight {
namespace rod {

/// What evaluateFullOrderRod() returns.
struct FullOrderRodEvaluation {
  double psi1 = 0.0;
  double volumeFraction = 0.0;
  Vector dpsi1;  ///< d psi1,full / dx (empty unless asked)
  Vector dvolume;
  RunSummary summary;
  int stateSize = 0;
  double omegaMax = 0.0;  ///< sqrt of the largest eigenvalue of M^{-1} K [rad/s]
  double modelSeconds = 0.0;
  double simulationSeconds = 0.0;
};

/// psi1,full (and with `gradient` dpsi1/dx by the discrete adjoint over config.simulation.storage)
/// for one design, integrator options as PistonRod::integratorOptions(). Throws std::invalid_argument
/// when the adjoint route is not "discrete", or when an explicit
/// method's step exceeds its stability limit 2.78 / omega_max (naming the limit), and NumericalError
/// for a failed simulation.
FullOrderRodEvaluation evaluateFullOrderRod(const Config& config, ConstVectorRef design, bool gradient);

}  // namespace rod
}  // namespace hindsight
