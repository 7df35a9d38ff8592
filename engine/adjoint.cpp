#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/grid_recomputer.h>
#include <hindsight/engine/interrupt.h>
#include <hindsight/engine/step_controller.h>
#include <hindsight/engine/stopwatch.h>

#include <cmath>
#include <ostream>
#include <sstream>

namespace hindsight {
namespace {

/// The fixed-step grid: N equal steps, t_N = t1 exactly.
std::vector<double> fixedGrid(const IntegratorOptions& options) {
  const double span = options.t1 - options.t0;
  const double ratio = span / options.step;
  // A tiny step over a long interval gives a ratio beyond int64 (or infinite), whose conversion below
  // would be undefined; it needs more steps than any maxSteps (at most int64) allows.
  if (!(ratio < 9.0e18)) {
    std::ostringstream text;
    text << "IntegratorOptions: step = " << options.step << " over [" << options.t0 << ", " << options.t1
         << "] needs more steps than maxSteps = " << options.maxSteps;
    throw std::invalid_argument(text.str());
  }
  // A step that divides the interval up to round-off must not produce an extra tiny step.
  auto count = static_cast<std::int64_t>(std::ceil(ratio - 1e-9 * ratio));
  if (count < 1) count = 1;
  if (count > options.maxSteps) {
    throw std::invalid_argument("IntegratorOptions: step = " + std::to_string(options.step) + " needs " +
                                std::to_string(count) +
                                " steps, more than maxSteps = " + std::to_string(options.maxSteps));
  }
  std::vector<double> grid(static_cast<std::size_t>(count) + 1);
  for (std::int64_t n = 0; n < count; ++n) grid[n] = options.t0 + span * (static_cast<double>(n) / count);
  grid[count] = options.t1;
  return grid;
}

/// The forward sweep shared by simulate() and computeGradient().
struct ForwardSweep {
  ForwardSweep(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options)
      : problem(problem), options(options), integrator(createIntegrator(problem, p, options)) {
    // z is the integrator's state; its head is the problem state (engine/integrator.h).
    const int m = integrator->stateSize();
    z.resize(m);
    zPrevious.resize(m);
    zdot.resize(m);
    integrator->initialState(options.t0, z);
    for (int k = 0; k < problem.stateSize(); ++k) {
      if (!std::isfinite(z(k))) {
        throw std::invalid_argument("initial state z0 of '" + problem.name() +
                                    "' has a non-finite entry z0[" + std::to_string(k) +
                                    "] = " + std::to_string(z(k)));
      }
    }
  }

  /// The problem state z = head of the integrator's state.
  Eigen::Ref<const Vector> problemState(const Vector& x) const { return x.head(problem.stateSize()); }

  void run(TrajectoryStorage* storage, const StateObserver& observer, RunSummary& summary) {
    const bool needDerivative = storage != nullptr && storage->needsDerivative();
    if (needDerivative && !integrator->hasStateDerivative()) {
      throw std::invalid_argument("storage '" + storage->spec() +
                                  "' needs the state derivative, which method '" + integrator->name() +
                                  "' does not provide; use a strategy that does not interpolate");
    }
    // Returns a Ref by value: a `const Ref&` to a Ref made from zdot would dangle.
    const auto derivativeAtStart = [&]() -> Eigen::Ref<const Vector> {
      if (!needDerivative) return zdot;
      if (integrator->firstStageIsRhs()) return integrator->lastFirstStage();
      integrator->stateDerivative(times.back(), zPrevious, zdot);
      return zdot;
    };
    const auto accept = [&](std::int64_t n, double t) {
      pollInterrupt();
      if (storage != nullptr) {
        storage->record(n, times[n], zPrevious, derivativeAtStart());
        if (stepData.size() > 0) {
          // The stage values of the step just accepted, the bits the adjoint step would recompute.
          integrator->saveStepData(stepData);
          storage->recordStepData(n, stepData);
        }
      }
      times.push_back(t);
      if (observer) observer(n + 1, t, problemState(z));
    };
    if (storage != nullptr) {
      TrajectoryInfo info;
      info.problemName = problem.name();
      info.stateSize = integrator->stateSize();
      info.t0 = options.t0;
      info.t1 = options.t1;
      const bool withRhsData = storage->keepsStepData() && storage->keepsRhsData();
      if (storage->keepsStepData())
        info.stepDataSize = integrator->stepDataSize() + (withRhsData ? integrator->stepRhsDataSize() : 0);
      stepData.resize(info.stepDataSize);
      integrator->setSavesStepData(info.stepDataSize > 0, withRhsData);
      if (!options.adaptive) {
        info.stepCount = options.replayTimes.empty()
                             ? static_cast<std::int64_t>(fixedGrid(options).size()) - 1
                             : static_cast<std::int64_t>(options.replayTimes.size()) - 1;
      }
      // The backward sweep restores into zPrevious, which holds x_{N-1} when the forward sweep ends (every
      // step starts from a copy there): the working state the strategy need not keep.
      info.workingStateHoldsLast = true;
      storage->begin(info, *recomputer);
    }
    times.clear();
    times.push_back(options.t0);
    if (observer) observer(0, options.t0, problemState(z));
    objective = 0.0;
    if (!options.adaptive || !options.replayTimes.empty()) {
      const std::vector<double> grid = options.replayTimes.empty() ? fixedGrid(options) : options.replayTimes;
      times.reserve(grid.size());
      for (std::size_t n = 0; n + 1 < grid.size(); ++n) {
        zPrevious = z;
        objective += integrator->step(grid[n], grid[n + 1] - grid[n], z);
        accept(static_cast<std::int64_t>(n), grid[n + 1]);
      }
    } else {
      runAdaptive(summary, accept);
    }
    summary.steps = static_cast<std::int64_t>(times.size()) - 1;
    // The terminal derivative for strategies that interpolate (Hermite).
    if (storage != nullptr) {
      if (needDerivative) integrator->stateDerivative(times.back(), z, zdot);
      storage->finish(summary.steps, times.back(), z, zdot);
    }
    objective += problem.terminal(problemState(z), integratorParameters());
  }

