// Strategy "cams": optimal stage-aware checkpointing for a known number of steps N.
//
// Spec: cams:budget=BYTES | cams:checkpoints=C   [,online=1]   (exactly one of budget and checkpoints;
// C in [1, 10^6]; checkpoints=C means the byte budget of binomial:checkpoints=C, i.e. C + 1 states).
//
// Idea (Zhang & Constantinescu, "Optimal checkpointing for adjoint multistage time-stepping schemes",
// arXiv 2106.13879, the CAMS algorithm behind PETSc's TSTrajectory "memory" type; Maddison's mixed
// checkpointing in the checkpoint_schedules package): a checkpoint may hold either the state x_k
// (1 memory unit = one state) or the step record of step k, the state plus the step's stage values
// (w units; w = 1 + stepDataSize / n, 4 for rk4). The adjoint step of a step whose record is held
// evaluates no right-hand side; every other adjoint step recomputes its step's stages. The stage values
// of a record are captured the first time the schedule advances through its step (for free in the
// forward sweep, and in the backward sweep because the part to the right of a checkpoint always
// starts by advancing from it). The written-out model and recurrences below are hindsight's own (read
// from the paper's idea, not its code).
//
// Cost model, counted in step evaluations (one step = its stages' right-hand sides): the forward sweep
// (N), the recomputed steps, and one recomputation per adjoint step whose stage values are not held.
// With x_0 of an interval held and m free units, F(l, m) is the least cost to reverse l steps:
//   F(1, m) = 1;   F(l, m) = min of
//     l (l + 1) / 2                                       (no checkpoint: replay from x_0 for every step)
//     min_k  k + F(k, m) + F(l - k, m - 1)                 (state checkpoint at k, m >= 1)
//     min_k  k + F(k, m) + F_R(l - k, m - w)               (record of step k, m >= w)
//     F(l, m - (w - 1)) - 1                                (w >= 2: x_0, a state on top of the stack, grows
//                                                          into the record of step 0, captured by the
//                                                          interval's first advance)
// with F_R(j, m) = F(j, m) - [j >= 2] (the record saves its step's adjoint recomputation; for j = 1 the
// capture itself costs the advance it saves). H(l, m) is the same for the interval the forward sweep runs
// through, where advancing is free: H(1, m) = 1 and the two checkpoint terms read F(k, m) + H(l - k, m - 1)
// and F(k, m) + H(l - k, m - w) - 1. With M units in all, the whole run costs
//   E(N, M) = N + min(H(N, M - 1), H(N, M - w) - 1)       (x_0 held as a state or as a record).
// Without records (w > M) this is the optimum over M slots of engine/binomial_checkpointing.h
// (binomial:checkpoints=M-1: revolve with M slots over the positions 0..N, T(N + 1, M) - N recomputed
// steps), plus N adjoint recomputations; records can only lower it (tests compare both strategies). The
// k-searches are exact: the rows are not convex in l (a record serves two steps, so parity shows), but each
// row stays within a few units of its greatest convex minorant, kept as the row grows; the minorants give a
// convex lower bound of the cost in k (computed exactly, in 128-bit integer arithmetic: a rounded bound could
// prune the optimum), so only the k whose bound is below the best found so far (one interval, bracketed
// from the previous length's split and bisected) are evaluated. Planning time is O(N M) searches, each
// scanning the flat part of that interval: measured 2.8 s for N = 3e4, M = 11 and 8.6 s for N = 4096, M =
// 1001 (bench/RESULTS.md). Tests check the result against the exhaustive O(l) search and against brute-force
// enumeration of all schedules for small N.
//
// Memory: the checkpoints form a stack; the strategy allocates M units once in begin() and charges
// them with holdBytes(): offline at most (N + 1) w units; the online mode, where N is unknown, at most
// 10^6 + 1 units, all at begin() (a budget of B bytes allocates min(B, 10^6 + 1 states)). The plan
// tables (16 bytes per (l, m) pair for l <= N, m <= M, 8 for N <= 2^15; the online mode's interval plans
// half of that, replay tables only; plus the values of w + 1 rows while they are built) are planning data,
// not trajectory data, and are not charged; begin() refuses N (M + 1) > kMaxTableEntries with a message
// naming online=1.
//
// Adaptive steps (TrajectoryInfo.stepCount unknown) or the key online=1: the online mode, see
// the online mode below (checkpoints placed as `online` places them, each interval reversed by the
// optimal plan for its length and the units left, or by revolve when the plan's tables for it would exceed
// cams::kMaxIntervalPlanSteps; M >= 2 units needed). Without online=1, fixed steps whose
// table exceeds kMaxTableEntries are refused with a message pointing to online=1. With an integrator that
// offers no step data (generalized-alpha) records are impossible and the plan is revolve's.
#pragma once

