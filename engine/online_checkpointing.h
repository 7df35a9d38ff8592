// Strategy "online": checkpointing while the number of steps N is still unknown (adaptive steps),
// re-planned with the offline binomial schedule once N is known.
//
// Spec: online:budget=BYTES | online:checkpoints=C[,budget=BYTES]   (default budget 4 GiB).
// With only a budget, c = floor(budget / stateBytes) - 1 checkpoints (one state is the working state).
//
// Algorithm (after Stumm & Walther 2010, "New algorithms for optimal online checkpointing", SIAM J. Sci.
// Comput. 32(2): revolve's optimum T(N, c) for every N while N is unknown, as far as an online rule can;
// internal::CostPlacement in engine/online_placement.h):
//  * Forward sweep: the last recorded state is the working state (like revolve's current state); when
//    the next record arrives it is a checkpoint candidate. The first c candidates are kept. From then on
//    the c checkpoints s_0 = 0 < s_1 < ... < s_{c-1} cut the trajectory into intervals L_i (the last
//    one up to the working state), interval i to be reversed with the c - i slots not held by earlier
//    checkpoints, T(L_i, c - i) forward steps. Up to N = beta(c, 2) and beyond beta(c, 3), the candidate
//    replaces the checkpoint j >= 1 that gives the least sum_i T(L_i, c - i) were the run to end at this
//    record, unless keeping the placement is cheaper (cost rule). For beta(c, 2) < N <= beta(c, 3) a
//    candidate is taken every third record, or when it lands on one of the positions revolve holds at
//    N = beta(c, 3) (then kept), and replaces the latest checkpoint whose merged interval stays within
//    what its slots reverse at repetition number 2 (three-step rule, as Stumm & Walther's second
//    algorithm; the details in engine/online_placement.h).
//  * Backward sweep, N known: x_{N-1} is the working state; interval j (last to first) is reversed by
//    the offline binomial schedule (BinomialSchedule) with the c - j slots not held by s_0..s_{j-1}.
// The forward steps, counted like revolve's T(N, c) (see binomial_checkpointing.h), are
//     (N - 1) + sum_i T(L_i, c - i)  >=  T(N, c),
// equal to predictedForwardSteps(N, c) exactly. What is known of them (tests/storage/
// online_checkpointing_test.cpp): equal to the offline optimum T(N, c) for every N <= beta(c, 2) + 1
// (c <= 60 checked), where Stumm & Walther prove their online algorithm optimal. No online rule can be
// at T(N, c) for every N up to beta(c, 2) + 2 (exhaustive search over every placement, c = 2..6), so
// one forward step above it somewhere in (beta(c, 2), beta(c, 3)] is the least possible there; the three-step
// rule is at most T(N, c) + 1 for every N <= beta(c, 3) when c <= 9 and T(N, c) + 2 for c = 10..60
// (worst ratio 1.071 at c = 2, 1.048 at c = 3, <= 1.025 for c >= 5). Beyond beta(c, 3), up to N = 10^5,
// measured at most 1.14 T(N, c) for c = 2 and 1.07 T(N, c) for c = 3..50 (the ratios per c in
// docs/guides/storage_strategies.md); no bound is proven there. c = 1: T(N, 1) exactly.
// Cost of the rules: O(1) evaluations of T per record and O(c) per replacement (cost rule), O(c) per
// candidate taken, about every third record (three-step rule).
// Memory: at most c checkpoints plus one working state, allocated on first use and charged with
// holdBytes(); it never exceeds the budget. counters().statesStored counts the checkpoint writes of
// the forward sweep plus the final working state x_{N-1} (the copy made at every step is not counted).
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
/// restored step (the last held position at or before it), reversed by revolve with c - j slots for
/// interval j. The strategy runs it with a visitor that copies states and recomputes, its prediction
/// (OnlineCheckpointing::predict) with one that counts: one code for both.
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
      schedule_.reset(interval_.length, checkpoints_ - interval_.index, false);
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
  /// (N - 1) + recomputed steps of this algorithm for N steps and c checkpoints, without states
  /// (the placement simulated step by step).
  static UnsignedInt128 predictedForwardSteps(std::int64_t steps, std::int64_t c);
  /// (N - 1) + sum_j T(L_j, c - j) for held positions (increasing, starting at 0) of N steps.
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
  void releaseAll();

  std::int64_t requestedCheckpoints_;
  bool stages_;
  internal::RecomputedStages recomputedStages_;  // stages=1
  std::int64_t activeCheckpoints_ = 0;
  internal::CostPlacement placement_;             // forward checkpoints, slot i holds positions()[i]
  std::vector<std::unique_ptr<double[]>> slots_;  // allocated on first use
  std::unique_ptr<double[]> working_;
  std::int64_t heldBytes_ = 0;
  bool workingValid_ = false;
  internal::OnlineReversal reversal_;  // backward sweep
};

}  // namespace hindsight
