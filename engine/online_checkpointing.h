// Strategy "online": checkpointing while the number of steps N is still unknown (adaptive steps),
// re-planned with the offline binomial schedule once N is known.
//
// Spec: online:budget=BYTES | online:checkpoints=C[,budget=BYTES]   (default budget 4 GiB).
// With only a budget, c = floor(budget / stateBytes) - 1 checkpoints (one state is the working state).
//
// Two games, by whether the caller's working state holds x_{N-1} (TrajectoryInfo::workingStateHoldsLast,
// engine/binomial_checkpointing.h): a run of computeGradient, and what the prediction reports, has it; the
// storage protocol driven directly (the PETSc adapter, tests) does not.
//
// With the working state (internal::TwoHorizonPlacement in engine/online_placement.h): the c + 1 slots
// all hold checkpoints p_0 = 0 < p_1 < ... < p_m (m <= c), each record x_k stored at once (into a free
// slot, or replacing p_j, j >= 1) or not. Backward sweep: x_{N-1} is the caller's; interval i (p_i to
// p_{i+1}, the last one to N - 1) is reversed by the offline binomial schedule (BinomialSchedule) with
// c + 1 - i slots (its own and those of p_{i+1}..p_c): sum_i T(L_i, c + 1 - i) recomputed steps. The offline
// optimum at the same memory is binomial's T(N, S) - (N - 1), S = min(c + 1, N - 1), and the measure is
// (2N + online) / (2N + binomial) (bench/online_working_state.py, whose TwoHorizonRule is the reference
// tests/storage/online_checkpointing_test.cpp compares counts with). Two-horizon rule: among keeping the
// placement, storing x_k in a free slot and replacing p_j, take the one whose worse ratio, were the run
// to end at N = k + 1 or N = k + 2, is least. What is known (the test and the script):
//  * c >= 2: ratio <= 1.10 for every N <= 10^5 (the script, --rule 100000; the test up to 2 * 10^4):
//    12/11 = 1.0909 (c = 2, N = 20), 17/16 (c = 3), 19/18 (c = 4), 82/77 = 1.065 (c = 5), 1.052 down to
//    1.033 for c = 6..12; never above Stumm & Walther's count T(N, c) - (N - 1). No bound is proven for
//    N beyond what was measured.
//  * c = 1: no online rule stays within 1.10 (exhaustive search over every sequence of decisions: every
//    rule exceeds it for some N <= 6); the least ratio any rule guarantees is 7/6 (N <= 200), and the rule
//    reaches it (at N = 5) and never exceeds it. For c = 3 and 4 the rule's worst ratio is also the least
//    any rule guarantees (N <= 40 and 30); for c = 2 the least is between 1.0869 and 1.0880 (N <= 80).
//  * Example: c = 2, N = 32: 63 recomputed steps (binomial 62; the cost rule below, which held before,
//    85).
//
// Without the working state (after Stumm & Walther 2010, "New algorithms for optimal online
// checkpointing", SIAM J. Sci. Comput. 32(2), moved to the game below; internal::CostPlacement):
//  * Forward sweep: the strategy's own copy holds the last recorded state (like revolve's current
//    state); when the next record arrives it is a checkpoint candidate. The first c candidates are kept.
//    From then on the c checkpoints s_0 = 0 < s_1 < ... < s_{c-1} cut the trajectory into intervals L_i
//    (the last one up to the copy).
//  * Backward sweep, N known: x_{N-1} is in the copy and is consumed first; its slot is then free, so
//    interval j (last to first) is reversed by BinomialSchedule with c + 1 - j slots: its own, those of
//    s_{j+1}..s_{c-1} and the copy's.
// The game: recomputed steps sum_i T(L_i, c + 1 - i) with sum_i L_i = N - 1, for a placement chosen
// while N is unknown. Up to N = beta(c + 1, 2) and beyond beta(c + 1, 3) the candidate replaces the
// checkpoint j >= 1 that gives the least sum were the run to end at this record, unless keeping the
// placement is cheaper (cost rule). For beta(c + 1, 2) < N <= beta(c + 1, 3) a candidate is taken
// every sixth record, or when it lands on one of the positions that fill every interval to what its
// slots reverse at repetition number 2 (then kept), and replaces the latest checkpoint whose merged
// interval stays within that (six-step rule: Stumm & Walther's three-step rule with the last interval's
// two slots instead of one; the details in engine/online_placement.h).
// The recomputed steps equal predictedForwardSteps(N, c, false) - (N - 1) exactly. What is known of them
// (tests/storage/online_checkpointing_test.cpp), with B(N, c) the least count of the game over every
// placement (N known; closed form: the N - 1 - c smallest of the values r = 1, 2, ... taken
// beta(c, r + 1) - 1 times each, checked against a dynamic programme), R(N, c + 1) = T(N + 1, c + 1) - N
// binomial's count at the same c + 1 states without the working state, and T(N, c) - (N - 1) Stumm &
// Walther's count (c snapshots and the current state, also c + 1 states in memory):
//  * B(N, c) = R(N, c + 1) for N <= beta(c + 1, 2) - 2, and B > R beyond (the copy holds x_{N-1},
//    where binomial would hold an earlier state); B(N, c) <= T(N, c) - (N - 1), equal for
//    N <= beta(c, 2), below beyond.
//  * online = B(N, c) for every N <= beta(c + 1, 2) + 1 (c <= 60 checked). No online rule reaches B for
//    every N up to beta(c + 1, 2) + 2, nor stays within one step of it up to beta(c + 1, 2) + 4; within
//    two steps up to beta(c + 1, 3) is possible (exhaustive search over every placement, c = 2..5), and
//    the six-step rule is within two steps of B for every N <= beta(c + 1, 3) (c = 2..60): the least
//    possible there for c <= 5.
//  * So online is below Stumm & Walther's count on their whole range beta(c, 2) < N <= beta(c, 3) and
//    equal to it below (c = 2..60 checked). Beyond beta(c + 1, 3), up to N = 10^5, measured for
//    c = 2..50: at most 1.31 R(N, c + 1) (c = 2, N = 32), 1.19 (c = 3), 1.12 (c = 5), 1.05 for c >= 9,
//    1.04 for c >= 11, 1.005 for c >= 37; no bound is proven there, and for c = 22 and 25..36 the cost
//    rule is up to 0.6 % above T(N, c) - (N - 1) at some N > beta(c, 3).
//    c = 1: T(N - 1, 2) exactly.
// Cost of the rules: O(1) evaluations of T per record; O(m - j) per replacement of p_j and O(1) per store
// into a free slot (two-horizon rule); O(c) per replacement (cost rule), O(c) per candidate taken, about
// every sixth record (six-step rule). No allocation per step (the tables are reserved at begin()). Memory: c
// + 1 states: with the working state c + 1 checkpoint slots, without it at most c checkpoints plus the
// strategy's copy (whose memory is slot c of the backward sweep); slots are allocated on first use and
// charged with holdBytes(); it never exceeds the budget. counters().statesStored counts the checkpoint writes
// of the forward sweep (x_0 included), without the working state plus the final copy of x_{N-1} (the copy
// made at every step is not counted).
//
// Preconditions: none on N (works for fixed and adaptive steps). Throws std::invalid_argument from
// begin() when c < 1 or (c + 1) states do not fit in the budget, naming online.checkpoints/online.budget.
// Complexity: one state copy per recorded step (the working state) plus the checkpoint copies; the
// backward sweep's cost is the bound above. The first use of a slot allocates it.
#pragma once

