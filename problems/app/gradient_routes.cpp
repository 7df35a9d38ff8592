#include <hindsight/problems/app/gradient_routes.h>

#include <hindsight/storage/storage_factory.h>

namespace hindsight {

AdjointMethod parseAdjointMethod(const std::string& name) {
  if (name == "discrete") return AdjointMethod::Discrete;
  if (name == "continuous") return AdjointMethod::Continuous;
  if (name == "cvodes") return AdjointMethod::Cvodes;
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
      CvodesOptions cvodes = options.cvodes;
      cvodes.t0 = options.integrator.t0;
      cvodes.t1 = options.integrator.t1;
      return computeGradientCvodes(problem, p, cvodes);
    }
  }
  throw std::invalid_argument("GradientOptions.adjoint has an invalid value");
}

}  // namespace hindsight
