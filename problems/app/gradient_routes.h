// One entry point for dpsi/dp whichever adjoint method computes it (docs/design.md §4 and §5):
// computeGradientByMethod() picks the route by name and makes the storage from its spec string; the routes
// themselves are computeGradient() (discrete, engine/adjoint.h), computeGradientContinuous() and
// computeGradientCvodes(). It lives in the application layer (problems/app/, docs/guides/architecture.md)
// because that is the lowest layer that sees all three: the engine knows neither CVODES nor spec
// strings, cvodes/ is one route among three, and the problems below this layer (problems/rod/) describe
// models without choosing how their gradients are computed. The CLI exposes the choice as
// --adjoint discrete|continuous|cvodes.
//
//   discrete   the transpose of the integrator's step map over a trajectory storage strategy
//              (engine/adjoint.h); the exact derivative of the computed psi; hindsight's default;
//   continuous the adjoint ODE integrated backward with its own adaptive steps, forward states
//              interpolated from the storage (engine/continuous_adjoint.h);
//   cvodes     SUNDIALS CVODES, CVodeF/CVodeB with check points (cvodes/cvodes_adjoint.h); needs a
//              dense Jacobian.
// The discrete and continuous routes run the forward sweep described by `integrator` over the
// storage made from `storage` (storage/storage_factory.h); the CVODES route uses `cvodes` and takes
// its interval [t0, t1] from `integrator` so that all three describe the same problem.
//
// Throws what the chosen route throws: std::invalid_argument for bad options or spec strings,
// NumericalError (with the time) for numerical failures, StorageError from the storage.
#pragma once

#include <hindsight/cvodes/cvodes_adjoint.h>
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/continuous_adjoint.h>

#include <string>
#include <vector>

namespace hindsight {

enum class AdjointMethod { Discrete, Continuous, Cvodes };

/// "discrete" | "continuous" | "cvodes"; throws std::invalid_argument listing the valid names.
AdjointMethod parseAdjointMethod(const std::string& name);
std::string toString(AdjointMethod method);
/// The valid names, for help texts.
std::vector<std::string> adjointMethodNames();

struct GradientOptions {
  AdjointMethod adjoint = AdjointMethod::Discrete;
  /// The forward integrator (discrete and continuous routes) and the interval [t0, t1] (all routes).
  IntegratorOptions integrator;
  /// Storage spec for the discrete and continuous routes, e.g. "full", "hermite:every=4".
  std::string storage = "full";
  ContinuousAdjointOptions continuous;
  /// CVODES settings; its t0 and t1 are replaced by integrator.t0 and integrator.t1.
  CvodesOptions cvodes;
};

/// psi and dpsi/dp by the route `options.adjoint`; summary.adjoint names the route.
GradientResult computeGradientByMethod(const Problem& problem, ConstVectorRef p,
                                       const GradientOptions& options);

}  // namespace hindsight