#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/online_placement.h>
#include <hindsight/engine/recomputed_stages.h>
#include <hindsight/engine/storage_registry.h>

namespace hindsight {

namespace internal {

/// online's backward sweep once its forward sweep has placed the checkpoints: the interval of each
/// restored step (the last held position at or before it), reversed by revolve with c + 1 - j slots for
/// interval j: slots j..c, slot c being the working state's, free once x_{N-1} is consumed. The strategy runs
/// it with a visitor that copies states and recomputes, its prediction (OnlineCheckpointing::predict) with
/// one that counts: one code for both.
class OnlineReversal {
 public:
  /// Capacity for the deepest interval (no allocation in the backward sweep).
  void reserve(std::int64_t slots) { schedule_.reserve(slots); }
  /// A new backward sweep over `positions` (held, increasing, from 0) of N steps with c checkpoints;
  /// x_{N-1} is the working state and not restored here.
  void reset(const std::vector<std::int64_t>* positions, std::int64_t steps, std::int64_t checkpoints) {
    positions_ = positions;
    steps_ = steps;
    checkpoints_ = checkpoints;
    interval_ = OnlinePlacement::Interval{static_cast<std::int64_t>(positions->size()), steps, 0};
  }
  /// Enters the interval of `step` (< N - 1, steps in decreasing order) when the previous one is done;
  /// returns it (its index is the slot of its first state).
  const OnlinePlacement::Interval& enter(std::int64_t step) {
    if (step < interval_.start) {
      interval_ = OnlinePlacement::intervalOf(*positions_, steps_, step, interval_.index);
      schedule_.reset(interval_.length, checkpoints_ + 1 - interval_.index, false);
    }
    return interval_;
  }
  /// Restores `step` by revolve within its interval (enter(step) first); the visitor sees positions and
  /// slots relative to the interval (BinomialSchedule's visitor).
  template <typename Visitor>
  void restoreStep(std::int64_t step, Visitor& visitor) {
    schedule_.restoreStep(step - interval_.start, visitor);
  }

