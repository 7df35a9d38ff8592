// The optimal stack schedule on K storage levels: RAM (level 0, copies free) and any number of slower
// levels, each with its slots, write and read costs -- the model of H-Revolve (Herrmann & Pallez 2020,
// "H-Revolve: a framework for adjoint computation on synchronous hierarchical platforms", ACM TOMS 46(2))
// with bounded levels, in the game of storage/schedule.h. With K = 2 it plans the two-level form too
// (TwoLevelPlan's stack schedules are optimal() and choose()'s, whose tests compare them with a brute-force
// search and an independent recursion); it is the exact reference the planners for large N are checked
// against.
//
// Recurrences. A segment of l states x_p..x_e whose first state is held at level L, with the free slots
// f = (f_0, ..., f_{K-1}) besides it:
//   F_L(l, f) = r_L + G_L(l, f)                       (load x_p; r_0 = 0)
//   G_L(1, f) = 0
//   G_L(l, f) = min of                                 (x_p at hand, l >= 2)
//     (l - 1) uf + F_L(l - 1, f)                        advance to x_e, consume it;
//     j uf + w_k + G_k(l - j, f - e_k) + F_L(j, f)      store x_{p+j} at level k (f_k >= 1), 1 <= j <= l-2;
//     w_k + G'_k(l, f - e_k + e_L)                      move x_p to level k != L (G' without moves: a chain
//                                                       of moves is never cheaper than its last one).
//   H(l, f) = min over L (f_L >= 1) of w_L + min(F_L(l, f'), min_{1<=j<=l-1} H(l - j, f') + F_L(j, f')),
//   f' = f - e_L: the forward sweep at x_p, storing it at L. The game's cost is H(N, slots).
// Time O(N^2 K^2 prod(s_k + 1)), memory O(N K prod(s_k + 1)): an exact reference for small sizes, refused
// beyond kMaxWork.
#pragma once

#include <hindsight/engine/storage_registry.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {

/// One level below RAM: how many states it holds and what writing and reading one costs (seconds, or any
/// unit shared with the forward step).
struct StorageLevelCosts {
  std::int64_t slots = 0;
  double write = 0.0;
  double read = 0.0;
};

class KLevelPlan {
 public:
  /// N^2 K^2 prod(s_k + 1) at most (a few seconds).
  static constexpr std::int64_t kMaxWork = std::int64_t{1} << 30;

  /// The optimal stack schedule for N >= 1 steps with `ramSlots` RAM states (free copies) and the slower
  /// `levels`, a forward step costing `forwardStep` > 0. Throws std::invalid_argument naming the
  /// argument when the sizes exceed kMaxWork, a count or cost is negative, or the slots cannot reverse N
  /// steps (N >= 2 needs one RAM slot and two slots in all). Polls pollInterrupt() once per length.
  static KLevelPlan optimal(std::int64_t steps, std::int64_t ramSlots,
                            const std::vector<StorageLevelCosts>& levels, double forwardStep);

  /// The optimal schedule of the hierarchical family (H-Revolve's structure, Herrmann & Pallez 2020): held
  /// checkpoints sit on slower or equal levels below faster ones, so while a checkpoint at level k is the top
  /// one, every faster level is empty and the slower ones are frozen. Its programme has the state (length,
  /// level, free slots of that level) instead of every level's free slots:
  ///   E_k(1, m) = 0,
  ///   E_k(l, m) = min( (l - 1) uf + r_k + E_k(l - 1, m),
  ///                    min_j j uf + r_k + E_k(j, m) + min( w_k + E_k(l - j, m - 1)           (m >= 1),
  ///                                                        min_{i<k} w_i + E_i(l - j, s_i - 1) ),
  ///                    min_{i<k} w_i + E_i(l, s_i - 1) )           (move x_p to a faster level),
  ///   W_k(l, m) = min( w_k + min( r_k + E_k(l, m - 1), min_j W_k(l - j, m - 1) + r_k + E_k(j, m - 1) ),
  ///                    W_{k-1}(l, s_{k-1}) ),
  /// the game's cost W_{K-1}(N, s_{K-1}); O(N^2 sum_k (s_k + 1)) time and O(N sum_k (s_k + 1)) memory,
  /// refused beyond kMaxHierarchicalWork. Never cheaper than optimal() (a subset of its schedules); with RAM
  /// alone it is revolve. Same arguments and errors as optimal().
  static constexpr std::int64_t kMaxHierarchicalWork = std::int64_t{1} << 33;
  /// `window` > 0: for each length, only splits within `window` of the previous length's best are searched
  /// (O(N window sum_k (s_k + 1)); a heuristic, measured against window = 0, the full search).
  static KLevelPlan hierarchical(std::int64_t steps, std::int64_t ramSlots,
                                 const std::vector<StorageLevelCosts>& levels, double forwardStep,
                                 std::int64_t window = 0);

