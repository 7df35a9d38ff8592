#include <hindsight/problems/topopt/topology_optimizer.h>

#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/rod/eigen_constraint.h>
#include <hindsight/problems/rod/solid_member.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

// The elements of the filter's grid: nx ny of the plate, nx ny nz of the solid.
int gridCount(const rod::RodConfig& rc) {
  return rc.elementsAlongLength * rc.elementsThroughHeight * (rc.isSolid() ? rc.elementsThroughThickness : 1);
}

std::vector<int> makeDesignToGrid(const rod::RodConfig& rc) {
  const int nx = rc.elementsAlongLength;
  const int ny = rc.elementsThroughHeight;
  std::vector<int> map(static_cast<std::size_t>(rc.designCount()));
  if (rc.isSolid()) {
    // The solid's grid is its element order (i ny + j) nz + k, the design index ((i - 1) ny + j) nz + k
    // (problems/rod/solid_model.h): one column of ny nz elements apart.
    for (int d = 0; d < rc.designCount(); ++d)
      map[static_cast<std::size_t>(d)] = d + ny * rc.elementsThroughThickness;
    return map;
  }
  // Design index d = (i - 1) ny + j for element column i, row j (problems/rod/fe_model.h).
  for (int d = 0; d < rc.designCount(); ++d) {
    const int column = d / ny + 1;
    const int row = d % ny;
    map[static_cast<std::size_t>(d)] = row * nx + column;
  }
  return map;
}

std::vector<bool> designMask(const rod::RodConfig& rc, const std::vector<int>& designToGrid) {
  std::vector<bool> mask(static_cast<std::size_t>(gridCount(rc)), false);
  for (int g : designToGrid) mask[static_cast<std::size_t>(g)] = true;
  return mask;
}

Config validated(const Config& config) {
  config.validate();
  return config;
}

// docs/design.md §7: Svanberg's 2007 constants (the MmaOptions defaults); the move limit and the
// asymptotes' smallest distance are configurable.
MmaOptions mmaOptions(const OptimizationSettings& settings) {
  MmaOptions options;
  options.move_limit = settings.moveLimit;
  options.min_asymptote_distance = settings.minAsymptoteDistance;
  options.adaptive_move_limit = settings.method == "mma-adaptive";
  options.min_move_limit = std::min(options.min_move_limit, settings.moveLimit);
  return options;
}

// (2 pi f)^2: the eigenvalue bound of the frequency guard.
double eigenvalueBound(double frequencyHz) {
  const double omega = 2.0 * 3.14159265358979323846 * frequencyHz;
  return omega * omega;
}

}  // namespace