 private:
  const std::vector<std::int64_t>* positions_ = nullptr;
  std::int64_t steps_ = 0, checkpoints_ = 0;
  OnlinePlacement::Interval interval_{0, 0, 0};
  BinomialSchedule schedule_;
};

}  // namespace internal

class OnlineCheckpointing final : public TrajectoryStorage {
 public:
  static constexpr std::int64_t kDefaultBudget = std::int64_t{4} << 30;
  /// checkpoints = 0 derives c from the budget at begin(); otherwise in [1,
  /// BinomialCheckpointing::kMaxCheckpoints].
  /// stages: as binomial's (engine/recomputed_stages.h): the stage values of the last recomputed step
  /// and of the forward sweep's last step, two step records charged to the budget.
  explicit OnlineCheckpointing(std::int64_t checkpoints, std::int64_t budgetBytes = kDefaultBudget,
                               bool stages = false);
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  /// The registry's prediction (engine/storage_registry.h): the counts of N fixed steps.
  static void predict(const TrajectoryStorage& storage, const StorageSpec& spec,
                      const PredictionRequest& request, SchedulePrediction& p);

  std::string spec() const override;
  bool isExact() const override { return true; }
  bool keepsStepData() const override { return stages_; }

  /// The checkpoint count c for states of stateBytes and recordBytes of step records (stages=1): the
  /// requested one, or what the budget holds besides the working state; at most kMaxCheckpoints.
  /// Throws std::invalid_argument naming online.checkpoints/online.budget when it does not fit.
  std::int64_t checkpointsFor(std::int64_t stateBytes, std::int64_t recordBytes) const;
  /// Whether stages=1.
  bool keepsStages() const { return stages_; }
  /// The checkpoint count c of the current run (known after begin()).
  std::int64_t checkpoints() const { return activeCheckpoints_; }
  /// (N - 1) + recomputed steps of this algorithm for N steps and c checkpoints, without states (the
  /// placement simulated step by step): internal::TwoHorizonPlacement when the caller's working state
  /// holds x_{N-1} (a run of computeGradient; what the registry's prediction reports), else
  /// internal::CostPlacement.
  static UnsignedInt128 predictedForwardSteps(std::int64_t steps, std::int64_t c, bool workingStateHoldsLast);
  /// (N - 1) + sum_j T(L_j, c + 1 - j) for held positions (increasing, starting at 0) of N steps.
  static UnsignedInt128 forwardStepsOf(const std::vector<std::int64_t>& positions, std::int64_t steps,
                                       std::int64_t c);

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;
  void doRecordStepData(std::int64_t step, ConstVectorRef data) override;
  bool doRestoreStepData(std::int64_t step, VectorRef data) override;
  double* slot(std::int64_t index);
  void commitWorkingState(std::int64_t step);
  void keep(std::int64_t dropped, std::int64_t held, const double* state);
  void releaseAll();

  std::int64_t requestedCheckpoints_;
  bool stages_;
  internal::RecomputedStages recomputedStages_;  // stages=1
  std::int64_t activeCheckpoints_ = 0;
  bool working_ = false;                          // this run's TrajectoryInfo.workingStateHoldsLast
  internal::TwoHorizonPlacement twoHorizon_;      // with it: slot i holds positions()[i]
  internal::CostPlacement placement_;             // without it: slot i holds positions()[i]
  std::vector<std::unique_ptr<double[]>> slots_;  // allocated on first use
  std::unique_ptr<double[]> workingCopy_;         // without it: x_{N-1}, slot c of the backward sweep
  std::int64_t heldBytes_ = 0;
  bool workingValid_ = false;
  internal::OnlineReversal reversal_;  // backward sweep
};

}  // namespace hindsight