#include <hindsight/engine/online_placement.h>
#include <hindsight/engine/storage_registry.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <iosfwd>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {
namespace cams {

/// Counts of a plan, as a real run reports them (all in steps; multiply by the right-hand sides per
/// step for rhs evaluations).
struct PlanCounts {
  std::int64_t steps = 0;
  std::int64_t forwardSteps = 0;           ///< N, the forward sweep
  std::int64_t recomputedSteps = 0;        ///< advances in the backward sweep (counters().recomputedSteps)
  std::int64_t adjointRecomputations = 0;  ///< adjoint steps without held stage values
  std::int64_t statesStored = 0;           ///< state checkpoints written (any sweep)
  std::int64_t forwardStores = 0;          ///< what the forward sweep stores (counters().statesStored)
  std::int64_t recordsStored = 0;          ///< step records filled (counters().stepDataStored)
  std::int64_t peakUnits = 0;              ///< most memory units held at once
  /// forwardSteps + recomputedSteps + adjointRecomputations: the plan's cost E(N, M).
  std::int64_t stepEvaluations() const { return forwardSteps + recomputedSteps + adjointRecomputations; }
};

/// One action of the schedule (for `hindsight schedule --actions` and tests).
struct Action {
  enum class Kind { StoreState, StoreRecord, Advance, Deliver } kind;
  std::int64_t from = 0;  ///< Advance: from step `from` to `to`; Store*/Deliver: position in `from`
  std::int64_t to = 0;
  bool withStageValues = false;  ///< Deliver: the adjoint step gets held stage values
};

/// The optimal plan for N steps, M memory units and records of w units (w > M: no records). Pure and
/// model-free. Throws std::invalid_argument when N < 1, M < 1, w < 1 or N (M + 1) > kMaxTableEntries.
class Plan {
 public:
  static constexpr std::int64_t kMaxTableEntries = 12'500'000;
  Plan(std::int64_t steps, std::int64_t memoryUnits, std::int64_t recordUnits);
  /// The same plan from the exhaustive O(l) search over every split (for tests; small N only).
  static Plan exhaustive(std::int64_t steps, std::int64_t memoryUnits, std::int64_t recordUnits);
  /// The replay tables alone (decision(false, ...)): what the online mode's intervals read, each reversed
  /// from a checkpoint the forward run stored, with no sweep running through it. They do not depend on the
  /// sweep tables, so they are the full plan's, at half its time and memory; optimalStepEvaluations() and
  /// anchorIsRecord() are not computed (-1, false) and recordForward cannot run on it.
  static Plan replayOnly(std::int64_t steps, std::int64_t memoryUnits, std::int64_t recordUnits);

  std::int64_t steps() const { return steps_; }
  /// The units the plan uses: min(M, (N + 1) w) (more cannot help).
  std::int64_t memoryUnits() const { return units_; }
  std::int64_t recordUnits() const { return recordUnits_; }
  /// E(N, M) from the recurrences.
  std::int64_t optimalStepEvaluations() const { return optimum_; }
  static constexpr std::int32_t kUpgradeAnchor = std::numeric_limits<std::int32_t>::min();
  /// The decision for an interval: 0 no checkpoint, k > 0 state checkpoint at offset k, k < 0 record at -k,
  /// kUpgradeAnchor: the anchor becomes a record (replay intervals only).
  std::int64_t decision(bool sweep, bool recordAnchor, std::int64_t l, std::int64_t m) const;
  bool anchorIsRecord() const { return anchorIsRecord_; }

