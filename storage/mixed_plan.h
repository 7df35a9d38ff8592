// Spec "mixed": checkpoint_schedules' Mixed plan (J. R. Maddison, "On the implementation of checkpointing
// with high-level algorithmic differentiation", arXiv 2305.09568, 2023; published as "Step-based
// checkpointing with high-level algorithmic differentiation", J. Comput. Sci. 82 (2024) 102405), for
// action streams and predictions only.
//
// Spec: mixed:checkpoints=C   (C units in [1, 10^6]; N - 1 of them at most are used).
//
// The model. Each of the C units holds either a state x_n (restart data: the forward can be advanced from
// it, any number of times) or the adjoint data of one step n (its "non-linear dependencies": the adjoint
// of step n can be taken from it, once, but the forward cannot be restarted there). Both take one unit.
// The state being advanced (WORK) is not counted, and x_0 is not held unless the plan stores it. For n steps
// left, starting from the state at hand, with s units free, the least number of forward steps m(n, s) is
// (the recurrence of the paper, s read as min(s, n - 1)):
//   m(1, s) = 1                                   one step, its adjoint data kept in WORK and reversed;
//   m(n, s) = n                 for n <= s + 1    every step's adjoint data stored on the way;
//   m(n, 1) = n (n + 1) / 2 - 1                   the state stored and replayed for every step;
//   m(n, s) = min( 1 + m(n - 1, s - 1),           store the first step's adjoint data, or
//                  min_{2 <= i < n} i + m(i, s) + m(n - i, s - 1) )
//                                                 store the state, advance i steps, reverse the n - i
//                                                 steps beyond with s - 1 units, then the first i from
//                                                 the stored state with s units (its own among them).
// The plan takes the largest minimizing i, and the adjoint-data option only when strictly cheaper (as
// checkpoint_schedules does). Its stream's Forward steps add up to m(N, C) exactly (N = 1000, C = 11:
// 3 730; N = 10^4, C = 51: 28 850), against revolve's with the same C snapshots (binomial:checkpoints=C-1:
// T(N, C) + N, 4 545 and 38 569): 0.82x and 0.75x. The stream is checkpoint_schedules'
// MixedCheckpointSchedule(N, C, storage=RAM) action by action (python/tests/test_checkpoint_schedule.py).
//
// Why not a run of the engine: a record of the engine is the state plus the step's stage values, 1 +
// ceil(stepDataSize / n) units, not one; `cams` is the engine's strategy of this kind (records sized by
// the integrator's stage data, restartable). A run with `mixed` is refused at begin() (std::invalid_argument
// naming cams); `hindsight schedule` predicts it and openCheckpointStream() (storage/checkpoint_stream.h),
// Python's hindsight.checkpoint_schedule hand out its actions for any time-stepper whose step records are
// one state in size.
//
// Complexity: the table m(n, s) for n <= N, s <= C' = min(C, N - 1): N C' cells (12 bytes each) and
// sum_n n C' ~ N^2 C' / 2 operations; (N + 1) C' <= kMaxCells (2^24) and N^2 (C' - 1) / 2 <= kMaxWork
// (2^32), refused naming the limits beyond (N = 10^4, C = 51: 6.5 s on a loaded machine). The stream is
// then generated action by action from the table.
#pragma once

#include <hindsight/engine/storage_registry.h>
#include <hindsight/storage/checkpoint_actions.h>

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

namespace hindsight {

namespace mixed {

/// The table of the recurrence above for every n <= N and s <= min(C, N - 1).
class Plan {
 public:
  static constexpr std::int64_t kMaxCells = std::int64_t{1} << 24;
  static constexpr std::int64_t kMaxWork = std::int64_t{1} << 32;
  /// What the plan does first with n steps left and s units free.
  enum class Kind : std::uint8_t {
    kForwardReverse,  ///< n == 1: advance with the adjoint data to WORK, reverse
    kAdjointData,     ///< store the first step's adjoint data in a unit
    kState,           ///< store the state at hand, advance `advance` steps
  };
  struct Step {
    Kind kind;
    std::int64_t advance;
  };
  /// Throws std::invalid_argument naming mixed.checkpoints (C < 1 with N >= 2) or the limits.
  Plan(std::int64_t steps, std::int64_t units);
  std::int64_t steps() const { return steps_; }
  /// min(C, N - 1): the units the plan can use.
  std::int64_t units() const { return units_; }
  /// m(n, s) (s read as min(s, n - 1)); 1 <= n <= N, 0 <= s, s >= 1 when n >= 2.
  std::int64_t cost(std::int64_t n, std::int64_t s) const;
  /// The first decision for n steps left and s units free (as cost()).
  Step step(std::int64_t n, std::int64_t s) const;

 private:
  std::size_t cell(std::int64_t n, std::int64_t s) const;
  std::int64_t steps_, units_;
  std::vector<std::int64_t> cost_;   // column s (1..units_) of n (0..N): cost_[(s - 1)(N + 1) + n]
  std::vector<std::int32_t> split_;  // same cells: i >= 2 for kState, 1 for kAdjointData, 0 for n == 1
};

/// The plan's action stream for N steps (checkpoint_schedules' vocabulary and contract,
/// storage/checkpoint_actions.h), checkpoints in RAM. Its Forward steps add up to plan.cost(N, C); at most C
/// units are held at once.
std::vector<CheckpointAction> actions(const Plan& plan);
/// The same actions handed to `out` one at a time, as they are made (no vector of them).
void forEachAction(const Plan& plan, const std::function<void(const CheckpointAction&)>& out);

}  // namespace mixed

/// The registry's object for `mixed` (storage/storage_factory.cpp): carries the spec for predictions and
/// refuses a run (file comment).
class MixedPlanStorage final : public TrajectoryStorage {
 public:
  static constexpr std::int64_t kMaxCheckpoints = 1'000'000;
  /// No byte budget (its limit is C units of the state's size); a run is refused at begin().
  explicit MixedPlanStorage(std::int64_t checkpoints)
      : TrajectoryStorage(std::numeric_limits<std::int64_t>::max()), checkpoints_(checkpoints) {}
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  /// Counts of the plan's stream: recomputed steps, stored and restored step data, states stored, peak
  /// bytes (units x state bytes).
  static void predict(const TrajectoryStorage& storage, const StorageSpec& spec,
                      const PredictionRequest& request, SchedulePrediction& p);
  std::int64_t checkpoints() const { return checkpoints_; }
  std::string spec() const override;
  bool isExact() const override { return true; }

 private:
  void doBegin() override;
  void doRecord(std::int64_t, double, ConstVectorRef, ConstVectorRef) override {}
  void doFinish(double, ConstVectorRef, ConstVectorRef) override {}
  void doRestore(std::int64_t, VectorRef) override {}
  std::int64_t checkpoints_;
};

}  // namespace hindsight
