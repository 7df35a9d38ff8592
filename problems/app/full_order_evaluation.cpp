#include <hindsight/problems/app/full_order_evaluation.h>

#include <hindsight/engine/runge_kutta.h>
#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/rod/full_order_rod.h>
#include <hindsight/storage/storage_factory.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {

FullOrderRodEvaluation evaluateFullOrderRod(const Config& config, ConstVectorRef design, bool gradient) {
  const PistonRod reference(config);  // validates the configuration
  if (config.simulation.adjoint != AdjointMethod::Discrete) {
    throw std::invalid_argument("config field 'simulation.adjoint' = '" +
                                toString(config.simulation.adjoint) +
                                "': the full-order model supports only 'discrete'");
  }
  if (!isRungeKutta(parseIntegratorMethod(config.simulation.integrator))) {
    // The full-order rod is a first-order Problem; generalized-alpha needs a SecondOrderProblem.
    throw std::invalid_argument("config field 'simulation.integrator' = '" + config.simulation.integrator +
                                "' serves only simulation.model = reduced; the full-order model takes a "
                                "Runge-Kutta method (trbdf2, midpoint, ...)");
  }
  IntegratorOptions options = reference.integratorOptions();
  // The stage residual K - F(Z) of this stiff model has round-off ~1e-11 ||Z|| (F sums terms
  // omega_max^2 u far larger than itself), so the engine's default 1e-13 could not be met by a
  // confirming iteration; the problem is linear in the state (isLinearInState), so the engine takes
  // one exact Newton step per stage and this tolerance only matters to callers that iterate.
  options.newtonTolerance = std::max(options.newtonTolerance, 1e-10);
  FullOrderRodEvaluation out;
  Stopwatch phase;
  const FullOrderRodProblem problem(config.rod, design, config.simulation.fullOrderCoupling);
  out.stateSize = problem.stateSize();
  out.volumeFraction = problem.model().volumeFraction();
  out.dvolume = problem.model().volumeFractionGradient();
  out.omegaMax = std::sqrt(problem.largestEigenvalue());
  const ButcherTableau tableau = ButcherTableau::byName(options.method);
  if (tableau.isExplicit() && !options.adaptive) {
    // RK4's stability interval on the imaginary axis is 2 sqrt(2) = 2.83; 2.78 leaves a margin for the
    // power iteration's underestimate.
    const double limit = 2.78 / out.omegaMax;
    if (options.step > limit) {
      throw std::invalid_argument("config field 'simulation.step' = " + std::to_string(options.step) +
                                  " is unstable for the explicit method '" + options.method +
                                  "' on the full-order model (omega_max = " + std::to_string(out.omegaMax) +
                                  " rad/s needs step < " + std::to_string(limit) +
                                  "); use simulation.integrator = trbdf2 or midpoint");
    }
  }
  out.modelSeconds = phase.restart();
  const Vector p = design;
  if (gradient) {
    auto storage = createStorage(config.simulation.storage);
    GradientResult result = computeGradient(problem, p, options, *storage);
    out.psi1 = result.objective;
    out.dpsi1 = result.gradient;
    out.summary = result.summary;
  } else {
    ForwardResult result = simulate(problem, p, options);
    out.psi1 = result.objective;
    out.summary = result.summary;
  }
  out.simulationSeconds = phase.seconds();
  return out;
}

}  // namespace rod
}  // namespace hindsight
