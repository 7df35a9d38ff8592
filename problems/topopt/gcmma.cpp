#include <hindsight/problems/topopt/gcmma.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace {

bool Fail(std::string* error, const std::string& field, double value, const char* range) {
  if (error != nullptr) {
    std::ostringstream out;
    out << "GcmmaOptions::" << field << " = " << value << " must be " << range;
    *error = out.str();
  }
  return false;
}

// Growth of rho_i after a non-conservative trial (Svanberg 2007): 1.1 (rho + delta), at most 10 rho.
constexpr double kDeltaFactor = 1.1;
constexpr double kMaxGrowth = 10.0;

}  // namespace

bool GcmmaOptions::IsValid(std::string* error) const {
  if (!mma.IsValid(error)) return false;
  if (!(max_inner_iterations >= 1)) return Fail(error, "max_inner_iterations", max_inner_iterations, ">= 1");
  if (!(initial_regularization_factor > 0.0 && std::isfinite(initial_regularization_factor)))
    return Fail(error, "initial_regularization_factor", initial_regularization_factor, "> 0 and finite");
  if (!(min_regularization > 0.0 && std::isfinite(min_regularization)))
    return Fail(error, "min_regularization", min_regularization, "> 0 and finite");
  if (!(conservative_tolerance >= 0.0 && std::isfinite(conservative_tolerance)))
    return Fail(error, "conservative_tolerance", conservative_tolerance, ">= 0 and finite");
  return true;
}

namespace {
const GcmmaOptions& validated(const GcmmaOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("Gcmma: options invalid: " + error);
  return options;
}
}  // namespace

Gcmma::Gcmma(int n, int m, const GcmmaOptions& options)
    : n_(n), m_(m), options_(validated(options)), mma_(n, m, options.mma) {}

void Gcmma::update(double objective, ConstVectorRef objective_gradient, ConstVectorRef constraints,
                   ConstMatrixRef constraint_jacobian, ConstVectorRef xmin, ConstVectorRef xmax, Vector& x,
                   const Evaluate& evaluate) {
  const MmaState before = mma_.state();
  mma_.beginConservativeIteration(objective, objective_gradient, constraints, constraint_jacobian, xmin, xmax,
                                  x);
  const double tolerance = options_.conservative_tolerance;
  const bool feasible = m_ == 0 || constraints.maxCoeff() <= 0.0;

  // rho_i at the start of the outer iteration: a tenth of the mean first-order change over the box.
  Vector rho(m_ + 1);
  for (int i = 0; i <= m_; ++i) {
    double sum = 0.0;
    for (int j = 0; j < n_; ++j) {
      const double g = i == 0 ? objective_gradient(j) : constraint_jacobian(i - 1, j);
      sum += std::abs(g) * (xmax(j) - xmin(j));
    }
    rho(i) = std::max(options_.initial_regularization_factor * sum / n_, options_.min_regularization);
  }

  summary_ = Summary{};
  Vector trial(n_);
  Vector trialConstraints(m_);
  try {
    for (int inner = 0; inner < options_.max_inner_iterations; ++inner) {
      mma_.solveConservativeSubproblem(objective_gradient, constraints, constraint_jacobian, xmin, xmax, x,
                                       rho, trial);
      ++summary_.inner_iterations;
      double trialObjective = 0.0;
      trialConstraints.setZero();
      const bool evaluated = evaluate(trial, trialObjective, trialConstraints) &&
                             std::isfinite(trialObjective) && trialConstraints.allFinite();
      if (!evaluated) {
        ++summary_.failed_evaluations;
        rho *= kMaxGrowth;
        continue;
      }
      const double distance = mma_.conservativeDistance(x, trial, xmin, xmax);
      bool conservative = true;
      bool feasibleDescent = trialObjective < objective;  // descent acceptance (accept_descent)
      Vector grown = rho;
      for (int i = 0; i <= m_; ++i) {
        const double value = i == 0 ? objective : constraints(i - 1);
        const double trialValue = i == 0 ? trialObjective : trialConstraints(i - 1);
        const double approximation = value + mma_.approximationChange(i, x, trial);
        if (approximation + tolerance >= trialValue) continue;
        conservative = false;
        if (i > 0 && trialValue > 0.0) feasibleDescent = false;
        const double delta = distance > 0.0 ? (trialValue - approximation) / distance : rho(i);
        grown(i) = std::min(kDeltaFactor * (rho(i) + delta), kMaxGrowth * rho(i));
      }
      if (conservative && feasible && trialObjective > objective) {
        // Declared addition: no increase of the objective from a feasible design.
        conservative = false;
        grown(0) = 2.0 * rho(0);
      }
      if (!conservative && options_.accept_descent && feasibleDescent) conservative = true;
      if (conservative) {
        summary_.accepted = true;
        break;
      }
      rho = grown;
    }
  } catch (...) {
    mma_.restore(before);
    throw;
  }
  summary_.regularization = rho;
  mma_.finishConservativeIteration(x);
  if (summary_.accepted) x = trial;
}

}  // namespace hindsight
