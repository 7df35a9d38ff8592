#include <hindsight/engine/generalized_alpha.h>
#include <hindsight/engine/integrator.h>

#include <hindsight/engine/runge_kutta.h>
#include <hindsight/engine/step_controller.h>

#include <cmath>
#include <sstream>

namespace hindsight {
namespace {

struct MethodName {
  IntegratorMethod method;
  const char* name;
};

// The one table of user-facing names; parse, print and list all read it.
constexpr MethodName kMethodNames[] = {
    {IntegratorMethod::Rk4, "rk4"},
    {IntegratorMethod::Dopri5, "dopri5"},
    {IntegratorMethod::TrBdf2, "trbdf2"},
    {IntegratorMethod::Sdirk2, "sdirk2"},
    {IntegratorMethod::Midpoint, "midpoint"},
    {IntegratorMethod::GeneralizedAlpha, "generalized-alpha"},
    {IntegratorMethod::HhtAlpha, "hht-alpha"},
};

}  // namespace

bool isRungeKutta(IntegratorMethod method) {
  return method != IntegratorMethod::GeneralizedAlpha && method != IntegratorMethod::HhtAlpha;
}

std::string toString(IntegratorMethod method) {
  for (const auto& entry : kMethodNames) {
    if (entry.method == method) return entry.name;
  }
  return "unknown";
}

std::vector<std::string> integratorMethodNames() {
  std::vector<std::string> names;
  for (const auto& entry : kMethodNames) names.emplace_back(entry.name);
  return names;
}

IntegratorMethod parseIntegratorMethod(const std::string& name) {
  for (const auto& entry : kMethodNames) {
    if (name == entry.name) return entry.method;
  }
  std::string known;
  for (const auto& n : integratorMethodNames()) known += (known.empty() ? "" : ", ") + n;
  throw std::invalid_argument("IntegratorOptions.method = '" + name +
                              "' is unknown; known methods: " + known);
}

bool IntegratorOptions::IsValid(std::string* error) const {
  std::ostringstream msg;
  const auto fail = [&](const std::string& text) {
    if (error != nullptr) *error = text;
    return false;
  };
  IntegratorMethod parsed;
  try {
    parsed = parseIntegratorMethod(method);
  } catch (const std::invalid_argument& e) {
    return fail(e.what());
  }
  if (!std::isfinite(t0) || !std::isfinite(t1) || !(t1 > t0)) {
    msg << "IntegratorOptions: t1 = " << t1 << " must be finite and greater than t0 = " << t0;
    return fail(msg.str());
  }
  if (!std::isfinite(step) || !(step > 0.0)) {
    msg << "IntegratorOptions.step = " << step << " must be positive and finite";
    return fail(msg.str());
  }
  if (adaptive) {
    if (!isRungeKutta(parsed) || ButcherTableau::byMethod(parsed).bEmbedded.size() == 0) {
      return fail("IntegratorOptions.adaptive: method '" + method +
                  "' has no embedded error estimate; use dopri5 or trbdf2");
    }
    if (!(relativeTolerance > 0.0) || !(absoluteTolerance > 0.0) || !std::isfinite(relativeTolerance) ||
        !std::isfinite(absoluteTolerance)) {
      msg << "IntegratorOptions: relativeTolerance = " << relativeTolerance
          << " and absoluteTolerance = " << absoluteTolerance << " must be positive and finite";
      return fail(msg.str());
    }
    if (const std::string entry =
            invalidToleranceEntry(absoluteTolerances, "IntegratorOptions.absoluteTolerances");
        !entry.empty())
      return fail(entry);
    if (!(minStep > 0.0) || maxStep < 0.0) {
      msg << "IntegratorOptions: minStep = " << minStep << " must be positive and maxStep = " << maxStep
          << " non-negative";
      return fail(msg.str());
    }
  }
  if (maxSteps < 1) {
    msg << "IntegratorOptions.maxSteps = " << maxSteps << " must be at least 1";
    return fail(msg.str());
  }
  if (!(newtonTolerance > 0.0) || newtonTolerance >= 1.0 || newtonMaxIterations < 1) {
    msg << "IntegratorOptions: newtonTolerance = " << newtonTolerance
        << " must be in (0, 1) and newtonMaxIterations = " << newtonMaxIterations << " at least 1";
    return fail(msg.str());
  }
  if (!(rhoInfinity >= 0.0 && rhoInfinity <= 1.0)) {
    msg << "IntegratorOptions.rhoInfinity = " << rhoInfinity << " must be in [0, 1]";
    return fail(msg.str());
  }
  if (parsed == IntegratorMethod::HhtAlpha && rhoInfinity < 0.5) {
    // HHT's alpha = (1 - rho)/(1 + rho) must stay in [0, 1/3] for unconditional stability.
    msg << "IntegratorOptions.rhoInfinity = " << rhoInfinity << " must be in [0.5, 1] for hht-alpha";
    return fail(msg.str());
  }
  if (!replayTimes.empty()) {
    if (replayTimes.size() < 2 || replayTimes.front() != t0 || replayTimes.back() != t1) {
      return fail("IntegratorOptions.replayTimes must start at t0 and end at t1");
    }
    for (std::size_t i = 1; i < replayTimes.size(); ++i) {
      if (!(replayTimes[i] > replayTimes[i - 1])) {
        msg << "IntegratorOptions.replayTimes[" << i << "] = " << replayTimes[i]
            << " must exceed the previous time";
        return fail(msg.str());
      }
    }
  }
  return true;
}

void IntegratorOptions::validate() const {
  std::string error;
  if (!IsValid(&error)) throw std::invalid_argument(error);
}

std::unique_ptr<Integrator> createIntegrator(const Problem& problem, ConstVectorRef p,
                                             const IntegratorOptions& options) {
  options.validate();
  if (!isRungeKutta(parseIntegratorMethod(options.method))) {
    const auto* secondOrder = dynamic_cast<const SecondOrderProblem*>(&problem);
    if (secondOrder == nullptr) {
      throw std::invalid_argument("IntegratorOptions.method = '" + options.method +
                                  "' needs a second-order " + "problem (SecondOrderProblem); '" +
                                  problem.name() + "' is first-order");
    }
    return std::make_unique<GeneralizedAlphaIntegrator>(*secondOrder, p, options);
  }
  return std::make_unique<RungeKuttaIntegrator>(problem, p, options);
}

void solveTransposedInPlace(const Eigen::PartialPivLU<Matrix>& lu, VectorRef x, VectorRef work) {
  work = x;
  lu.matrixLU().triangularView<Eigen::Upper>().transpose().solveInPlace(work);
  lu.matrixLU().triangularView<Eigen::UnitLower>().transpose().solveInPlace(work);
  x.noalias() = lu.permutationP().transpose() * work;
}

IntegratorMethod checkedMethod(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options) {
  options.validate();
  if (p.size() != problem.parameterSize()) {
    throw std::invalid_argument("parameter vector p has size " + std::to_string(p.size()) + ", problem '" +
                                problem.name() + "' expects " + std::to_string(problem.parameterSize()));
  }
  if (options.adaptive) {
    requireOneTolerancePerState(options.absoluteTolerances, "IntegratorOptions.absoluteTolerances",
                                problem.name(), problem.stateSize(),
                                "one atol per state, or empty for the scalar absoluteTolerance");
  }
  return parseIntegratorMethod(options.method);
}

}  // namespace hindsight
