// Strategy "binomial": offline revolve-optimal checkpointing for a known number of steps N
// (Griewank & Walther 2000, "Algorithm 799: revolve", ACM TOMS 26(1); Griewank & Walther,
// "Evaluating Derivatives", 2nd ed., SIAM 2008, chapter 12).
//
// Spec: binomial:checkpoints=C[,budget=BYTES]   (C in [1, 10^9]; default budget 4 GiB).
//
// Mathematics. With beta(c, r) = C(c + r, c), c checkpoints and r repetitions reverse at most
// beta(c, r) steps. For N steps let r be the least integer with beta(c, r) >= N; the least number of
// forward steps that reverses N steps is
//     T(N, c) = r N - beta(c + 1, r - 1) = r N - C(c + r, r - 1)
// (Griewank 1992, Optim. Methods Softw. 1:35-54; Griewank & Walther 2000; docs/design.md §6).
// The schedule below attains it: to reverse an interval of l steps whose first state is held in one of
// s slots, advance m steps, keep that state in a new slot, reverse the right part (l - m steps, s - 1
// slots), release the slot and reverse the left part (m steps, s slots). T is convex piecewise linear in
// l, the maximum of the lines r l - beta(s + 1, r - 1), and T(l, s) = m + T(l - m, s - 1) + T(m, s)
// holds exactly when both parts lie on their own supporting lines r and r - 1:
//     beta(s - 1, r - 1) <= l - m <= beta(s - 1, r)   and   beta(s, r - 2) <= m <= beta(s, r - 1),
// (the two lines add up to r l - beta(s + 1, r - 1) by Pascal's rule). binomialSplit() picks the
// largest such m. With one slot the interval is replayed from its start for every step.
//
// What is counted, and the slots. Revolve's setting charges c checkpoints but not its "current" state,
// which reaches x_{N-1} at the end of the first sweep and is consumed at once by the first adjoint step.
// computeGradient has that state too: its backward sweep restores into the buffer its forward sweep's
// last step started from, which holds x_{N-1} (TrajectoryInfo.workingStateHoldsLast, the caller's
// working state; checkpoint_schedules' WORK). So a run of the engine is revolve's game exactly: with
// S = slotsFor(N, C, true) = min(C + 1, N - 1) slots (1 for N = 1) over the positions 0..N-1,
//     counters().recomputedSteps == T(N, S) - (N - 1)      exactly, for every N >= 1, C >= 1,
// revolve's own count with C + 1 snapshots (N = 1000, C = 2: 11 156), and peakBytesInMemory == S states,
// all charged with holdBytes(); begin() throws std::invalid_argument naming binomial.checkpoints and
// binomial.budget when they do not fit.
//
// A caller without a working state (workingStateHoldsLast false: the storage protocol driven directly,
// the PETSc adapter) plays the game where every kept state is charged and the forward sweep ends at x_N:
// the states x_e are asked for in the order N-1, ..., 0, each from a slot plus advances (docs/design.md
// §6, "the game"). With S slots its least number of recomputed steps is
//     R(N, S) = T(N + 1, S) - N,
// revolve with S checkpoints over N + 1 positions (0..N) whose first sweep 0 -> N is the forward sweep
// itself: x_N plays revolve's current state and is never asked for; the strategy then runs that plan
// with S = slotsFor(N, C, false) = min(C + 1, N) slots. The tests confirm R by exhaustive search over
// every schedule of that game (small N and S) and by a dynamic programme over first splits.
// R(N, S) = T(N, S) - (N - 1) + (r(N + 1, S) - 1): one recomputed step per repetition more than with the
// working state (N = 1000, C = 2: 11 172).
//
// Preconditions: TrajectoryInfo.stepCount >= 1 (fixed step or replayed grid); begin() throws
// std::invalid_argument telling to use `online` when it is -1 (adaptive steps).
// Complexity: the recomputed steps above in total; restores and records allocate nothing (all
// slots are allocated in begin(), a test counts heap allocations); each schedule decision costs
// O(min(c, r) log r) products of 128-bit saturating binomials, so N up to 2^62 and c up to 10^9 do not
// overflow.
#pragma once

#include <hindsight/engine/recomputed_stages.h>
#include <hindsight/engine/storage_registry.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>

#include <cassert>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <vector>

