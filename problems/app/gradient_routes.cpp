#include <hindsight/problems/app/gradient_routes.h>

#include <hindsight/storage/storage_factory.h>

namespace hindsight {

namespace {

// The CVODES route is built only where SUNDIALS was found (CMakeLists.txt, HINDSIGHT_CVODES): elsewhere
// asking for it is refused where the name is read, before anything runs or is written.
void requireCvodesBuilt() {
#ifndef HINDSIGHT_HAVE_CVODES
  throw std::invalid_argument(
      "adjoint method 'cvodes': this build has no CVODES route (SUNDIALS was not found when it was "
      "configured); install Debian's libsundials-dev and configure again with -DHINDSIGHT_CVODES=ON (the "
      "README's second command does both), or use discrete or continuous");
#endif
}

}  // namespace

AdjointMethod parseAdjointMethod(const std::string& name) {
  if (name == "discrete") return AdjointMethod::Discrete;
  if (name == "continuous") return AdjointMethod::Continuous;
  if (name == "cvodes") {
    requireCvodesBuilt();
    return AdjointMethod::Cvodes;
  }
  throw std::invalid_argument("adjoint method '" + name +
                              "' is unknown; valid: discrete, continuous, cvodes");
}

std::string toString(AdjointMethod method) {
  switch (method) {
    case AdjointMethod::Discrete:
      return "discrete";
    case AdjointMethod::Continuous:
      return "continuous";
    case AdjointMethod::Cvodes:
      return "cvodes";
  }
  return "unknown";
}

std::vector<std::string> adjointMethodNames() { return {"discrete", "continuous", "cvodes"}; }

GradientResult computeGradientByMethod(const Problem& problem, ConstVectorRef p,
                                       const GradientOptions& options) {
  switch (options.adjoint) {
    case AdjointMethod::Discrete: {
      const std::unique_ptr<TrajectoryStorage> storage = createStorage(options.storage);
      return computeGradient(problem, p, options.integrator, *storage);
    }
    case AdjointMethod::Continuous: {
      const std::unique_ptr<TrajectoryStorage> storage = createStorage(options.storage);
      return computeGradientContinuous(problem, p, options.integrator, *storage, options.continuous);
    }
    case AdjointMethod::Cvodes: {
      requireCvodesBuilt();
#ifdef HINDSIGHT_HAVE_CVODES
      CvodesOptions cvodes = options.cvodes;
      cvodes.t0 = options.integrator.t0;
      cvodes.t1 = options.integrator.t1;
      return computeGradientCvodes(problem, p, cvodes);
#endif
    }
  }
  throw std::invalid_argument("GradientOptions.adjoint has an invalid value");
}

}  // namespace hindsight
