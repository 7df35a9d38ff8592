// The forward sweep and the discrete-adjoint backward sweep over a trajectory storage strategy
// (docs/design.md §5). The backward sweep asks the storage for z_n in reverse order and applies the
// integrator's exact transposed step, so the gradient is the derivative of the psi actually
// computed (to the Newton residual for implicit methods). Adaptive steps are taken once in the
// forward sweep; the backward sweep replays exactly the accepted steps.
#pragma once

#include <hindsight/engine/integrator.h>
#include <hindsight/engine/trajectory_storage.h>

#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

namespace hindsight {

/// What a run did and what it cost (docs/design.md §5).
struct RunSummary {
  std::string method;
  std::string adjoint = "discrete";
  std::string storage;
  std::int64_t steps = 0;
  std::int64_t rejectedSteps = 0;
  std::int64_t rhsEvaluations = 0;
  std::int64_t jacobianEvaluations = 0;
  std::int64_t factorizations = 0;
  std::int64_t newtonIterations = 0;
  std::int64_t recomputedSteps = 0;
  std::int64_t statesStored = 0;
  std::int64_t peakBytesInMemory = 0;  ///< storage plus the time grid
  std::int64_t bytesOnDisk = 0;
  double compressionRatio = 1.0;
  double gradientErrorEstimate = -1.0;  ///< from the storage (StorageCounters); -1: none made
  double forwardSeconds = 0.0;
  double backwardSeconds = 0.0;
  double ioSeconds = 0.0;
  /// The storage's predicted and measured seconds of recomputation + disk I/O (multilevel's plan; 0 else).
  double predictedStorageSeconds = 0.0;
  double measuredStorageSeconds = 0.0;
  /// Step data (stage values) the storage kept and served (StorageCounters), and the seconds it spent
  /// planning (cams; included in forwardSeconds or backwardSeconds).
  std::int64_t stepDataStored = 0;
  std::int64_t stepDataRestored = 0;
  double planningSeconds = 0.0;
  /// Human-readable, one "key: value" per line.
  void print(std::ostream& out) const;
  /// Copies what the storage reports (recomputations, states, bytes, compression, I/O time); the time
  /// grid of `gridPoints` doubles counts towards the peak memory. Shared by every route over a storage.
  void addStorageCounters(const StorageCounters& counters, std::size_t gridPoints);
};

struct ForwardResult {
  double objective = 0.0;
  Vector finalState;
  std::vector<double> times;  ///< the grid t_0..t_N actually taken
  RunSummary summary;
};

struct GradientResult {
  double objective = 0.0;
  Vector gradient;            ///< dpsi/dp
  std::vector<double> times;  ///< the grid t_0..t_N actually taken
  RunSummary summary;
};

/// Called at every grid point (t_n, z_n), n = 0..N, during the forward sweep.
using StateObserver = std::function<void(std::int64_t step, double t, ConstVectorRef z)>;

/// Forward sweep only: psi and the final state. Throws std::invalid_argument on bad input (wrong p
/// size, invalid options, non-finite initial state) and NumericalError on a numerical failure.
ForwardResult simulate(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options,
                       const StateObserver& observer = {});

/// psi and dpsi/dp by the discrete adjoint over `storage`.
GradientResult computeGradient(const Problem& problem, ConstVectorRef p, const IntegratorOptions& options,
                               TrajectoryStorage& storage, const StateObserver& observer = {});

}  // namespace hindsight
