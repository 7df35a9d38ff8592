// Schedules as data: what a storage strategy will do for N fixed steps,
// computed without running a model, by the same plan code the strategies execute (so a prediction
// and a run cannot disagree; tests compare them counter by counter).
//
// Cost model (Aupy, Herrmann, Hovland & Robert 2016, "Optimal multistage algorithm for adjoint
// computation", SIAM J. Sci. Comput. 38(3); Herrmann & Pallez 2020, "H-Revolve", ACM TOMS 46(2)):
//   uf  one forward step (also one recomputed step),     ub  one adjoint step,
//   wd  writing one state to the disk level,             rd  reading one state from the disk level;
// RAM copies are free. A run of N steps costs N uf + N ub (fixed) plus the schedule's part
//     R uf + W wd + Q rd       (R recomputed steps, W disk writes, Q disk reads),
// which is what a plan minimizes and what `predictedSeconds` reports.
//
// The game (what "all schedules" means in the tests): ram slots and disk slots each hold one state;
// the forward sweep passes x_0 .. x_{N-1} once for free and may copy the state at hand into a free
// slot; afterwards x_{N-1}, x_{N-2}, ..., x_0 must be produced in turn, by reading a slot and
// advancing (each advance a recomputed step), copying states into free slots on the way. The state at
// hand is lost after each produced state (the adjoint step consumes it); x_{N-1} too must therefore be
// in a slot when the forward sweep ends (a "working state") or be recomputed from one. With one level
// the game's optimum is T(N + 1, S) - N recomputed steps for S slots, which `binomial` attains
// (engine/binomial_checkpointing.h).
//
// The two-level plan (TwoLevelPlan) chooses, by the cost model, the cheapest of two families, both
// executed by BinomialSchedule (engine/binomial_checkpointing.h):
//   leaves(K)   cut [0, N) into K balanced leaves (the last one the shortest); the forward sweep
//               writes the first state of leaves 0..K-2 to disk slots 0..K-2 (write-once); the last
//               leaf is reversed by revolve over the RAM slots with its last state as working state;
//               every other leaf reads its first state once from disk into RAM slot 0 and is reversed
//               by revolve over all RAM slots. K = 1 is revolve in RAM alone. This is Disk-Revolve's
//               structure (disk checkpoints written in the first forward sweep only, revolve in memory
//               between them), which Aupy et al. prove optimal when the disk is not the bottleneck;
//               every K in [1, min(N, diskSlots + 1)] is evaluated in closed form.
//   allSlots    revolve over every slot: BinomialSchedule with ramSlots - 1 + diskSlots checkpoints
//               plus the working state in RAM; checkpoint depth d < diskSlots (the bottom of revolve's
//               stack, the long-lived checkpoints) lives on disk, the rest in RAM. With free disk
//               (wd = rd = 0) it is revolve with all slots, the optimum of the game; its disk traffic is
//               counted by running the schedule without states (O(N)), so it is considered for
//               N <= kMaxSimulatedSteps only.
//   dynamic     the optimum over the schedules that keep their checkpoints as a stack (each segment
//               [p, e] is reversed from the checkpoint at p, which stays until the segment is done):
//               the dynamic programme of H-Revolve (Herrmann & Pallez 2020) for two levels with bounded
//               RAM and disk, written for this game -- KLevelPlan::optimal (storage/k_level_plan.h) with
//               one level below RAM. Disk slots are reused as soon as their segment is done, states may
//               be written to disk in the backward sweep, and a checkpoint at hand may move between the
//               levels. Computed when N^2 (R + 1)(D + 1) <= kMaxDynamicWork (R, D the slots, at most N
//               each).
//   hierarchical  beyond the dynamic programme's limit: KLevelPlan::graded with RAM and disk, H-Revolve's
//               structure with moves, the lengths 1..4096 exact and longer ones on a geometric grid; where
//               its tables cannot hold every slot within KLevelPlan::kMaxGradedCells, a coarser grid of
//               lengths (KLevelPlan::kGradedGrids) with every slot, and only beyond the coarsest grid
//               fewer disk slots -- or, where cheaper, KLevelPlan::segmented: forward stores on nearly every
//               disk slot at equal spacing, each segment reversed by the programme over short lengths (within
//               1 % of the full search, of the dynamic programme and of the finest grid with every slot
//               wherever they were measured, also for disks of N slots; docs/theory/storage.md, "Large
//               disks"). Considered for N <= kMaxSimulatedSteps (its
//               counts are a walk of the plan), for any number of slots.
//   Both stack plans are KLevelPlan::choose's, the planner of the K-level form, so a spec with one level
//   below RAM plans alike in either form.
// choose() returns the cheapest plan it evaluated; where the best leaves plan attains the game's lower
// bound (lowerBound()) it is optimal and nothing else is evaluated (a large disk: one 2^24-step walk and a
// graded programme saved). The tests compare it with a brute-force search over
// every schedule of the game (N <= 7: equal in every case tried) and, for larger N, the dynamic
// programme with an independent memoised recursion of the same recurrences -- see docs/theory/storage.md,
// "Two-level schedules".
#pragma once