namespace hindsight {

__extension__ typedef unsigned __int128 UnsignedInt128;

namespace revolve {

/// beta(c, r) = C(c + r, c), saturated at 2^64 (a value >= 2^64 is returned as 2^64); 0 for r < 0.
/// Preconditions: c >= 0.
UnsignedInt128 beta(std::int64_t c, std::int64_t r);
/// The repetition number: least r >= 0 with beta(c, r) >= steps. Preconditions: steps >= 1, c >= 1.
std::int64_t repetitionNumber(std::int64_t steps, std::int64_t checkpoints);
/// T(N, c) = r N - beta(c + 1, r - 1): least number of forward steps (revolve's count, see above).
UnsignedInt128 optimalForwardSteps(std::int64_t steps, std::int64_t checkpoints);
/// R(N, S) = T(N + 1, S) - N: least number of recomputed steps when every kept state is charged and
/// the forward sweep ends at x_N (see above). Preconditions: steps >= 1, slots >= 1.
UnsignedInt128 optimalRecomputedSteps(std::int64_t steps, std::int64_t slots);
/// T(N, S) - (N - 1): revolve's own count of recomputed steps with S snapshots, reached when the caller's
/// working state holds x_{N-1} (TrajectoryInfo.workingStateHoldsLast; see above).
/// Preconditions: steps >= 1, slots >= 1.
UnsignedInt128 workingStateRecomputedSteps(std::int64_t steps, std::int64_t slots);
/// The first checkpoint's offset m (1 <= m < l) for reversing l >= 2 steps with s >= 2 slots, one of
/// them holding the interval's first state; optimal in the sense of T(l, s) = m + T(l-m, s-1) + T(m, s).
std::int64_t binomialSplit(std::int64_t steps, std::int64_t slots);
/// Decimal rendering of a 128-bit count, for messages.
std::string toString(UnsignedInt128 value);
/// The checkpoints BinomialSchedule::reset(length, slots, true) pushes in its first sweep (x_0 not
/// counted) and the position of the last one (0 when none), in O(pushes while r >= 2).
struct FirstSweep {
  std::int64_t pushes = 0;
  std::int64_t top = 0;
};
FirstSweep firstSweep(std::int64_t length, std::int64_t slots);
/// Checkpoint writes of a whole BinomialSchedule run (reset(length, slots, true): x_0, the first sweep's
/// and the backward sweep's stores), simulateSchedule's checkpointWrites in closed form, O(slots + r).
std::int64_t checkpointWrites(std::int64_t length, std::int64_t slots);

}  // namespace revolve

/// The revolve schedule as a state machine on positions 0..l-1 of one interval, without states
/// (docs/design.md P 1: the storage strategies and the pure schedule simulator drive the same code).
/// Checkpoints form a stack; the checkpoint at stack depth i lives in slot i. Slot 0 holds position 0.
class BinomialSchedule {
 public:
  /// Starts an interval of `length` >= 1 steps with `slots` >= 1 checkpoint slots. With
  /// `workingStateHoldsLast`, the caller keeps the state at position length - 1 (revolve's current
  /// state after the first sweep) and records the first sweep through recordForward(); otherwise the
  /// first restoreStep() performs the first sweep itself by advancing from slot 0.
  void reset(std::int64_t length, std::int64_t slots, bool workingStateHoldsLast);
  /// Capacity for schedules of up to `slots` slots, so that later reset()s allocate nothing.
  void reserve(std::int64_t slots) { stack_.reserve(static_cast<std::size_t>(slots)); }

  /// First sweep, for positions n = 1, 2, ..., length - 1 in order: the slot into which the state at n
  /// is to be copied, or -1 when the schedule does not keep it (position 0 goes to slot 0).
  std::int64_t recordForward(std::int64_t n);

  /// Produces the state at position e (e = length-1, ..., 0 in order) through the visitor:
  ///   loadWorking()                  the state is the working state;
  ///   load(slot)                     copy the checkpoint in `slot` into the current state;
  ///   advance(from, to)              recompute the current state from position `from` to `to`;
  ///   store(slot)                    copy the current state into `slot`.
  template <typename Visitor>
  void restoreStep(std::int64_t e, Visitor& visitor);

  /// The position the first sweep keeps next (recordForward() returns a slot there and -1 before it),
  /// -1 when it keeps no more: lets a caller skip the positions in between.
  std::int64_t nextForward() const { return nextForward_; }
  std::int64_t length() const { return length_; }
  std::int64_t slots() const { return slots_; }
  /// Checkpoints held now (stack depth).
  std::int64_t held() const { return static_cast<std::int64_t>(stack_.size()); }

 private:
  std::int64_t nextForwardTarget() const;