TopologyOptimizer::TopologyOptimizer(const Config& config, const Communicator& communicator)
    : designToGrid_(makeDesignToGrid(validated(config).rod)),
      config_(config),
      scenarios_(config, communicator),
      multiple_(!config.scenarios.empty()),
      bound_(multiple_ && config.optimization.aggregate == Aggregate::Max),
      filter_(config.rod.elementsAlongLength, config.rod.elementsThroughHeight,
              config.rod.isSolid() ? 0.0 : config.optimization.filterRadius,
              config.rod.isSolid() ? std::vector<bool>() : designMask(config.rod, designToGrid_)),
      // The bound formulation: one more variable (z) and one constraint per scenario; the frequency
      // guard adds one constraint (constraintCount()).
      mma_(config.rod.designCount() + (bound_ ? 1 : 0), constraintCount() + (bound_ ? scenarios_.count() : 0),
           mmaOptions(config.optimization)) {
  const OptimizationSettings& settings = config.optimization;
  if (settings.method == "gcmma" && !multiple_ && communicator.size() > 1) {
    // Without scenarios a run has one rank's work; GCMMA's trials would be simulated by every rank.
    throw std::invalid_argument(
        "optimization.method = gcmma under mpirun needs scenarios (the ranks share "
        "their evaluations); without them run one process");
  }
  if (settings.minFirstFrequency > 0.0 && communicator.size() > scenarios_.count()) {
    // The eigenvalue constraint depends on the design only (a scenario changes the mechanism, not the
    // rod), so every rank computes it from the full evaluation of a scenario it owns: it needs one.
    throw std::invalid_argument(
        "optimization.minFirstFrequency > 0 needs every MPI rank to own a scenario: " +
        std::to_string(communicator.size()) + " ranks for " + std::to_string(scenarios_.count()) +
        " scenario(s); run with at most " + std::to_string(scenarios_.count()) + " ranks");
  }
  if (settings.method == "gcmma") {
    GcmmaOptions options;
    options.mma = mmaOptions(settings);
    options.accept_descent = true;  // see GcmmaOptions::accept_descent
    // With scenarios the trials evaluate every scenario (collectively over the ranks) and the problem is
    // that of MMA's (the bound formulation: z and one constraint per scenario more).
    gcmma_ = std::make_unique<Gcmma>(config.rod.designCount() + (bound_ ? 1 : 0),
                                     constraintCount() + (bound_ ? scenarios_.count() : 0), options);
  }
  // optimization.filterRadius = 0 means no filter; the 3-D filter's rule would give every element a
  // weight of zero there, so it is made only for a positive radius (filter_ is the identity then).
  if (config.rod.isSolid() && config.optimization.filterRadius > 0.0) {
    const rod::SolidModel geometry(config.rod, rod::solidMeshOptions(config.rod),
                                   Vector::Constant(config.rod.designCount(), 1.0));
    DensityFilter3d::Grid grid;
    grid.elementsAlongLength = config.rod.elementsAlongLength;
    grid.elementsThroughHeight = config.rod.elementsThroughHeight;
    grid.elementsThroughThickness = config.rod.elementsThroughThickness;
    grid.elementWidthX = geometry.elementWidthX();
    grid.elementWidthY = geometry.elementWidthY();
    grid.elementWidthZ = geometry.elementWidthZ();
    grid.midPlaneSymmetry = config.rod.midPlaneSymmetry;
    filter3d_ = std::make_unique<DensityFilter3d>(grid, config.optimization.filterRadius,
                                                  designMask(config.rod, designToGrid_));
  }
  state_.design = scenarios_.rod(0).initialDesign();
  state_.mma = mma_.state();
  if (bound_) {
    // The design variables' part of the MMA state lives in state_.mma, z's in state_.bound.
    const int n = designCount();
    state_.bound = Vector::Zero(4);
    for (Vector* v : {&state_.mma.xold1, &state_.mma.xold2, &state_.mma.low, &state_.mma.upp})
      *v = Vector(v->head(n));
  }
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
  if (multiple_ && state.iteration > 0 && state.scenarioScales.size() != scenarios_.count()) {
    throw std::invalid_argument("optimizer state: " + std::to_string(state.scenarioScales.size()) +
                                " scenario scales, the configuration has " +
                                std::to_string(scenarios_.count()) + " scenarios");
  }
  if (bound_ != (state.bound.size() == 4)) {
    throw std::invalid_argument("optimizer state: the bound variable's MMA state has " +
                                std::to_string(state.bound.size()) + " entries, expected " +
                                std::string(bound_ ? "4 (aggregate max)" : "0"));
  }
  mma_.restore(fullMmaState(state));  // checks the MMA vectors
  state_ = state;
  lastIteration_ = state.iteration;
  finished_ = false;
  last_.reset();
}

MmaState TopologyOptimizer::fullMmaState(const OptimizerState& state) const {
  if (!bound_) return state.mma;
  MmaState full = state.mma;
  const Vector* parts[] = {&state.mma.xold1, &state.mma.xold2, &state.mma.low, &state.mma.upp};
  Vector* out[] = {&full.xold1, &full.xold2, &full.low, &full.upp};
  for (int k = 0; k < 4; ++k) {
    out[k]->resize(parts[k]->size() + 1);
    *out[k] << *parts[k], state.bound(k);
  }
  return full;
}