#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/storage_registry.h>
#include <hindsight/storage/k_level_plan.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

namespace hindsight {

/// Limits of `hindsight schedule` and Python's schedule(): N fixed steps, bytes of one state (a run's
/// TrajectoryInfo.stateSize is an int of doubles), right-hand sides per step, and each cost in seconds
/// (so that N (uf + ub) and every count times a cost stay finite).
constexpr std::int64_t kMaxScheduleSteps = 4'000'000'000'000'000'000;
constexpr std::int64_t kMaxScheduleStateBytes = std::int64_t{8} * 2147483647;
constexpr int kMaxScheduleStages = 64;
constexpr double kMaxScheduleCost = 1e30;

/// Reads an integer in [minimum, maximum] written as digits ("30000") or in exact scientific notation
/// ("1e9", "2.5e6"; the value must be an integer), with nothing after it. Throws std::invalid_argument
/// naming `field` and the allowed range otherwise (also for "1.5", "1e17x", "" and overflow).
std::int64_t parseScheduleInteger(const std::string& text, const std::string& field, std::int64_t minimum,
                                  std::int64_t maximum);

/// Receives a plan's actions (tests and `hindsight schedule --actions`; the strategies execute them).
/// Positions are grid points 0..N-1; "current" is the state at hand.
///   store(level, slot)     copy the current state into the slot (forward: the recorded state)
///   load(level, slot)      the current state becomes the slot's content
///   advance(from, to)      recompute from grid point `from` to `to`
/// Every restore ends with the current state equal to x_e.

/// The two-level plan for N >= 1 steps, ramSlots >= 1 and diskSlots >= 0 (see the file comment).
class TwoLevelPlan {
 public:
  enum class Kind { kLeaves, kAllSlots, kDynamic, kHierarchical };
  static constexpr std::int64_t kMaxSimulatedSteps = std::int64_t{1} << 24;
  /// The dynamic programme is solved when N^2 (R + 1)(D + 1) is at most this (2-3 s; KLevelPlan::kMaxWork
  /// for two levels).
  static constexpr std::int64_t kMaxDynamicWork = std::int64_t{1} << 28;