  template <typename Accept>
  void runAdaptive(RunSummary& summary, Accept&& accept) {
    const StepSizeController controller(integrator->errorOrder());
    const double maxStep = options.maxStep > 0.0 ? options.maxStep : options.t1 - options.t0;
    double t = options.t0;
    double h = std::min(options.step, maxStep);
    std::int64_t n = 0;
    while (t < options.t1) {
      if (n >= options.maxSteps) {
        throw NumericalError("more than maxSteps = " + std::to_string(options.maxSteps) + " steps", t);
      }
      zPrevious = z;
      for (;;) {
        if (h < options.minStep) {
          throw NumericalError("step size underflow: h = " + std::to_string(h) + " < minStep", t);
        }
        const double tNext = (t + h >= options.t1 || options.t1 - (t + h) < 1e-12 * h) ? options.t1 : t + h;
        const double hTaken = tNext - t;
        double error = 0.0;
        double increment = 0.0;
        bool newtonFailed = false;
        try {
          increment = integrator->step(t, hTaken, z, &error);
        } catch (const NewtonFailure&) {
          newtonFailed = true;
        } catch (const NumericalError&) {
          newtonFailed = true;  // a non-finite trial state: retry smaller
        }
        if (!newtonFailed && error <= 1.0) {
          objective += increment;
          accept(n, tNext);
          t = tNext;
          h = std::min(maxStep, controller.afterAccepted(hTaken, error));
          break;
        }
        ++summary.rejectedSteps;
        z = zPrevious;
        h = newtonFailed ? controller.afterFailed(hTaken) : controller.afterRejected(hTaken, error);
      }
      ++n;
    }
  }

  const Vector& integratorParameters() const { return parameters; }