 private:
  Plan() = default;
  void build(bool exhaustiveSearch, bool sweepTables = true);
  std::int64_t steps_ = 0, units_ = 0, recordUnits_ = 0, optimum_ = 0;
  bool anchorIsRecord_ = false;
  // Per (sweep, anchor kind) a table, row m holding l = 0..N; decisions as int32 (N < 2^31 is checked).
  std::vector<std::int32_t> decisions_[4];
  // The same as int16 when every decision fits (N <= 2^15: offsets below 2^15, kUpgradeAnchor kept as
  // INT16_MIN): half the memory of the online mode's interval plans (2^15 steps at most) and of short
  // exact plans.
  static constexpr std::int64_t kMaxNarrowSteps = std::int64_t{1} << 15;
  std::vector<std::int16_t> narrowDecisions_[4];
  bool narrow_ = false;
  std::int32_t storedDecision(int table, std::size_t index) const {
    if (!narrow_) return decisions_[table][index];
    const std::int16_t d = narrowDecisions_[table][index];
    return d == std::numeric_limits<std::int16_t>::min() ? kUpgradeAnchor : d;
  }
  void storeDecision(int table, std::size_t index, std::int64_t decision) {
    if (!narrow_) {
      decisions_[table][index] = static_cast<std::int32_t>(decision);
    } else {
      narrowDecisions_[table][index] = decision == kUpgradeAnchor ? std::numeric_limits<std::int16_t>::min()
                                                                  : static_cast<std::int16_t>(decision);
    }
  }
};

/// Runs the plan without states: counts, and optionally the action stream.
PlanCounts simulate(const Plan& plan, std::vector<Action>* actions = nullptr);

/// Online mode (adaptive steps, or cams:...,online=1): the forward sweep keeps checkpoints by the rule of
/// `online` (engine/online_placement.h) with c = M - 1 of the M units, the last state being the working
/// state; once N is known, the intervals between held checkpoints are reversed last to first, interval j
/// by the plan's replay tables with the M - j - 1 units not held by checkpoints 0..j. One plan serves all
/// intervals: its rows hold every length up to the longest interval and every unit count up to M - 1.
///
/// Intervals longer than kMaxIntervalPlanSteps, or whose plan would exceed Plan::kMaxTableEntries, are
/// reversed by revolve (engine/binomial_checkpointing.h's BinomialSchedule) with the same units, without
/// records: the plan's time grows faster than the interval times its units (a search per entry over a
/// range that grows with the interval), and the longest interval grows with N (about 2N/c), so an optimal
/// plan for it took 157 s at N = 10^6, C = 10 and was refused at 2^24 steps. 2^15 steps plan in about
/// 3 s with 11 units (bench/RESULTS.md, "Stage-aware storage"). Revolve is that plan without records (the
/// file comment); the longer intervals give up only what records would save.
constexpr std::int64_t kMaxIntervalPlanSteps = std::int64_t{1} << 15;
/// The longest interval the online mode reverses by its plan, for intervals up to `longest` steps and M
/// units: at most `longest`, kMaxIntervalPlanSteps and what Plan::kMaxTableEntries allows with M - 1 units.
std::int64_t onlineIntervalPlanSteps(std::int64_t longest, std::int64_t memoryUnits,
                                     std::int64_t recordUnits);
/// The plan for intervals up to `longest` steps (at most onlineIntervalPlanSteps) with M - 1
/// units, reusing `cached` when it covers them (the rows of a plan do not depend on its N).
const Plan& onlineIntervalPlan(std::unique_ptr<Plan>& cached, std::int64_t longest, std::int64_t memoryUnits,
                               std::int64_t recordUnits);
/// Counts of the online mode for N fixed steps (as a run with cams:...,online=1 reports them); the plan is
/// built for the longest interval (or reused when `plan` already covers it).
PlanCounts simulateOnline(std::int64_t steps, std::int64_t memoryUnits, std::int64_t recordUnits,
                          std::unique_ptr<Plan>* plan = nullptr);

/// Smallest cost over every schedule of the model by exhaustive enumeration of all action sequences
/// (exponential; for tests with N <= 7).
std::int64_t bruteForceStepEvaluations(std::int64_t steps, std::int64_t memoryUnits,
                                       std::int64_t recordUnits);

/// The executor: drives a plan through a visitor with
///   store(ref, position, isRecord)   copy the current state into a new checkpoint (stack offset ref);
///   upgrade(ref, position)           the state checkpoint ref becomes a record (its stage values follow);
///   capture(ref, step)               the stage values of `step` just advanced go into record `ref`;
///   load(ref)                        copy checkpoint ref's state into the current state;
///   advance(from, to)                recompute from position `from` to `to` (one step at a time: the
///                                    executor calls capture right after the step a pending record needs);
///   deliver(position, ref, filled)   the current state is x_position; ref >= 0 with filled: the
///                                    record ref holds the step's stage values.
/// Offsets are in units of one state; a record takes recordUnits consecutive units.
class Executor {
 public:
  void reset(const Plan* plan);
  /// Online mode: reverse only the interval [position, position + length) from the state checkpoint at
  /// `position` (unit ref, held by the caller below ref + 1), with `units` free units above it, by the
  /// plan's replay tables (decisions for any length <= plan->steps() and units <= plan->memoryUnits());
  /// a longer interval by revolve over units ref..ref + units (onlineIntervalPlan).
  void beginInterval(const Plan* plan, std::int64_t position, std::int64_t ref, std::int64_t length,
                     std::int64_t units);
  /// Capacity for intervals of up to `checkpoints` checkpoints above their anchor (no allocation later).
  void reserve(std::int64_t checkpoints);
  /// Forward sweep: what to keep of x_n (n = 0..N-1 in order): -1 nothing, else the ref; *isRecord tells
  /// whether the step's stage values (given by the forward sweep) go with it.
  std::int64_t recordForward(std::int64_t n, bool* isRecord);
  /// Backward sweep, e = N-1, ..., 0 in order.
  template <typename Visitor>
  void restoreStep(std::int64_t e, Visitor& visitor);
  std::int64_t heldUnits() const { return top_; }