Vector TopologyOptimizer::physicalDesign(ConstVectorRef design) const {
  if (filter3d_ ? filter3d_->isIdentity() : filter_.isIdentity()) return design;
  const rod::RodConfig& rc = config().rod;
  Vector grid = Vector::Ones(gridCount(rc));
  for (int d = 0; d < designCount(); ++d) grid(designToGrid_[static_cast<std::size_t>(d)]) = design(d);
  Vector filtered(grid.size());
  if (filter3d_)
    filter3d_->apply(grid, filtered);
  else
    filter_.apply(grid, filtered);
  Vector out(designCount());
  // A convex combination of values in [xMin, 1]; the clamp only removes rounding.
  for (int d = 0; d < designCount(); ++d) {
    out(d) = std::clamp(filtered(designToGrid_[static_cast<std::size_t>(d)]), rc.designLowerBound, 1.0);
  }
  return out;
}

Vector TopologyOptimizer::chainThroughFilter(ConstVectorRef gradient) const {
  if (filter3d_ ? filter3d_->isIdentity() : filter_.isIdentity()) return gradient;
  const rod::RodConfig& rc = config().rod;
  Vector grid = Vector::Zero(gridCount(rc));
  for (int d = 0; d < designCount(); ++d) grid(designToGrid_[static_cast<std::size_t>(d)]) = gradient(d);
  Vector chained(grid.size());
  if (filter3d_)
    filter3d_->applyTranspose(grid, chained);
  else
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
  return HeavisideProjection(HeavisideProjection::continuationBeta(s.projectionBeta, s.projectionBetaMax,
                                                                   s.projectionEvery, iteration),
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

Vector TopologyOptimizer::constraintsOf(double volumeFraction, ConstVectorRef dvolume,
                                        const PistonRodEvaluation* evaluation, ConstVectorRef design,
                                        int iteration, Matrix* jacobian) const {
  const OptimizationSettings& settings = config().optimization;
  Vector constraint(constraintCount());
  constraint(0) = volumeFraction / settings.volumeFraction - 1.0;
  if (jacobian != nullptr) {
    *jacobian = Matrix(constraintCount(), designCount());
    jacobian->row(0) = chainToDesign(dvolume / settings.volumeFraction, design, iteration).transpose();
  }
  if (settings.minFirstFrequency > 0.0) {
    if (evaluation == nullptr) throw std::logic_error("the frequency guard needs the full evaluation");
    const double bound = eigenvalueBound(settings.minFirstFrequency);
    const Vector physical = modelDesign(design, iteration);
    const rod::FirstEigenvalue first = config().rod.isSolid()
                                           ? rod::firstEigenvalue(rod::SolidMember(config().rod, physical),
                                                                  evaluation->eigenvalues, evaluation->modes)
                                           : rod::firstEigenvalue(rod::FeModel(config().rod, physical),
                                                                  evaluation->eigenvalues, evaluation->modes);
    constraint(1) = 1.0 - first.value / bound;
    if (jacobian != nullptr)
      jacobian->row(1) = chainToDesign(-first.gradient / bound, design, iteration).transpose();
  }
  return constraint;
}

Vector TopologyOptimizer::recordConstraints(const IterationRecord& record,
                                            const OptimizationSettings& settings) {
  Vector constraint(settings.minFirstFrequency > 0.0 ? 2 : 1);
  constraint(0) = record.volumeFraction / settings.volumeFraction - 1.0;
  if (settings.minFirstFrequency > 0.0) {
    const double ratio = record.firstFrequencyHz / settings.minFirstFrequency;
    constraint(1) = std::isnan(ratio) ? std::numeric_limits<double>::infinity() : 1.0 - ratio * ratio;
  }
  return constraint;
}

Vector TopologyOptimizer::densityGrid(ConstVectorRef design) const {
  const rod::RodConfig& rc = config().rod;
  const int nx = rc.elementsAlongLength, ny = rc.elementsThroughHeight;
  if (rc.isSolid()) {
    // The picture of the solid: each (column, row)'s mean over the layers, on the plate's grid.
    const int nz = rc.elementsThroughThickness;
    const Vector solid = solidDensities(design, lastIteration_);
    Vector grid(nx * ny);
    for (int i = 0; i < nx; ++i) {
      for (int j = 0; j < ny; ++j) grid(j * nx + i) = solid.segment((i * ny + j) * nz, nz).mean();
    }
    return grid;
  }
  const Vector physical = modelDesign(design, lastIteration_);
  Vector grid = Vector::Ones(nx * ny);
  for (int d = 0; d < designCount(); ++d) grid(designToGrid_[static_cast<std::size_t>(d)]) = physical(d);
  return grid;
}

Vector TopologyOptimizer::solidDensities(ConstVectorRef design, int iteration) const {
  const rod::RodConfig& rc = config().rod;
  if (!rc.isSolid()) throw std::logic_error("TopologyOptimizer::solidDensities: the member is the plate");
  const Vector physical = modelDesign(design, iteration);
  Vector densities = Vector::Ones(gridCount(rc));
  for (int d = 0; d < designCount(); ++d) densities(designToGrid_[static_cast<std::size_t>(d)]) = physical(d);
  return densities;
}

BoxDensityField TopologyOptimizer::solidField(ConstVectorRef design, int iteration) const {
  const rod::RodConfig& rc = config().rod;
  BoxDensityField field;
  field.nx = rc.elementsAlongLength;
  field.ny = rc.elementsThroughHeight;
  field.nz = rc.elementsThroughThickness;
  field.midPlaneSymmetry = rc.midPlaneSymmetry;
  field.values = solidDensities(design, iteration);
  field.cellWidthMm = 1000.0 * rc.length / field.nx;
  field.cellHeightMm = 1000.0 * rc.height / field.ny;
  field.cellDepthMm = 1000.0 * rc.thickness / field.layers();
  return field;
}

IterationRecord TopologyOptimizer::step() {
  if (finished_) throw std::logic_error("TopologyOptimizer::step after the final evaluation");
  const Stopwatch stepTimer;
  const OptimizationSettings& settings = config().optimization;
  const bool usePsi1 = settings.objective == Objective::Psi1;
  const bool update = state_.iteration < settings.iterations;
  const int scenarioCount = scenarios_.count();

  PistonRod::Request request;
  request.psi1Gradient = update && usePsi1;
  request.psi2 = true;
  request.psi2Gradient = update && !usePsi1;
  IterationRecord record;
  record.iteration = state_.iteration;
  Vector design = designToEvaluate(state_);
  std::optional<ScenarioResults> evaluated;
  while (!evaluated) {
    try {
      // Collective over the ranks: every rank gets every scenario's results or the same exception.
      evaluated = scenarios_.evaluate(modelDesign(design, state_.iteration), request, usePsi1);
      for (int s = 0; s < scenarioCount; ++s) {
        const double value = usePsi1 ? evaluated->psi1[s] : evaluated->psi2[s];
        const double scale = state_.iteration > 0 ? scenarioScale(state_, s) : 0.0;
        if (state_.iteration > 0 && !(value <= maxObjectiveGrowth * scale)) {
          throw NumericalError((multiple_ ? "scenario '" + scenarios_.name(s) + "': " : std::string()) +
                                   "objective " + toString(settings.objective) + " = " +
                                   std::to_string(value) + " exceeds " + std::to_string(maxObjectiveGrowth) +
                                   " times its initial value",
                               scenarios_.rod(s).config().rod.endTime);
        }
      }
    } catch (const NumericalError&) {
      if (state_.iteration == 0 || record.backtracks == maxBacktracks) throw;
      evaluated.reset();
      design = 0.5 * (design + state_.mma.xold1);  // halfway back to x_{k-1}
      ++record.backtracks;
    }
  }
  ScenarioResults& evaluation = *evaluated;
  times_.localSeconds += evaluation.localSeconds;
  times_.exchangeSeconds += evaluation.exchangeSeconds;
  times_.smallestExchangeSeconds = times_.exchanges == 0
                                       ? evaluation.exchangeSeconds
                                       : std::min(times_.smallestExchangeSeconds, evaluation.exchangeSeconds);
  ++times_.exchanges;
  record.volumeFraction = evaluation.volumeFraction;
  record.grayness = grayness(modelDesign(design, state_.iteration));
  if (evaluation.local && !evaluation.local->frequenciesHz.empty())
    record.firstFrequencyHz = evaluation.local->frequenciesHz.front();
  record.evaluationSeconds = stepTimer.seconds();

  for (int s = 0; s < scenarioCount; ++s) {
    const double objective = usePsi1 ? evaluation.psi1[s] : evaluation.psi2[s];
    if (!(std::isfinite(objective) && objective > 0.0)) {
      throw NumericalError((multiple_ ? "scenario '" + scenarios_.name(s) + "': " : std::string()) +
                               "objective " + toString(settings.objective) + " = " +
                               std::to_string(objective) + " at iteration " +
                               std::to_string(state_.iteration) + " is not positive and finite",
                           scenarios_.rod(s).config().rod.endTime);
    }
  }
  OptimizerState next = state_;
  settled_ = false;
  // One path: a run without a scenarios list is the list of its one configuration, weight 1.
  updateFromScenarios(evaluation, next, design, record);
  if (update && settled_) {
    // The stopping rule holds at x_k: x_k is the final design (this record its final evaluation), the
    // update to x_{k+1} is discarded, and the state stays that of x_k (the scales found at x0 kept).
    const Vector objectiveScales = next.scenarioScales;
    const double objectiveScale = next.objectiveScale;
    next = state_;
    next.design = design;
    next.objectiveScale = objectiveScale;
    next.scenarioScales = objectiveScales;
    record.converged = true;
    finished_ = true;
  }
  if (!update) finished_ = true;
  lastIteration_ = state_.iteration;
  state_ = std::move(next);
  last_ = std::move(evaluation.local);
  lastDesign_ = std::move(design);
  record.totalSeconds = stepTimer.seconds();
  return record;
}

Vector TopologyOptimizer::designToEvaluate(const OptimizerState& state) const {
  // The final evaluation of a run that reached the iteration cap is that of its best feasible design
  // (the class comment); without projection the model of x_k* is the one it was evaluated with.
  const OptimizationSettings& settings = config().optimization;
  const bool toBest = stoppingRuleOn() && state.iteration >= settings.iterations &&
                      state.bestDesign.size() > 0 && settings.projectionBeta == 0.0;
  return toBest ? state.bestDesign : state.design;
}

bool TopologyOptimizer::stoppingRuleOn() const {
  return config().optimization.kktTolerance > 0.0 && config().optimization.changeTolerance > 0.0;
}

bool TopologyOptimizer::stagnated(const std::vector<double>& recent) const {
  const double tolerance = config().optimization.objectiveTolerance;
  if (!(tolerance > 0.0) || recent.size() != OptimizerState::kObjectiveWindow) return false;
  const auto [smallest, largest] = std::minmax_element(recent.begin(), recent.end());
  return *largest - *smallest <= tolerance * *smallest;
}

bool TopologyOptimizer::endGameOn() const {
  // The refinement ends when the move limit reaches changeTolerance, which it can only do above MMA's
  // smallest limit.
  return config().optimization.endGame && stoppingRuleOn() && !bound_ && !gcmma_ &&
         mma_.options().adaptive_move_limit &&
         config().optimization.changeTolerance >= mma_.options().min_move_limit;
}

int TopologyOptimizer::endGameReserve() const {
  const OptimizationSettings& settings = config().optimization;
  const double halvings = std::ceil(std::log2(settings.moveLimit / settings.changeTolerance));
  return 2 * static_cast<int>(std::max(halvings, 0.0)) + 1;
}

double TopologyOptimizer::scenarioScale(const OptimizerState& state, int s) const {
  return multiple_ ? state.scenarioScales(s) : state.objectiveScale;
}

void TopologyOptimizer::updateFromScenarios(const ScenarioResults& evaluation, OptimizerState& next,
                                            const Vector& design, IterationRecord& record) {
  const OptimizationSettings& settings = config().optimization;
  const bool usePsi1 = settings.objective == Objective::Psi1;
  const bool update = state_.iteration < settings.iterations;
  const int count = scenarios_.count();
  const std::vector<double>& values = usePsi1 ? evaluation.psi1 : evaluation.psi2;
  if (next.iteration == 0 && multiple_ && next.scenarioScales.size() == 0) {
    next.scenarioScales = Eigen::Map<const Vector>(values.data(), count);
    double aggregate = 0.0;
    for (int s = 0; s < count; ++s) {
      aggregate = settings.aggregate == Aggregate::Max ? std::max(aggregate, scenarios_.weight(s))
                                                       : aggregate + scenarios_.weight(s);
    }
    next.objectiveScale = aggregate;
  }
  // Without a scenarios list the state keeps psi(x0) itself as the scale (the results file's
  // objective_scale, and no /scenarios group).
  if (next.iteration == 0 && !multiple_ && next.objectiveScale == 0.0) next.objectiveScale = values[0];
  // f_s = w_s psi_s / psi_s(x0), every sum in scenario order (the same bits for any rank count).
  Vector relative(count);
  for (int s = 0; s < count; ++s) relative(s) = scenarios_.weight(s) * values[s] / scenarioScale(next, s);
  int worst = 0;
  for (int s = 1; s < count; ++s) {
    if (relative(s) > relative(worst)) worst = s;
  }
  if (multiple_) {
    record.scenarioPsi1 = evaluation.psi1;
    record.scenarioPsi2 = evaluation.psi2;
    record.worstScenario = worst;
  }
  record.psi1 = evaluation.psi1[worst];
  record.psi2 = evaluation.psi2[worst];
  if (!update) return;

  // The aggregate the update minimizes (sum, or max, of the relative objectives, in scenario order from
  // the first term: not from zero, which could flip the sign of a zero); the stagnation window's entry.
  double aggregate = relative(0);
  for (int s = 1; s < count; ++s)
    aggregate = bound_ ? std::max(aggregate, relative(s)) : aggregate + relative(s);
  next.recentObjectives.push_back(aggregate);
  if (next.recentObjectives.size() > OptimizerState::kObjectiveWindow)
    next.recentObjectives.erase(next.recentObjectives.begin());

  const Stopwatch mmaTimer;
  const int n = designCount();
  std::vector<Vector> gradients(static_cast<std::size_t>(count));
  for (int s = 0; s < count; ++s) {
    // d f_s / dx = chain(d psi_s / dp) / (psi_s(x0) / w_s): with one scenario (w = 1) the division by
    // psi(x0) of the paper's normalisation, bit for bit.
    gradients[s] = chainToDesign(evaluation.gradient[s], design, state_.iteration) /
                   (scenarioScale(next, s) / scenarios_.weight(s));
    if (!gradients[s].allFinite()) {
      throw NumericalError((multiple_ ? "scenario '" + scenarios_.name(s) + "': " : std::string()) +
                               "the gradient of " + toString(settings.objective) + " at iteration " +
                               std::to_string(state_.iteration) + " is not finite",
                           scenarios_.rod(s).config().rod.endTime);
    }
  }
  // The design's constraints (volume; the frequency guard when on, from this rank's full evaluation of a
  // scenario it owns: the eigenpairs are the design's, the same in every scenario and on every rank).
  Matrix ownJacobian;
  const Vector own =
      constraintsOf(evaluation.volumeFraction, evaluation.dvolume,
                    evaluation.local ? &*evaluation.local : nullptr, design, state_.iteration, &ownJacobian);
  const Eigen::Index owned = own.size();
  // NaN (no feasible design yet) is no better than this one.
  const bool bestSoFar = !(next.bestObjective < aggregate);
  bool returnToBest = false;
  if (feasible(own) && bestSoFar) {
    next.bestObjective = aggregate;
    next.bestDesign = design;
  }
  Vector x;
  if (!bound_) {
    Vector gradient = gradients[0];
    for (int s = 1; s < count; ++s) gradient += gradients[s];
    const Vector& constraint = own;
    const Matrix& jacobian = ownJacobian;
    x = design;
    const Vector lower = Vector::Constant(n, config().rod.designLowerBound), upper = Vector::Ones(n);
    const Gcmma::Evaluate trials = gcmma_ ? scenarioTrials(next) : Gcmma::Evaluate();
    updateDesign(state_.mma, aggregate, gradient, constraint, jacobian, lower, upper,
                 gcmma_ ? &trials : nullptr, next.recentObjectives, bestSoFar, x, record);
    // The end game (the header comment): after an update the rule did not end the run with.
    if (endGameOn() && !settled_ &&
        (next.refining || (state_.iteration >= endGameReserve() &&
                           state_.iteration + endGameReserve() >= settings.iterations))) {
      next.refining = true;
      if ((feasible(constraint) && bestSoFar) || next.bestDesign.size() == 0) {
        // Refine from x_k (the best design, or no design has been feasible yet): the same update in a
        // trust region that only contracts (MMA halves its limit after an update it is told raised the
        // objective).
        MmaState contracting = state_.mma;
        contracting.objective = -std::numeric_limits<double>::max();
        x = design;
        updateDesign(contracting, aggregate, gradient, constraint, jacobian, lower, upper, nullptr,
                     next.recentObjectives, bestSoFar, x, record);
      } else {
        returnToBest = true;
        x = next.bestDesign;
      }
    }
  } else {
    // minimize z subject to V/V0 / vf - 1 <= 0 and f_s(x) - z <= 0: z is variable n, started at the
    // current worst value (the tightest feasible bound), within [0, maxObjectiveGrowth max_s w_s]
    // (the divergence guard keeps every f_s below that).
    double largestWeight = 0.0;
    for (int s = 0; s < count; ++s) largestWeight = std::max(largestWeight, scenarios_.weight(s));
    Vector lower = Vector::Constant(n + 1, config().rod.designLowerBound);
    Vector upper = Vector::Ones(n + 1);
    lower(n) = 0.0;
    upper(n) = maxObjectiveGrowth * largestWeight;
    x.resize(n + 1);
    x << design, std::min(relative(worst), upper(n));
    Vector objectiveGradient = Vector::Zero(n + 1);
    objectiveGradient(n) = 1.0;
    Vector constraints(owned + count);
    Matrix jacobian = Matrix::Zero(owned + count, n + 1);
    constraints.head(owned) = own;
    jacobian.topLeftCorner(owned, n) = ownJacobian;
    for (int s = 0; s < count; ++s) {
      constraints(owned + s) = relative(s) - x(n);
      jacobian.row(owned + s).head(n) = gradients[s].transpose();
      jacobian(owned + s, n) = -1.0;
    }
    const Gcmma::Evaluate trials = gcmma_ ? scenarioTrials(next) : Gcmma::Evaluate();
    updateDesign(fullMmaState(state_), x(n), objectiveGradient, constraints, jacobian, lower, upper,
                 gcmma_ ? &trials : nullptr, next.recentObjectives, bestSoFar, x, record);
  }
  if (!x.allFinite()) {
    throw NumericalError("the MMA update of iteration " + std::to_string(state_.iteration) + " is not finite",
                         config().rod.endTime);
  }
  record.maxDesignChange = (x.head(n) - design).cwiseAbs().maxCoeff();
  next.design = x.head(n);
  const MmaState& full = gcmma_ ? gcmma_->state() : mma_.state();
  next.mma = full;
  if (returnToBest) {
    // MMA restarted at the best design: no history there (xold1 = xold2 = x, so the next update keeps
    // the asymptotes where they are set here, at the first iterations' distance), the move limit of the
    // update that was not taken, halved by the next update.
    const double distance = mma_.options().initial_asymptote_distance * (1.0 - config().rod.designLowerBound);
    next.mma = state_.mma;
    next.mma.iteration = full.iteration;
    next.mma.xold1 = next.mma.xold2 = next.design;
    next.mma.low = next.design.array() - distance;
    next.mma.upp = next.design.array() + distance;
    next.mma.objective = -std::numeric_limits<double>::max();
  }
  if (bound_) {
    next.bound = Vector(4);
    const Vector* parts[] = {&full.xold1, &full.xold2, &full.low, &full.upp};
    Vector* out[] = {&next.mma.xold1, &next.mma.xold2, &next.mma.low, &next.mma.upp};
    for (int k = 0; k < 4; ++k) {
      next.bound(k) = (*parts[k])(n);
      *out[k] = Vector(parts[k]->head(n));
    }
  }
  next.iteration += 1;
  record.mmaSeconds = mmaTimer.seconds();
}

MmaState TopologyOptimizer::updateDesign(const MmaState& from, double objective,
                                         const Vector& objectiveGradient, const Vector& constraints,
                                         const Matrix& jacobian, const Vector& lower, const Vector& upper,
                                         const Gcmma::Evaluate* trials, const std::vector<double>& recent,
                                         bool bestSoFar, Vector& x, IterationRecord& record) {
  const Vector current = x;
  const MmaSubproblemSummary* subproblem;
  MmaState to;
  if (trials != nullptr) {
    gcmma_->restore(from);
    gcmma_->update(objective, objectiveGradient, constraints, jacobian, lower, upper, x, *trials);
    record.innerIterations = gcmma_->lastUpdate().inner_iterations;
    subproblem = &gcmma_->lastSubproblem();
    to = gcmma_->state();
  } else {
    mma_.restore(from);
    mma_.update(objective, objectiveGradient, constraints, jacobian, lower, upper, x);
    subproblem = &mma_.lastSubproblem();
    to = mma_.state();
  }
  // The subproblem's multipliers estimate those of the problem at the current design (exact at a
  // fixed point, where the approximations' gradients equal the functions').
  record.kktResidual =
      kktResidual(current, objectiveGradient, constraints, jacobian, subproblem->lambda, lower, upper);
  // The stopping rule (see the header): small residual and step, at a feasible design that did not
  // raise the objective (the rule must not end the run on a resonance spike that the step leaves).
  const OptimizationSettings& settings = config().optimization;
  const Eigen::Index n = designCount();
  const bool feasible = TopologyOptimizer::feasible(constraints);
  const bool stationary =
      record.kktResidual <= settings.kktTolerance &&
      ((x.head(n) - current.head(n)).cwiseAbs().maxCoeff() <= settings.changeTolerance || stagnated(recent));
  // With the adaptive move limit (a trust region, problems/topopt/mma.h), a limit that had to shrink
  // below changeTolerance says that no step of that size lowers the objective any more: the trust-region
  // methods' stopping test. On an objective with narrow resonance peaks this is the test that ends the
  // run; the residual stalls above any useful tolerance there (docs/guides/optimizer.md).
  const bool collapsed =
      trials == nullptr && mma_.options().adaptive_move_limit && to.moveLimit <= settings.changeTolerance;
  settled_ = stoppingRuleOn() && feasible && bestSoFar && (stationary || collapsed);
  return to;
}

Gcmma::Evaluate TopologyOptimizer::scenarioTrials(const OptimizerState& next) const {
  // GCMMA's trial points (x, or (x, z) for the bound formulation): every scenario evaluated at x without
  // gradients, collectively over the ranks (every rank gets the same values or the same failure, so
  // every rank's GCMMA takes the same path); the functions of MMA's problem from them.
  return [this, &next](const Vector& trial, double& value, Vector& constraints) {
    const OptimizationSettings& settings = config().optimization;
    const bool usePsi1 = settings.objective == Objective::Psi1;
    const int n = designCount(), count = scenarios_.count();
    PistonRod::Request request;
    request.psi1Gradient = false;
    request.psi2 = !usePsi1;
    request.psi2Gradient = false;
    const Vector design = trial.head(n);
    try {
      const ScenarioResults r = scenarios_.evaluate(modelDesign(design, state_.iteration), request, usePsi1);
      Vector relative(count);
      for (int s = 0; s < count; ++s) {
        const double psi = usePsi1 ? r.psi1[s] : r.psi2[s];
        if (!(psi <= maxObjectiveGrowth * scenarioScale(next, s))) return false;  // a diverging response
        relative(s) = scenarios_.weight(s) * psi / scenarioScale(next, s);
      }
      const Vector own = constraintsOf(r.volumeFraction, r.dvolume, r.local ? &*r.local : nullptr, design,
                                       state_.iteration, nullptr);
      const Eigen::Index owned = own.size();  // volume, and the frequency guard when on
      constraints.resize(owned + (bound_ ? count : 0));
      constraints.head(owned) = own;
      if (bound_) {
        value = trial(n);
        for (int s = 0; s < count; ++s) constraints(owned + s) = relative(s) - trial(n);
      } else {
        value = 0.0;
        value = relative(0);
        for (int s = 1; s < count; ++s) value += relative(s);  // scenario order, as the MMA step's sum
      }
      return true;
    } catch (const NumericalError&) {
      return false;  // a diverged simulation (in any scenario, on every rank alike): not conservative
    }
  };
}

}  // namespace hindsight