  const Problem& problem;
  const IntegratorOptions& options;
  std::unique_ptr<Integrator> integrator;
  Vector parameters;
  Vector z, zPrevious, zdot;
  Vector stepData;  ///< the stage values of a step, when the storage keeps them
  std::vector<double> times;
  double objective = 0.0;
  std::unique_ptr<StepRecomputer> recomputer;
};

}  // namespace

void RunSummary::addStorageCounters(const StorageCounters& counters, std::size_t gridPoints) {
  recomputedSteps = counters.recomputedSteps;
  statesStored = counters.statesStored;
  peakBytesInMemory = counters.peakBytesInMemory + static_cast<std::int64_t>(gridPoints) * 8;
  bytesOnDisk = counters.bytesOnDisk;
  compressionRatio = counters.compressionRatio();
  gradientErrorEstimate = counters.gradientErrorEstimate;
  ioSeconds = counters.ioSeconds;
  predictedStorageSeconds = counters.predictedSeconds;
  measuredStorageSeconds = counters.scheduleSeconds;
  stepDataStored = counters.stepDataStored;
  stepDataRestored = counters.stepDataRestored;
  planningSeconds = counters.planningSeconds;
}

namespace {

void fillWork(RunSummary& summary, const Integrator& integrator) {
  summary.method = integrator.name();
  summary.rhsEvaluations = integrator.counters().rhsEvaluations;
  summary.jacobianEvaluations = integrator.counters().jacobianEvaluations;
  summary.factorizations = integrator.counters().factorizations;
  summary.newtonIterations = integrator.counters().newtonIterations;
}

}  // namespace

void RunSummary::print(std::ostream& out) const {
  out << "method: " << method << (adjoint.empty() ? "" : "\nadjoint: " + adjoint)
      << (storage.empty() ? "" : "\nstorage: " + storage) << "\nsteps: " << steps
      << "\nrejected steps: " << rejectedSteps << "\nrhs evaluations: " << rhsEvaluations
      << "\njacobian evaluations: " << jacobianEvaluations << "\nfactorizations: " << factorizations
      << "\nnewton iterations: " << newtonIterations << "\nrecomputed steps: " << recomputedSteps
      << "\nstates stored: " << statesStored << "\npeak bytes in memory: " << formatBytes(peakBytesInMemory)
      << "\nbytes on disk: " << formatBytes(bytesOnDisk) << "\ncompression ratio: " << compressionRatio
      << "\nforward seconds: " << forwardSeconds << "\nbackward seconds: " << backwardSeconds
      << "\nI/O seconds: " << ioSeconds << '\n';
  if (gradientErrorEstimate >= 0.0) out << "gradient error estimate: " << gradientErrorEstimate << '\n';
  if (predictedStorageSeconds > 0.0 || measuredStorageSeconds > 0.0) {
    out << "storage seconds predicted: " << predictedStorageSeconds
        << "\nstorage seconds measured: " << measuredStorageSeconds << '\n';
  }
  if (stepDataStored > 0 || stepDataRestored > 0)
    out << "step data stored: " << stepDataStored << "\nstep data restored: " << stepDataRestored << '\n';
  if (planningSeconds > 0.0) out << "planning seconds: " << planningSeconds << '\n';
}

ForwardResult simulate(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options,
                       const StateObserver& observer) {
  const Stopwatch forwardTimer;
  ForwardSweep sweep(problem, p, options);
  sweep.parameters = p;
  ForwardResult result;
  sweep.run(nullptr, observer, result.summary);
  result.objective = sweep.objective;
  result.finalState = sweep.problemState(sweep.z);
  result.times = std::move(sweep.times);
  fillWork(result.summary, *sweep.integrator);
  result.summary.adjoint.clear();
  result.summary.peakBytesInMemory = static_cast<std::int64_t>(result.times.size()) * 8;
  result.summary.forwardSeconds = forwardTimer.seconds();
  return result;
}

GradientResult computeGradient(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options,
                               TrajectoryStorage& storage, const StateObserver& observer) {
  const Stopwatch forwardTimer;
  ForwardSweep sweep(problem, p, options);
  sweep.parameters = p;
  sweep.recomputer = std::make_unique<GridRecomputer>(*sweep.integrator, sweep.times);
  GradientResult result;
  result.summary.storage = storage.spec();
  if (!options.adaptive) {
    // Fixed grids are known in advance: reserve so that recording never reallocates the grid.
    sweep.times.reserve(options.replayTimes.empty() ? fixedGrid(options).size() : options.replayTimes.size());
  }
  sweep.run(&storage, observer, result.summary);
  result.summary.forwardSeconds = forwardTimer.seconds();

  const Stopwatch backwardTimer;
  const int n = problem.stateSize();
  Vector lambda = Vector::Zero(sweep.integrator->stateSize());
  Vector gradient = Vector::Zero(problem.parameterSize());
  problem.addTerminalGradient(sweep.problemState(sweep.z), p, lambda.head(n), gradient);
  Vector& z = sweep.zPrevious;
  const std::vector<double>& times = sweep.times;
  // x_{n+1} with the forward bits, for a method that reads its step's solution from it: the final state,
  // then each restored state (only an exact storage restores the forward bits).
  const bool withEnd = sweep.integrator->usesStepEnd() && storage.isExact();
  Vector zEnd;
  if (withEnd) zEnd = sweep.z;
  for (std::int64_t step = result.summary.steps - 1; step >= 0; --step) {
    pollInterrupt();
    try {
      storage.restore(step, z);
      const double h = times[step + 1] - times[step];
      if (sweep.stepData.size() > 0 && storage.restoreStepData(step, sweep.stepData)) {
        sweep.integrator->adjointStepFromData(times[step], h, z, sweep.stepData, lambda, gradient);
      } else if (withEnd) {
        sweep.integrator->adjointStepWithEnd(times[step], h, z, zEnd, lambda, gradient);
        zEnd = z;
      } else {
        sweep.integrator->adjointStep(times[step], h, z, lambda, gradient);
      }
    } catch (const NumericalError& e) {
      throwBackwardSweepFailure(e, storage, "discrete adjoint, step " + std::to_string(step));
    }
  }
  // z holds z_0 again: the last restore was step 0.
  sweep.integrator->addInitialStateVjp(options.t0, z, lambda, gradient);
  result.summary.backwardSeconds = backwardTimer.seconds();

  const StorageCounters& counters = storage.counters();
  fillWork(result.summary, *sweep.integrator);
  result.summary.addStorageCounters(counters, times.size());
  result.objective = sweep.objective;
  result.gradient = std::move(gradient);
  result.times = std::move(sweep.times);
  return result;
}

}  // namespace hindsight
