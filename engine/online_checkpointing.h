// Strategy "online": checkpointing while the number of steps N is still unknown (adaptive steps),
// re-planned with the offline binomial schedule once N is known.
//
// Spec: online:budget=BYTES | online:checkpoints=C[,budget=BYTES]   (default budget 4 GiB).
// With only a budget, c = floor(budget / stateBytes) - 1 checkpoints (one state is the working state).
//
// Algorithm (a simple member of the family of Stumm & Walther 2010, "New algorithms for optimal online
// checkpointing", SIAM J. Sci. Comput. 32(2); and Wang, Moin & Iaccarino 2009, "Minimal repetition
// dynamic checkpointing algorithm for unsteady adjoint calculation", SIAM J. Sci. Comput. 31(4); it is
// neither paper's placement rule, see the bound below for what it guarantees):
//  * Forward sweep: the last recorded state is the working state (like revolve's current state); when
//    the next record arrives it becomes a checkpoint candidate. Checkpoints are equidistant with
//    spacing d, always all multiples of d among the candidates. While d = 1 every candidate is kept, up to
//    c of them (so N <= c + 1 costs no recomputation at all); from then on at most F = ceil(c / 2). When
//    a candidate at a multiple of d arrives and the limit is reached, every other checkpoint is dropped
//    and d doubles ("thinning", repeated if needed).
//  * Backward sweep, N known: x_{N-1} is the working state. The intervals between held checkpoints
//    s_0 = 0 < s_1 < ... < s_{k-1} are reversed last to first, interval j with the offline binomial
//    schedule (BinomialSchedule) and the c - j slots not held by s_0..s_{j-1}; the last interval ends
//    at N - 1.
// Guarantee (what the test asserts). Candidates are the positions 0..N-2. Thinning from d >= 2 happens
// only at a candidate F d <= N - 2 and from d = 1 at candidate c >= F, so d <= max(1, 2(N-2)/F). If d = 1
// every interval has one step and nothing is recomputed; otherwise at most F checkpoints are held, every
// interval has at most d steps and at least c - F + 1 = floor(c/2) + 1 slots. Since
// T(l, s) <= rep(l, s) l (the line r l - beta(s+1, r-1) with beta >= 0) and rep grows with l and falls
// with s, the total number of forward steps, counted like revolve's T(N, c) (see binomial_checkpointing.h),
//     (N - 1) + recomputedSteps <= (N - 1) + N rep(d, floor(c/2) + 1),
// and it equals predictedForwardSteps(N, c) exactly. For c = 1 it is optimal, T(N, 1).
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

namespace hindsight {

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
  static std::vector<std::string> keys() { return {"checkpoints", "budget", "stages"}; }

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
  /// Forward-sweep checkpoint limit F = ceil(c / 2).
  static std::int64_t forwardCheckpoints(std::int64_t c) { return internal::OnlinePlacement::forwardCheckpoints(c); }
  /// The final spacing d of the forward sweep for N steps.
  static std::int64_t finalSpacing(std::int64_t steps, std::int64_t c);
  /// (N - 1) + recomputed steps of this algorithm for N steps and c checkpoints, without states.
  static UnsignedInt128 predictedForwardSteps(std::int64_t steps, std::int64_t c);
  /// The guaranteed upper bound (N - 1) + N rep(d, floor(c/2) + 1) of the header comment.
  static UnsignedInt128 forwardStepBound(std::int64_t steps, std::int64_t c);

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;
  void doRecordStepData(std::int64_t step, ConstVectorRef data) override;
  bool doRestoreStepData(std::int64_t step, VectorRef data) override;
  double* slot(std::int64_t index);
  void commitWorkingState(std::int64_t position);
  void releaseAll();

  std::int64_t requestedCheckpoints_;
  bool stages_;
  internal::RecomputedStages recomputedStages_;  // stages=1
  std::int64_t activeCheckpoints_ = 0;
  internal::OnlinePlacement placement_;           // forward checkpoints, slot i holds positions()[i]
  std::vector<std::unique_ptr<double[]>> slots_;  // allocated on first use
  std::unique_ptr<double[]> working_;
  std::int64_t heldBytes_ = 0;
  bool workingValid_ = false;
  // Backward sweep: the interval being reversed.
  std::int64_t interval_ = -1;
  std::int64_t intervalStart_ = 0;
  BinomialSchedule schedule_;
};

}  // namespace hindsight