  /// How the checkpoint stored last (by recordForward, or reported to the visitor's store) is used until
  /// it is delivered: the advances from it (each reads its state) and whether its step's stage values are
  /// held then. Read from the plan's decisions for the interval it anchors, without running it: the action
  /// stream (storage/checkpoint_actions.cpp) must know at a store whether the state is read back at all,
  /// and at each read whether it is the last.
  struct AnchorUse {
    std::int64_t advances = 0;
    bool filledAtDelivery = false;
  };
  AnchorUse lastStoredUse() const;

 private:
  struct Checkpoint {
    std::int64_t position;
    std::int64_t ref;
    bool record;
    bool filled;
  };
  struct Task {
    std::int64_t anchor;  // index into checkpoints_
    std::int64_t length;
    std::int64_t units;  // free units
    bool sweep;          // H mode: the forward sweep has run through (its checkpoints are stored)
    std::int64_t next;   // no-checkpoint replay: the next position to deliver (-1: not started)
  };
  std::int64_t push(std::int64_t position, bool record);
  void pop();
  template <typename Visitor>
  void advanceFrom(std::int64_t index, std::int64_t to, Visitor& visitor);
  // An interval longer than the plan: revolve's slot s is unit revolveRef_ + s.
  template <typename Visitor>
  struct RevolveAdapter {
    Executor& executor;
    Visitor& visitor;
    void loadWorking() { assert(false); }  // reset without a working state
    void load(std::int64_t slot) {
      visitor.load(executor.revolveRef_ + slot);
      executor.revolveAt_ = executor.revolvePositions_[static_cast<std::size_t>(slot)];
    }
    void store(std::int64_t slot) {
      executor.revolvePositions_[static_cast<std::size_t>(slot)] = executor.revolveAt_;
      visitor.store(executor.revolveRef_ + slot, executor.revolveAt_, false);
    }
    void advance(std::int64_t from, std::int64_t to) {
      visitor.advance(executor.revolveStart_ + from, executor.revolveStart_ + to);
      executor.revolveAt_ = executor.revolveStart_ + to;
    }
  };
  BinomialSchedule revolve_;
  bool revolveInterval_ = false;
  std::int64_t revolveStart_ = 0, revolveRef_ = 0, revolveAt_ = 0;
  std::vector<std::int64_t> revolvePositions_;  // per slot, the position it holds

