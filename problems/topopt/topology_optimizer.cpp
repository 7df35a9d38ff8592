#include <hindsight/problems/topopt/topology_optimizer.h>

#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/rod/eigen_constraint.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

std::vector<int> makeDesignToGrid(const rod::RodConfig& rc) {
  const int nx = rc.elementsAlongLength;
  const int ny = rc.elementsThroughHeight;
  std::vector<int> map(static_cast<std::size_t>(rc.designCount()));
  // Design index d = (i - 1) ny + j for element column i, row j (problems/fe_model.h).
  for (int d = 0; d < rc.designCount(); ++d) {
    const int column = d / ny + 1;
    const int row = d % ny;
    map[static_cast<std::size_t>(d)] = row * nx + column;
  }
  return map;
}

std::vector<bool> designMask(const rod::RodConfig& rc, const std::vector<int>& designToGrid) {
  std::vector<bool> mask(static_cast<std::size_t>(rc.elementsAlongLength * rc.elementsThroughHeight), false);
  for (int g : designToGrid) mask[static_cast<std::size_t>(g)] = true;
  return mask;
}

Config validated(const Config& config) {
  config.validate();
  return config;
}

// docs/design.md §7: Svanberg's 2007 constants (the MmaOptions defaults); only the move limit is
// configurable.
MmaOptions mmaOptions(const OptimizationSettings& settings) {
  MmaOptions options;
  options.move_limit = settings.moveLimit;
  return options;
}

// (2 pi f)^2: the eigenvalue bound of the frequency guard.
double eigenvalueBound(double frequencyHz) {
  const double omega = 2.0 * 3.14159265358979323846 * frequencyHz;
  return omega * omega;
}

}  // namespace

TopologyOptimizer::TopologyOptimizer(const Config& config)
    : designToGrid_(makeDesignToGrid(validated(config).rod)),
      rod_(config),
      filter_(config.rod.elementsAlongLength, config.rod.elementsThroughHeight,
              config.optimization.filterRadius, designMask(config.rod, designToGrid_)),
      mma_(config.rod.designCount(), config.optimization.minFirstFrequency > 0.0 ? 2 : 1,
           mmaOptions(config.optimization)) {
  if (config.optimization.method == "gcmma") {
    GcmmaOptions options;
    options.mma = mmaOptions(config.optimization);
    options.accept_descent = true;  // see GcmmaOptions::accept_descent
    gcmma_ = std::make_unique<Gcmma>(config.rod.designCount(), constraintCount(), options);
  }
  state_.design = rod_.initialDesign();
  state_.mma = mma_.state();
}

void TopologyOptimizer::restore(const OptimizerState& state) {
  const int n = designCount();
  if (state.design.size() != n) {
    throw std::invalid_argument("optimizer state: design has " + std::to_string(state.design.size()) +
                                " entries, the configuration has " + std::to_string(n) + " design variables");
  }
  if (state.iteration < 0 || state.iteration > config().optimization.iterations) {
    throw std::invalid_argument(
        "optimizer state: iteration " + std::to_string(state.iteration) +
        " outside [0, optimization.iterations = " + std::to_string(config().optimization.iterations) + "]");
  }
  if (state.iteration > 0 && !(state.objectiveScale > 0.0 && std::isfinite(state.objectiveScale))) {
    throw std::invalid_argument("optimizer state: objective scale " + std::to_string(state.objectiveScale) +
                                " must be positive and finite after the first iteration");
  }
  mma_.restore(state.mma);  // checks the MMA vectors
  state_ = state;
  lastIteration_ = state.iteration;
  finished_ = false;
  last_.reset();
}

Vector TopologyOptimizer::physicalDesign(ConstVectorRef design) const {
  if (filter_.isIdentity()) return design;
  const rod::RodConfig& rc = config().rod;
  Vector grid = Vector::Ones(rc.elementsAlongLength * rc.elementsThroughHeight);
  for (int d = 0; d < designCount(); ++d) grid(designToGrid_[static_cast<std::size_t>(d)]) = design(d);
  Vector filtered(grid.size());
  filter_.apply(grid, filtered);
  Vector out(designCount());
  // A convex combination of values in [xMin, 1]; the clamp only removes rounding.
  for (int d = 0; d < designCount(); ++d) {
    out(d) = std::clamp(filtered(designToGrid_[static_cast<std::size_t>(d)]), rc.designLowerBound, 1.0);
  }
  return out;
}