  /// H-Revolve's structure for any N (up to 10^6 in seconds): hierarchical()'s programme with the window
  /// kGradedWindow over the lengths 1..kGradedExactLengths and, beyond, over a geometric grid of lengths
  /// (each at least 1/kGradedSpacingDivisor of the previous one further), values between the grid's lengths
  /// interpolated linearly; the executor evaluates the recurrence for a length between grid points when
  /// it meets one (every grid length a split). Tables O((kGradedExactLengths + ln(N) kGradedSpacingDivisor)
  /// sum_k (s_k + 1)). A heuristic: the tests measure it against the full search (docs/theory/storage.md,
  /// "K storage levels"). For N <= kGradedExactLengths it is hierarchical(..., kGradedWindow).
  static constexpr std::int64_t kGradedExactLengths = 4096;
  static constexpr std::int64_t kGradedSpacingDivisor = 256;
  static constexpr std::int64_t kGradedWindow = 16;
  /// A grid of lengths: every length 1..exactLengths, beyond each at least 1/spacingDivisor further.
  struct GradedGrid {
    std::int64_t exactLengths;
    std::int64_t spacingDivisor;
  };
  /// The grids choose() plans on, finest first: graded()'s, then coarser ones, for slots that graded()'s
  /// tables cannot hold. At N = 10^6 they have about 5 500, 2 760, 1 470, 780, 420, 220, 120, 67 and 38 rows,
  /// and hold R + D + 2 <= 381 ... 55 188 slots within kMaxGradedCells (beyond, choose() also tries
  /// segmented()). Coarser rows lose little: at
  /// N = 10^6 with 8 RAM and 1 000 disk slots (1:1:2:2) every grid's plan down to {128, 32} is within
  /// 0.12 % of graded()'s, with 2 RAM and 50 000 disk slots {32, 8}, {16, 4} and {8, 2} within 0.0001 %
  /// of each other ({4, 1}: 1.9 % dearer); docs/theory/storage.md, "Large disks".
  static constexpr GradedGrid kGradedGrids[] = {{kGradedExactLengths, kGradedSpacingDivisor},
                                                {1024, 256},
                                                {512, 128},
                                                {256, 64},
                                                {128, 32},
                                                {64, 16},
                                                {32, 8},
                                                {16, 4},
                                                {8, 2}};
  /// Rows of the tables on `grid` for N steps (the exact lengths, the grid and length 0).
  static std::int64_t gradedRows(std::int64_t steps, GradedGrid grid = kGradedGrids[0]);
  /// graded()'s table entries at the most (32 bytes each: 64 MiB); choose() plans on the finest grid of
  /// kGradedGrids whose tables hold every slot within this, and only beyond the coarsest one with fewer
  /// slots of the largest levels (a plan with fewer slots is one of the plans with more).
  static constexpr std::int64_t kMaxGradedCells = std::int64_t{1} << 21;
  static KLevelPlan graded(std::int64_t steps, std::int64_t ramSlots,
                           const std::vector<StorageLevelCosts>& levels, double forwardStep,
                           GradedGrid grid = kGradedGrids[0]);

  /// Large slowest levels (more slots than graded()'s tables hold): the forward sweep stores `count` states
  /// at the slowest level K - 1 at equal spacing (segments of base or base + 1 states, the longer ones
  /// first), each segment is reversed from its first state by hierarchical()'s programme over the lengths
  /// 1..maxLength with every level's free slots capped at what tables of maxLength rows hold within
  /// kMaxGradedCells, and the last `tail` states (0..maxLength) are that programme's forward sweep with the
  /// slowest level's slots left over. Its cost in closed form over the programme's values:
  ///   count (w + r) + (count - q) E(base, c) + q E(base + 1, c) + W(tail, c),  c = min(cap, D - count),
  /// E and W of the slowest level (storage/k_level_plan.h's recurrences), q = (N - tail) mod count,
  /// minimised over count and tail (for a tail, the cost is linear in count wherever base is constant,
  /// so the ends of those O(sqrt N) intervals are the candidates). The executor reads the tables at
  /// min(free slots, cap): a segment may use more free slots than planned, never fewer (so the run costs at
  /// most optimum(); counts() is the walk, what a run does). For N <= maxLength it is also allowed to be
  /// the programme alone (count 0). docs/theory/storage.md, "Large disks". Same arguments and errors as
  /// optimal(); maxLength in [1, kGradedExactLengths].
  static KLevelPlan segmented(std::int64_t steps, std::int64_t ramSlots,
                              const std::vector<StorageLevelCosts>& levels, double forwardStep,
                              std::int64_t maxLength = kGradedExactLengths);
  /// segmented()'s forward stores at the slowest level before its tail (0: not a segmented plan).
  struct Segments {
    std::int64_t count = 0, base = 0, longer = 0, tail = 0;
  };
  const Segments& segments() const { return segments_; }