  const Plan* plan_ = nullptr;
  std::vector<Checkpoint> checkpoints_;
  std::vector<Task> tasks_;
  std::int64_t top_ = 0;    // units held
  std::int64_t limit_ = 0;  // top_ never exceeds it
  // Forward sweep: the chain of the sweep interval.
  std::int64_t chainLength_ = 0, chainUnits_ = 0, chainPosition_ = 0, nextForward_ = 0;
  bool nextForwardRecord_ = false;
  // The interval the checkpoint stored last anchors first (lastStoredUse).
  struct Stored {
    bool sweep = false, record = false, filled = false;
    std::int64_t length = 0, units = 0;
  } lastStored_;
};

template <typename Visitor>
void Executor::advanceFrom(std::int64_t index, std::int64_t to, Visitor& visitor) {
  Checkpoint& c = checkpoints_[static_cast<std::size_t>(index)];
  visitor.load(c.ref);
  for (std::int64_t k = c.position; k < to; ++k) {
    visitor.advance(k, k + 1);
    if (k == c.position && c.record && !c.filled) {
      visitor.capture(c.ref, k);
      c.filled = true;
    }
  }
}

template <typename Visitor>
void Executor::restoreStep(std::int64_t e, Visitor& visitor) {
  if (revolveInterval_) {
    RevolveAdapter<Visitor> adapter{*this, visitor};
    revolve_.restoreStep(e - revolveStart_, adapter);
    visitor.deliver(e, -1, false);
    return;
  }
  for (;;) {
    Task& task = tasks_.back();
    const Checkpoint anchor = checkpoints_[static_cast<std::size_t>(task.anchor)];
    if (task.length == 1 || task.next == anchor.position) {
      // Deliver the anchor itself; the interval is done.
      assert(anchor.position == e);
      visitor.load(anchor.ref);
      visitor.deliver(anchor.position, anchor.ref, anchor.record && anchor.filled);
      tasks_.pop_back();
      pop();
      return;
    }
    if (task.next > anchor.position) {
      // No-checkpoint replay: advance from the anchor to the next position and deliver it.
      const std::int64_t position = task.next;
      assert(position == e);
      --task.next;
      advanceFrom(tasks_.back().anchor, position, visitor);
      visitor.deliver(position, -1, false);
      return;
    }
    const std::int64_t k = plan_->decision(task.sweep, anchor.record, task.length, task.units);
    if (k == Plan::kUpgradeAnchor) {
      Checkpoint& c = checkpoints_[static_cast<std::size_t>(task.anchor)];
      assert(!task.sweep && !c.record && task.anchor + 1 == static_cast<std::int64_t>(checkpoints_.size()));
      c.record = true;
      c.filled = false;
      top_ += plan_->recordUnits() - 1;
      task.units -= plan_->recordUnits() - 1;
      visitor.upgrade(c.ref, c.position);
      continue;
    }
    if (k == 0) {
      task.next = anchor.position + task.length - 1;
      continue;
    }
    const bool record = k < 0;
    const std::int64_t offset = record ? -k : k;
    const std::int64_t units = record ? plan_->recordUnits() : 1;
    // The left part keeps this task's anchor and units; the right part starts at the new checkpoint.
    const Task left{task.anchor, offset, task.units, false, -1};
    Task right{0, task.length - offset, task.units - units, task.sweep, -1};
    tasks_.pop_back();
    tasks_.push_back(left);
    if (right.sweep) {
      // The forward sweep stored it, right above the anchor on the stack, stage values included.
      right.anchor = left.anchor + 1;
      assert(checkpoints_[static_cast<std::size_t>(right.anchor)].position == anchor.position + offset);
    } else {
      advanceFrom(left.anchor, anchor.position + offset, visitor);
      right.anchor = push(anchor.position + offset, record);
      lastStored_ = Stored{false, record, false, right.length, right.units};
      visitor.store(checkpoints_.back().ref, anchor.position + offset, record);
    }
    tasks_.push_back(right);
  }
}

}  // namespace cams