Vector TopologyOptimizer::chainThroughFilter(ConstVectorRef gradient) const {
  if (filter_.isIdentity()) return gradient;
  const rod::RodConfig& rc = config().rod;
  Vector grid = Vector::Zero(rc.elementsAlongLength * rc.elementsThroughHeight);
  for (int d = 0; d < designCount(); ++d) grid(designToGrid_[static_cast<std::size_t>(d)]) = gradient(d);
  Vector chained(grid.size());
  filter_.applyTranspose(grid, chained);
  Vector out(designCount());
  for (int d = 0; d < designCount(); ++d) out(d) = chained(designToGrid_[static_cast<std::size_t>(d)]);
  return out;
}

int TopologyOptimizer::constraintCount() const {
  return config().optimization.minFirstFrequency > 0.0 ? 2 : 1;
}

std::optional<HeavisideProjection> TopologyOptimizer::projectionAt(int iteration) const {
  const OptimizationSettings& s = config().optimization;
  if (!(s.projectionBeta > 0.0)) return std::nullopt;
  return HeavisideProjection(
      HeavisideProjection::continuationBeta(s.projectionBeta, s.projectionBetaMax, s.projectionEvery, iteration),
      s.projectionThreshold, config().rod.designLowerBound);
}

Vector TopologyOptimizer::modelDesign(ConstVectorRef design, int iteration) const {
  Vector filtered = physicalDesign(design);
  const std::optional<HeavisideProjection> projection = projectionAt(iteration);
  if (!projection) return filtered;
  for (Eigen::Index d = 0; d < filtered.size(); ++d)
    filtered(d) = std::clamp(projection->value(filtered(d)), config().rod.designLowerBound, 1.0);
  return filtered;
}

Vector TopologyOptimizer::chainToDesign(ConstVectorRef gradient, ConstVectorRef design, int iteration) const {
  const std::optional<HeavisideProjection> projection = projectionAt(iteration);
  if (!projection) return chainThroughFilter(gradient);
  const Vector filtered = physicalDesign(design);
  Vector chained = gradient;
  for (Eigen::Index d = 0; d < chained.size(); ++d) chained(d) *= projection->derivative(filtered(d));
  return chainThroughFilter(chained);
}

Vector TopologyOptimizer::constraintsOf(const PistonRodEvaluation& evaluation, ConstVectorRef design,
                                        int iteration, Matrix* jacobian) const {
  const OptimizationSettings& settings = config().optimization;
  Vector constraint(constraintCount());
  constraint(0) = evaluation.volumeFraction / settings.volumeFraction - 1.0;
  if (jacobian != nullptr) {
    *jacobian = Matrix(constraintCount(), designCount());
    jacobian->row(0) = chainToDesign(evaluation.dvolume / settings.volumeFraction, design, iteration).transpose();
  }
  if (settings.minFirstFrequency > 0.0) {
    const double bound = eigenvalueBound(settings.minFirstFrequency);
    const rod::FeModel model(config().rod, modelDesign(design, iteration));
    const rod::FirstEigenvalue first = rod::firstEigenvalue(model, evaluation.eigenvalues, evaluation.modes);
    constraint(1) = 1.0 - first.value / bound;
    if (jacobian != nullptr) jacobian->row(1) = chainToDesign(-first.gradient / bound, design, iteration).transpose();
  }
  return constraint;
}

Vector TopologyOptimizer::densityGrid(ConstVectorRef design) const {
  const rod::RodConfig& rc = config().rod;
  const Vector physical = modelDesign(design, lastIteration_);
  Vector grid = Vector::Ones(rc.elementsAlongLength * rc.elementsThroughHeight);
  for (int d = 0; d < designCount(); ++d) grid(designToGrid_[static_cast<std::size_t>(d)]) = physical(d);
  return grid;
}