  std::int64_t length_ = 0;
  std::int64_t slots_ = 0;
  bool workingValid_ = false;
  std::int64_t nextForward_ = -1;
  std::vector<std::int64_t> stack_;
};

template <typename Visitor>
void BinomialSchedule::restoreStep(std::int64_t e, Visitor& visitor) {
  assert(!stack_.empty() && stack_.back() <= e && e < length_);
  if (workingValid_ && e == length_ - 1 && stack_.back() != e) {
    workingValid_ = false;
    visitor.loadWorking();
    return;
  }
  workingValid_ = false;
  std::int64_t position = stack_.back();
  visitor.load(static_cast<std::int64_t>(stack_.size()) - 1);
  if (position == e) {
    stack_.pop_back();
    return;
  }
  while (position < e) {
    const std::int64_t freeSlots = slots_ - static_cast<std::int64_t>(stack_.size());
    if (freeSlots == 0) {
      visitor.advance(position, e);
      position = e;
      break;
    }
    const std::int64_t split = revolve::binomialSplit(e + 1 - position, freeSlots + 1);
    visitor.advance(position, position + split);
    position += split;
    // A checkpoint at e itself would be used at once and released: reverse it from the current state.
    if (position < e) {
      stack_.push_back(position);
      visitor.store(static_cast<std::int64_t>(stack_.size()) - 1);
    }
  }
}

/// Counts of a schedule run without states (revolve::simulateSchedule).
struct ScheduleCounts {
  std::int64_t firstSweepSteps = 0;    ///< N - 1
  UnsignedInt128 recomputedSteps = 0;  ///< advances in the backward sweep
  std::int64_t checkpointWrites = 0;   ///< states copied into slots, first sweep included
  std::int64_t maxCheckpointsHeld = 0;
  std::int64_t workingStateLoads = 0;
  UnsignedInt128 totalForwardSteps() const { return firstSweepSteps + recomputedSteps; }
};

namespace revolve {
/// Runs the binomial schedule for N steps and c slots through every restore, counting steps only
/// (no states). O(N + number of actions) time, O(c) memory.
ScheduleCounts simulateSchedule(std::int64_t steps, std::int64_t checkpoints);
}  // namespace revolve

class BinomialCheckpointing final : public TrajectoryStorage {
 public:
  static constexpr std::int64_t kDefaultBudget = std::int64_t{4} << 30;
  static constexpr std::int64_t kMaxCheckpoints = 1'000'000'000;
  /// Throws std::invalid_argument when checkpoints is outside [1, kMaxCheckpoints].
  /// stages: keep the stage values of the last recomputed step (and of the forward sweep's last step),
  /// two step records in all, so the adjoint step that follows a recomputation evaluates no right-hand
  /// side. The schedule, and so the recomputed steps, are revolve's as without it.
  explicit BinomialCheckpointing(std::int64_t checkpoints, std::int64_t budgetBytes = kDefaultBudget,
                                 bool stages = false);
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  /// The registry's prediction (engine/storage_registry.h): the counts of N fixed steps.
  static void predict(const TrajectoryStorage& storage, const StorageSpec& spec,
                      const PredictionRequest& request, SchedulePrediction& p);
  /// The registry's action stream: the BinomialSchedule a run executes, written action by action.
  static void writeActions(const TrajectoryStorage& storage, const StorageSpec& spec,
                           const PredictionRequest& request, std::ostream& out);

  std::string spec() const override;
  bool isExact() const override { return true; }
  bool keepsStepData() const override { return stages_; }
  std::int64_t checkpoints() const { return checkpoints_; }
  /// The slots a run of N >= 1 steps uses with C checkpoints: min(C + 1, N - 1) (1 for N = 1) when the
  /// caller's working state holds x_{N-1}, else min(C + 1, N): one per position that can be a checkpoint.
  static std::int64_t slotsFor(std::int64_t steps, std::int64_t checkpoints, bool workingStateHoldsLast);
  /// The positions the plan's BinomialSchedule spans: 0..N-1 with the working state, else 0..N.
  static std::int64_t planLength(std::int64_t steps, bool workingStateHoldsLast) {
    return workingStateHoldsLast ? steps : steps + 1;
  }

  /// The counters of a run of N >= 1 fixed steps with S >= 1 slots (S = slotsFor(N, C, working)), the
  /// caller's working state holding x_{N-1} or not, and, with keepStages, stages=1 for an integrator with
  /// stage values: recomputed steps, statesStored, RAM writes (slot copies), stepDataStored and
  /// stepDataRestored.
  struct PlanCounts {
    UnsignedInt128 recomputedSteps = 0;
    std::int64_t statesStored = 0, ramWrites = 0, stepDataStored = 0, stepDataRestored = 0;
  };
  /// By running the strategy's own plan (the code doRecord and doRestore run) with a counting visitor:
  /// O(N + actions) time, O(S) memory.
  static PlanCounts countPlan(std::int64_t steps, std::int64_t slots, bool keepStages, bool working);
  /// By revolve's closed forms, O(S + r): what the prediction uses beyond prediction::kMaxWalkedSteps.
  static PlanCounts closedFormCounts(std::int64_t steps, std::int64_t slots, bool keepStages, bool working);

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;
  void doRecordStepData(std::int64_t step, ConstVectorRef data) override;
  bool doRestoreStepData(std::int64_t step, VectorRef data) override;
  void releaseAll();

  std::int64_t checkpoints_;
  bool stages_;
  bool working_ = false;                         // this run's TrajectoryInfo.workingStateHoldsLast
  internal::RecomputedStages recomputedStages_;  // stages=1
  BinomialSchedule schedule_;
  std::unique_ptr<double[]> slots_;  // slotCount_ states, slot i at slots_ + i * n
  std::int64_t slotCount_ = 0;
  std::int64_t heldBytes_ = 0;
};

}  // namespace hindsight