class CamsCheckpointing final : public TrajectoryStorage {
 public:
  static constexpr std::int64_t kMaxCheckpoints = 1'000'000;
  /// The byte budget of cams:checkpoints=C (the strategy holds (C + 1) states of it), like binomial's.
  static constexpr std::int64_t kDefaultBudget = std::int64_t{4} << 30;
  /// checkpoints > 0: the budget of binomial:checkpoints=C, (C + 1) states, fixed at begin(); otherwise
  /// budgetBytes is the budget.
  /// online: the online mode (cams::simulateOnline) even for fixed steps; adaptive steps always use it.
  CamsCheckpointing(std::int64_t checkpoints, std::int64_t budgetBytes, bool online = false);
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  /// The registry's prediction (engine/storage_registry.h): the counts of N fixed steps.
  static void predict(const TrajectoryStorage& storage, const StorageSpec& spec,
                      const PredictionRequest& request, SchedulePrediction& p);
  /// The registry's action stream: the plan's actions (cams::simulate), step records of `stages` state
  /// units; the online mode (online=1) is refused, its placement not being a fixed plan.
  static void writeActions(const TrajectoryStorage& storage, const StorageSpec& spec,
                           const PredictionRequest& request, std::ostream& out);
  /// The record units of the plans predict and writeActions make for an explicit Runge-Kutta method of
  /// `stages` stages: the state and S - 1 stage states; none (more than any budget) for one stage.
  static std::int64_t recordUnitsOfStages(int stages) {
    return stages > 1 ? stages : std::numeric_limits<std::int32_t>::max();
  }

  std::string spec() const override;
  bool isExact() const override { return true; }
  bool keepsStepData() const override { return true; }
  /// Records of stage values only: its plans count records in state units (S for an S-stage method).
  bool keepsRhsData() const override { return false; }
  /// Memory units (states) the strategy has for states of stateBytes: C + 1, or the budget's states.
  std::int64_t memoryUnits(std::int64_t stateBytes) const {
    return checkpoints_ > 0 ? checkpoints_ + 1 : budgetBytes() / stateBytes;
  }
  /// The units a run uses for states of stateBytes: memoryUnits, in the online mode at most 10^6 + 1 (N
  /// is unknown when they are allocated). Throws std::invalid_argument naming cams.budget when they are
  /// fewer than the mode needs (one; the online mode two: a checkpoint and the working state).
  std::int64_t usableUnits(std::int64_t stateBytes, bool online) const;
  /// The plan of the current run (after begin(); in the online mode after the forward sweep), or null.
  const cams::Plan* plan() const { return onlineRun_ ? intervalPlan_.get() : plan_.get(); }
  /// Whether the spec asks for the online mode (online=1).
  bool onlineRequested() const { return online_; }
  /// Whether the current run uses the online mode.
  bool onlineRun() const { return onlineRun_; }

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRecordStepData(std::int64_t step, ConstVectorRef data) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;
  bool doRestoreStepData(std::int64_t step, VectorRef data) override;
  void releaseAll();

  std::int64_t checkpoints_;
  bool online_;
  bool onlineRun_ = false;
  std::unique_ptr<cams::Plan> plan_;
  // Online mode: the forward placement, the working state (unit units_ - 1), the interval plan (kept
  // across runs while it covers the longest interval), the interval being reversed.
  internal::OnlinePlacement placement_;
  bool workingValid_ = false;
  std::int64_t recordUnits_ = 0;
  std::unique_ptr<cams::Plan> intervalPlan_;
  std::int64_t intervalStart_ = -1, intervalIndex_ = 0;
  cams::Executor executor_;
  std::unique_ptr<double[]> memory_;  // units x n doubles
  std::int64_t heldBytes_ = 0;
  std::int64_t units_ = 0;
  std::int64_t pendingRecord_ = -1;    // forward: ref of the record whose stage values come next
  const double* delivered_ = nullptr;  // stage values for restoreStepData, or null
};

}  // namespace hindsight