IterationRecord TopologyOptimizer::step() {
  if (finished_) throw std::logic_error("TopologyOptimizer::step after the final evaluation");
  const Stopwatch stepTimer;
  const OptimizationSettings& settings = config().optimization;
  const bool usePsi1 = settings.objective == Objective::Psi1;
  const bool update = state_.iteration < settings.iterations;

  PistonRod::Request request;
  request.psi1Gradient = update && usePsi1;
  request.psi2 = true;
  request.psi2Gradient = update && !usePsi1;
  IterationRecord record;
  record.iteration = state_.iteration;
  Vector design = state_.design;
  std::optional<PistonRodEvaluation> evaluated;
  while (!evaluated) {
    try {
      evaluated = rod_.evaluate(modelDesign(design, state_.iteration), request);
      const double value = usePsi1 ? evaluated->psi1 : evaluated->psi2;
      if (state_.iteration > 0 && !(value <= maxObjectiveGrowth * state_.objectiveScale)) {
        throw NumericalError("objective " + toString(settings.objective) + " = " + std::to_string(value) +
                                 " exceeds " + std::to_string(maxObjectiveGrowth) +
                                 " times its initial value",
                             config().rod.endTime);
      }
    } catch (const NumericalError&) {
      if (state_.iteration == 0 || record.backtracks == maxBacktracks) throw;
      evaluated.reset();
      design = 0.5 * (design + state_.mma.xold1);  // halfway back to x_{k-1}
      ++record.backtracks;
    }
  }
  PistonRodEvaluation& evaluation = *evaluated;
  record.psi1 = evaluation.psi1;
  record.psi2 = evaluation.psi2;
  record.volumeFraction = evaluation.volumeFraction;
  record.grayness = grayness(modelDesign(design, state_.iteration));
  if (!evaluation.frequenciesHz.empty()) record.firstFrequencyHz = evaluation.frequenciesHz.front();
  record.evaluationSeconds = stepTimer.seconds();

  const double objective = usePsi1 ? evaluation.psi1 : evaluation.psi2;
  if (!(std::isfinite(objective) && objective > 0.0)) {
    throw NumericalError("objective " + toString(settings.objective) + " = " + std::to_string(objective) +
                             " at iteration " + std::to_string(state_.iteration) +
                             " is not positive and finite",
                         config().rod.endTime);
  }
  OptimizerState next = state_;
  if (next.iteration == 0 && next.objectiveScale == 0.0) next.objectiveScale = objective;

  if (update) {
    const Stopwatch mmaTimer;
    const int n = designCount();
    const Vector gradient =
        chainToDesign(usePsi1 ? evaluation.dpsi1 : evaluation.dpsi2, design, state_.iteration) /
        next.objectiveScale;
    if (!gradient.allFinite()) {
      throw NumericalError("the gradient of " + toString(settings.objective) + " at iteration " +
                               std::to_string(state_.iteration) + " is not finite",
                           config().rod.endTime);
    }
    Matrix jacobian;
    const Vector constraint = constraintsOf(evaluation, design, state_.iteration, &jacobian);
    const Vector lower = Vector::Constant(n, config().rod.designLowerBound);
    const Vector upper = Vector::Ones(n);
    Vector x = design;
    if (gcmma_) {
      // Trials: values only, with the projection of this iteration (the approximations are of this
      // iteration's functions).
      PistonRod::Request trialRequest;
      trialRequest.psi1Gradient = false;
      trialRequest.psi2 = !usePsi1;
      trialRequest.psi2Gradient = false;
      const int iteration = state_.iteration;
      const double scale = next.objectiveScale;
      const Gcmma::Evaluate evaluate = [&](const Vector& trial, double& value, Vector& constraints) {
        try {
          const PistonRodEvaluation e = rod_.evaluate(modelDesign(trial, iteration), trialRequest);
          const double psi = usePsi1 ? e.psi1 : e.psi2;
          if (!(psi <= maxObjectiveGrowth * scale)) return false;  // a diverging response
          value = psi / scale;
          constraints = constraintsOf(e, trial, iteration, nullptr);
          return true;
        } catch (const NumericalError&) {
          return false;  // a diverged simulation: not conservative
        }
      };
      gcmma_->restore(state_.mma);
      gcmma_->update(objective / next.objectiveScale, gradient, constraint, jacobian, lower, upper, x, evaluate);
      record.innerIterations = gcmma_->lastUpdate().inner_iterations;
      next.mma = gcmma_->state();
    } else {
      mma_.restore(state_.mma);
      mma_.update(objective / next.objectiveScale, gradient, constraint, jacobian, lower, upper, x);
      next.mma = mma_.state();
    }
    if (!x.allFinite()) {
      throw NumericalError(
          "the MMA update of iteration " + std::to_string(state_.iteration) + " is not finite",
          config().rod.endTime);
    }
    record.maxDesignChange = (x - design).cwiseAbs().maxCoeff();
    next.design = x;
    next.iteration += 1;
    record.mmaSeconds = mmaTimer.seconds();
  } else {
    finished_ = true;
  }
  lastIteration_ = state_.iteration;
  state_ = std::move(next);
  last_ = std::move(evaluated);
  lastDesign_ = std::move(design);
  record.totalSeconds = stepTimer.seconds();
  return record;
}

}  // namespace hindsight