  /// A lower bound on hierarchical()'s optimum (the full split search: H-Revolve's family) for any N,
  /// in O(rows * multipliers * sum_k (s_k + 1) * log rows) time without its O(N^2) work: the lengths
  /// 1..grid.exactLengths by that search, beyond them a geometric grid (as graded()'s), each row bounded
  /// by Lagrangian duality over the parts a chain of stores leaves (storage/k_level_plan.cpp). No schedule
  /// of the family costs less than `bound`, so optimum() - bound bounds what a plan leaves to the family's
  /// optimum (docs/theory/storage.md, "A certificate for large N"). Same arguments and errors as
  /// optimal(); rows * sum_k (s_k + 1) at most kMaxBoundCells.
  struct LowerBound {
    double bound = 0.0;  ///< in optimum()'s unit (the schedule part)
    std::int64_t exactLengths = 0, rows = 0;
  };
  static constexpr std::int64_t kMaxBoundCells = std::int64_t{1} << 23;
  static constexpr double kBoundMultiplierRatio = 1.01;
  /// The grids the bound is computed on, finest first. With few slots the bound is coarser where each part
  /// is long against the grid's spacing (RAM 2 + disk 2 at N = 10^5: 1.26 % at {1024, 1024}); boundGrid()
  /// takes the finest of those finer than {1024, 1024} whose rows * sum_k (s_k + 1) is at most
  /// kBoundGridCells (seconds: about 7 us a cell) and whose exact lengths' full search L^2 sum_k (s_k + 1)
  /// is at most 2^28, else {1024, 1024} or the first coarser one within kMaxBoundCells.
  static constexpr GradedGrid kBoundGrids[] = {{4096, 8192}, {2048, 4096}, {1024, 2048},
                                               {1024, 1024}, {512, 256},   {256, 64}};
  static constexpr std::int64_t kBoundGridCells = std::int64_t{1} << 20;
  static GradedGrid boundGrid(std::int64_t steps, std::int64_t columns);
  /// On boundGrid(N, sum_k (s_k + 1)) (the slots capped at N as the plans cap them).
  static LowerBound lowerBound(std::int64_t steps, std::int64_t ramSlots,
                               const std::vector<StorageLevelCosts>& levels, double forwardStep);
  static LowerBound lowerBound(std::int64_t steps, std::int64_t ramSlots,
                               const std::vector<StorageLevelCosts>& levels, double forwardStep,
                               GradedGrid grid);

  /// The plan a `multilevel` spec runs, with K levels or two (TwoLevelPlan::choose's stack schedule):
  /// optimal() where its work is at most kChooseExactWork -- for two levels kMaxWork, the limit the
  /// two-level programme always had (N^2 (R + 1)(D + 1) <= 2^28, 2-3 s) --, else graded() on the finest
  /// grid of kGradedGrids whose tables hold every slot within kMaxGradedCells; where the finest grid cannot
  /// hold every slot, the cheaper (walked cost) of that (a coarser grid, or beyond the coarsest each level's
  /// slots capped so that they fit) and segmented(). Same arguments and errors as optimal().
  static constexpr std::int64_t kChooseExactWork = std::int64_t{1} << 26;
  static KLevelPlan choose(std::int64_t steps, std::int64_t ramSlots,
                           const std::vector<StorageLevelCosts>& levels, double forwardStep);
  /// One line: the programme and the slots each level uses at the most.
  std::string describe() const;

  struct Counts {
    std::int64_t recomputedSteps = 0;
    std::int64_t forwardStores = 0;           ///< states stored during the forward sweep (any level)
    std::vector<std::int64_t> writes, reads;  ///< per level, RAM (level 0) included
    /// recomputed steps * uf + sum over the levels below RAM of writes * w + reads * r.
    double cost = 0.0;
  };
  const Counts& counts() const { return counts_; }
  /// Whether the plan is optimal()'s (else H-Revolve's structure: hierarchical() or graded()).
  bool exact() const { return tables_ != nullptr; }
  /// Whether graded()'s geometric grid of lengths plans the longer segments.
  bool onGrid() const;
  /// The lengths planned exactly (1..exactLengths()): N for optimal() and hierarchical(), the grid's for
  /// graded().
  std::int64_t exactLengths() const;
  /// The programme's optimum H(N, slots); counts().cost equals it (the executor follows its decisions).
  double optimum() const { return optimum_; }
  int levelCount() const { return static_cast<int>(capacity_.size()); }
  /// Slots of each level in use at the most during one pass.
  const std::vector<std::int64_t>& slotsUsed() const { return peak_; }
  std::int64_t steps() const { return steps_; }