  /// The cheapest plan under `costs`. Throws std::invalid_argument when the slots cannot reverse N
  /// steps (N >= 2 needs ramSlots >= 2, or ramSlots == 1 and a disk slot).
  static TwoLevelPlan choose(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                             const ScheduleCosts& costs);
  /// The cheapest of the closed-form families alone (leaves, allSlots), as choose() compares them with the
  /// stack schedule (what choose() returned beyond the tables' limits before graded() planned there).
  static TwoLevelPlan families(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                               const ScheduleCosts& costs);
  /// replayLast: no working state; the first restore replays x_{N-1} from the top checkpoint, which
  /// frees a slot for revolve (better when slots are few: the game does not get x_{N-1} for free).
  static TwoLevelPlan leaves(std::int64_t steps, std::int64_t ramSlots, std::int64_t leafCount,
                             std::int64_t lastLength, bool replayLast);
  static TwoLevelPlan allSlots(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                               bool replayLast);
  /// The optimal stack schedule by dynamic programming (file comment). Throws std::invalid_argument when
  /// the work exceeds kMaxDynamicWork or the slots cannot reverse N steps. Polls pollInterrupt()
  /// (engine/interrupt.h) once per segment length.
  static TwoLevelPlan dynamic(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                              const ScheduleCosts& costs);
  /// Whether dynamic() is within kMaxDynamicWork for these sizes.
  static bool dynamicAffordable(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots);
  /// A lower bound on every schedule's cost: of the N states the backward sweep consumes, at most R come
  /// free (held in RAM when the forward sweep ends), at most D more without a recomputed step (held on
  /// disk then: written and read, wd + rd), every other one ends an advance (uf):
  ///   uf max(0, N - R - D) + min(uf, wd + rd) min(D, max(0, N - R)).
  static double lowerBound(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                           const ScheduleCosts& costs);

  Kind kind() const { return kind_; }
  std::int64_t steps() const { return steps_; }
  std::int64_t leafCount() const { return leafCount_; }
  std::int64_t lastLeafLength() const { return lastLength_; }
  bool replaysLast() const { return replayLast_; }
  /// Slots the plan uses at the most (RAM includes the working state).
  std::int64_t ramSlotsUsed() const { return ramSlotsUsed_; }
  std::int64_t diskSlotsUsed() const { return diskSlotsUsed_; }
  std::string describe() const;

  /// Counts (recomputedSteps, statesStored, reads and writes per level; peaks in slots via
  /// ramSlotsUsed/diskSlotsUsed). Closed form for leaves, a stateless run for allSlots.
  struct Counts {
    std::int64_t recomputedSteps = 0, statesStored = 0;
    std::int64_t ramWrites = 0, ramReads = 0, diskWrites = 0, diskReads = 0;
    double cost(const ScheduleCosts& c) const {
      return static_cast<double>(recomputedSteps) * c.forwardStep +
             static_cast<double>(diskWrites) * c.diskWrite + static_cast<double>(diskReads) * c.diskRead;
    }
  };
  const Counts& counts() const { return counts_; }
  /// The counts of one pass (forward then backward) of the plan with a counting visitor, as the strategy
  /// runs it (O(N + actions); rewinds before and after).
  Counts walk();

  /// Forward sweep, n = 0, 1, ..., N-1 in order: stores of the recorded state.
  template <typename Visitor>
  void recordForward(std::int64_t n, Visitor& visitor);
  /// Backward sweep, e = N-1, ..., 0 in order.
  template <typename Visitor>
  void restoreStep(std::int64_t e, Visitor& visitor);
  /// Starts a new pass (forward then backward) over the same plan.
  void rewind();

 private:
  std::int64_t leafStart(std::int64_t leaf) const;
  std::int64_t leafLength(std::int64_t leaf) const;
  std::int64_t leafOf(std::int64_t n) const;
  std::int64_t leafSlots(std::int64_t leaf) const;
  Counts countLeaves() const;

  // kDynamic and kHierarchical: the KLevelPlan with RAM and disk (storage/k_level_plan.h), by value: each
  // copy of the plan executes on its own (the tables are shared).
  std::optional<KLevelPlan> stack_;
  static TwoLevelPlan fromStack(KLevelPlan stack);
  static TwoLevelPlan cheapest(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                               const ScheduleCosts& costs, bool stack);
  template <typename Visitor>
  struct LevelAdapter {
    Visitor& visitor;
    static StorageLevel level(int index) { return index == 0 ? StorageLevel::kRam : StorageLevel::kDisk; }
    void store(int index, std::int64_t slot) { visitor.store(level(index), slot); }
    void load(int index, std::int64_t slot) { visitor.load(level(index), slot); }
    void advance(std::int64_t from, std::int64_t to) { visitor.advance(from, to); }
  };

  // Maps BinomialSchedule's slots and relative positions onto levels and grid points.
  template <typename Visitor>
  struct Adapter {
    Visitor& visitor;
    std::int64_t offset;
    TwoLevelPlan& plan;
    void loadWorking() { visitor.load(StorageLevel::kRam, plan.ramSlotsUsed_ - 1); }
    void load(std::int64_t slot) {
      plan.mapSlot(slot, [&](StorageLevel l, std::int64_t s) { visitor.load(l, s); });
    }
    void store(std::int64_t slot) {
      plan.mapSlot(slot, [&](StorageLevel l, std::int64_t s) { visitor.store(l, s); });
    }
    void push(std::int64_t slot, std::int64_t position) {
      store(slot);
      plan.topSlot_ = slot;
      plan.topPosition_ = offset + position;
    }
    void advance(std::int64_t from, std::int64_t to) { visitor.advance(offset + from, offset + to); }
  };
  template <typename F>
  void mapSlot(std::int64_t slot, F&& f) const {
    if (kind_ == Kind::kAllSlots && slot < diskSlotsUsed_)
      f(StorageLevel::kDisk, slot);
    else
      f(StorageLevel::kRam, kind_ == Kind::kAllSlots ? slot - diskSlotsUsed_ : slot);
  }

  Kind kind_ = Kind::kLeaves;
  std::int64_t steps_ = 0;
  std::int64_t ramSlots_ = 0;
  std::int64_t leafCount_ = 1;
  std::int64_t lastLength_ = 0;
  std::int64_t ramSlotsUsed_ = 0;
  std::int64_t diskSlotsUsed_ = 0;
  std::int64_t revolveSlots_ = 0;  // allSlots: BinomialSchedule's slots
  bool replayLast_ = false;
  std::int64_t topPosition_ = 0, topSlot_ = 0;  // revolve's top checkpoint after the forward sweep
  struct NoActions {
    void loadWorking() {}
    void load(std::int64_t) {}
    void store(std::int64_t) {}
    void advance(std::int64_t, std::int64_t) {}
  };
  template <typename Visitor>
  void replayLast(std::int64_t start, std::int64_t e, Visitor& visitor);
  Counts counts_;
  BinomialSchedule schedule_;
  std::int64_t currentLeaf_ = -1;
};

template <typename Visitor>
void TwoLevelPlan::recordForward(std::int64_t n, Visitor& visitor) {
  if (stack_) {
    LevelAdapter<Visitor> adapter{visitor};
    stack_->recordForward(n, adapter);
    return;
  }
  if (kind_ == Kind::kAllSlots) {
    Adapter<Visitor> adapter{visitor, 0, *this};
    if (n == 0) {
      schedule_.reset(steps_, revolveSlots_, true);
      adapter.push(0, 0);
    } else {
      const std::int64_t slot = schedule_.recordForward(n);
      if (slot >= 0) adapter.push(slot, n);
    }
    if (n == steps_ - 1 && steps_ >= 2 && !replayLast_) visitor.store(StorageLevel::kRam, ramSlotsUsed_ - 1);
    return;
  }
  const std::int64_t leaf = leafOf(n);
  const std::int64_t start = leafStart(leaf);
  const std::int64_t length = leafLength(leaf);
  if (leaf < leafCount_ - 1) {
    if (n == start) visitor.store(StorageLevel::kDisk, leaf);
    return;
  }
  // The last leaf: revolve in RAM with its last state as the working state.
  Adapter<Visitor> adapter{visitor, start, *this};
  if (n == start) {
    schedule_.reset(length, leafSlots(leaf), true);
    currentLeaf_ = leaf;
    adapter.push(0, 0);
  } else {
    const std::int64_t slot = schedule_.recordForward(n - start);
    if (slot >= 0) adapter.push(slot, n - start);
  }
  if (n == steps_ - 1 && length >= 2 && !replayLast_) visitor.store(StorageLevel::kRam, ramSlotsUsed_ - 1);
}

template <typename Visitor>
void TwoLevelPlan::restoreStep(std::int64_t e, Visitor& visitor) {
  if (stack_) {
    LevelAdapter<Visitor> adapter{visitor};
    stack_->restoreStep(e, adapter);
    return;
  }
  if (kind_ == Kind::kAllSlots) {
    if (replayLast_ && e == steps_ - 1 && steps_ >= 2) {
      replayLast(0, e, visitor);
      return;
    }
    Adapter<Visitor> adapter{visitor, 0, *this};
    schedule_.restoreStep(e, adapter);
    return;
  }
  const std::int64_t leaf = leafOf(e);
  const std::int64_t start = leafStart(leaf);
  if (leaf != currentLeaf_) {
    // A new leaf (always entered at its last state): its first state from disk into RAM slot 0.
    currentLeaf_ = leaf;
    visitor.load(StorageLevel::kDisk, leaf);
    visitor.store(StorageLevel::kRam, 0);
    schedule_.reset(leafLength(leaf), leafSlots(leaf), false);
  }
  if (replayLast_ && e == steps_ - 1 && e > start) {
    replayLast(start, e, visitor);
    return;
  }
  Adapter<Visitor> adapter{visitor, start, *this};
  schedule_.restoreStep(e - start, adapter);
}

template <typename Visitor>
void TwoLevelPlan::replayLast(std::int64_t start, std::int64_t e, Visitor& visitor) {
  // x_{N-1} from revolve's top checkpoint; then the schedule goes on as if it had had the working state.
  Adapter<Visitor> adapter{visitor, start, *this};
  adapter.load(topSlot_);
  visitor.advance(topPosition_, e);
  NoActions none;
  schedule_.restoreStep(e - start, none);
}

/// What strategy `spec` does for N fixed steps: its registry row's prediction (engine/storage_registry.h;
/// predicted are full, disk, binomial (also stages=1, for an explicit Runge-Kutta method of `stages`
/// stages), online, cams, multilevel with either schedule). `costs` may be omitted (nullptr) for all but
/// multilevel's plan without costs= in its spec. Throws std::invalid_argument naming the flag or field
/// for bad input, and for strategies whose counters depend on the run (lossy, packed, hermite: "is not
/// predicted" and the row's reason).
/// `stageBytes`: the rhs data a problem keeps per stage with the stage values (PredictionRequest::
/// stageDataBytes; `hindsight schedule --stage-bytes`), a multiple of 8 in [0, kMaxScheduleStateBytes].
/// `lowerBound`: also bound the family's optimum from below (PredictionRequest::lowerBound; multilevel
/// plans only, `hindsight schedule --bound`).
SchedulePrediction predictSchedule(const std::string& spec, std::int64_t steps, std::int64_t stateBytes,
                                   int stages, const ScheduleCosts* costs, std::int64_t stageBytes = 0,
                                   bool lowerBound = false);

/// Writes the plan's action stream of `spec` (one action per line) for fixed steps, N <= 2^24; cams'
/// step records are those of an explicit Runge-Kutta method of `stages` stages, as predictSchedule
/// counts them. Everything is validated (as predictSchedule does) before the first line is written.
void writeScheduleActions(const std::string& spec, std::int64_t steps, std::int64_t stateBytes, int stages,
                          const ScheduleCosts* costs, std::ostream& out, std::int64_t stageBytes = 0);

}  // namespace hindsight