  /// The forward sweep at step n (0..N-1 in order) and the backward sweep at e (N-1..0 in order), as
  /// TwoLevelPlan's: the visitor gets store(level, slot), load(level, slot), advance(from, to), levels as
  /// ints (0 = RAM). rewind() starts a new pass.
  template <typename Visitor>
  void recordForward(std::int64_t n, Visitor& visitor);
  template <typename Visitor>
  void restoreStep(std::int64_t e, Visitor& visitor);
  void rewind();

 private:
  struct Tables;
  struct Held {
    std::int64_t position;
    int level;
    std::int64_t slot;
  };
  struct Decision {
    int action;  // forward: the level of the store; backward: kDone, kNone, kStore, kMove
    int level;   // backward: the level stored at or moved to
    std::int64_t distance;
  };
  enum : int { kDone = 0, kNone = 1, kStore = 2, kMove = 3 };
  Decision forwardDecision(std::int64_t length) const;
  Decision backwardDecision(int level, std::int64_t length) const;
  std::int64_t takeSlot(int level);
  void releaseSlot(const Held& held);
  Counts walk();

  struct HierarchicalTables;
  /// hierarchical() over the lengths 1..exactLengths and a geometric grid beyond (spacing: see graded()).
  static KLevelPlan solveHierarchical(std::int64_t steps, std::int64_t ramSlots,
                                      const std::vector<StorageLevelCosts>& levels, double forwardStep,
                                      std::int64_t window, std::int64_t exactLengths, double spacing);
  /// The tables of solveHierarchical() for the lengths up to `steps` and the slots `capacity` (checked).
  static std::shared_ptr<HierarchicalTables> hierarchicalTables(std::int64_t steps,
                                                                const std::vector<std::int64_t>& capacity,
                                                                const std::vector<double>& write,
                                                                const std::vector<double>& read, double uf,
                                                                std::int64_t window,
                                                                std::int64_t exactLengths, double spacing);
  /// The tables' column for `free` slots of `level` (they may hold fewer slots than the level: segmented()).
  std::int64_t column(int level, std::int64_t free) const;
  std::shared_ptr<const Tables> tables_;
  std::shared_ptr<const HierarchicalTables> hierarchical_;
  /// Checks the arguments of optimal() and hierarchical(); fills capacity (RAM first, each at most N),
  /// write and read (RAM: 0).
  static void checkArguments(std::int64_t steps, std::int64_t ramSlots,
                             const std::vector<StorageLevelCosts>& levels, double forwardStep,
                             std::vector<std::int64_t>& capacity, std::vector<double>& write,
                             std::vector<double>& read);
  void finish(double uf, const std::vector<double>& write, const std::vector<double>& read);
  std::int64_t steps_ = 0;
  Segments segments_;
  std::vector<std::int64_t> capacity_;
  double optimum_ = 0.0;
  Counts counts_;
  // The executor's state.
  std::vector<Held> held_;
  std::vector<std::vector<std::int64_t>> released_;  // per level: a min-heap of the released slots
  std::vector<std::int64_t> unused_, free_, peak_;   // unused_: the first slot never taken
  std::int64_t nextStore_ = -1;
};

template <typename Visitor>
void KLevelPlan::recordForward(std::int64_t n, Visitor& visitor) {
  if (n != nextStore_) return;
  const Decision decision = forwardDecision(steps_ - n);
  const std::int64_t slot = takeSlot(decision.action);
  visitor.store(decision.action, slot);
  held_.push_back(Held{n, decision.action, slot});
  nextStore_ = decision.distance > 0 ? n + decision.distance : -1;
}

template <typename Visitor>
void KLevelPlan::restoreStep(std::int64_t e, Visitor& visitor) {
  bool atHand = false;  // whether the state at hand is the top checkpoint's
  for (;;) {
    const Held top = held_.back();
    const std::int64_t length = e - top.position + 1;
    if (!atHand) visitor.load(top.level, top.slot);
    atHand = true;
    if (length == 1) {
      releaseSlot(top);
      held_.pop_back();
      return;
    }
    const Decision decision = backwardDecision(top.level, length);
    if (decision.action == kNone) {
      visitor.advance(top.position, e);
      return;
    }
    if (decision.action == kMove) {
      const std::int64_t slot = takeSlot(decision.level);
      visitor.store(decision.level, slot);
      releaseSlot(top);
      held_.back() = Held{top.position, decision.level, slot};
      continue;
    }
    visitor.advance(top.position, top.position + decision.distance);
    const std::int64_t slot = takeSlot(decision.level);
    visitor.store(decision.level, slot);
    held_.push_back(Held{top.position + decision.distance, decision.level, slot});
  }
}

}  // namespace hindsight
