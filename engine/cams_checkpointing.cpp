#include <hindsight/engine/cams_checkpointing.h>

#include <hindsight/engine/interrupt.h>
#include <hindsight/engine/stopwatch.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <limits>
#include <ostream>
#include <stdexcept>

namespace hindsight {
namespace cams {
namespace {

std::int64_t noCheckpointCost(std::int64_t l) { return l * (l + 1) / 2; }

__extension__ typedef __int128
    Wide;  // exact products of table values (up to ~N^2 / 2) and segment lengths (up to N)

/// The greatest convex minorant of a row V(0..l), built as l grows (Andrew's monotone chain: a point
/// removes the vertices it makes non-convex). The rows are not convex (a record serves two steps, so
/// parity shows in the increments), but they stay within a few units of their minorant, which makes it a
/// tight lower bound for the split search. All arithmetic is exact (integers, 128-bit products): a
/// rounded bound could prune the optimum. Hand-written: a dozen lines that no package offers for integer
/// points appended in order.
class Minorant {
 public:
  void reset() {
    x_.clear();
    y_.clear();
  }
  void push(std::int64_t x, std::int64_t y) {
    while (x_.size() >= 2) {
      const std::size_t n = x_.size();
      // Keep vertex n - 1 only if it lies strictly below the chord from vertex n - 2 to (x, y).
      const Wide cross = static_cast<Wide>(x_[n - 1] - x_[n - 2]) * (y - y_[n - 2]) -
                         static_cast<Wide>(y_[n - 1] - y_[n - 2]) * (x - x_[n - 2]);
      if (cross > 0) break;
      x_.pop_back();
      y_.pop_back();
    }
    x_.push_back(x);
    y_.push_back(y);
  }
  /// The segment (x0, y0, dx, dy) holding [k, k + 1] (k < the last x), or ending at k = the last x.
  struct Segment {
    std::int64_t x0, y0, dx, dy;
    /// The minorant at k as numerator over dx.
    Wide numerator(std::int64_t k) const {
      return static_cast<Wide>(y0) * dx + static_cast<Wide>(dy) * (k - x0);
    }
  };
  Segment segment(std::int64_t k) const {
    assert(x_.size() >= 2 && k >= 0 && k <= x_.back());
    std::size_t j = static_cast<std::size_t>(std::upper_bound(x_.begin(), x_.end(), k) - x_.begin()) - 1;
    if (j + 1 == x_.size()) --j;
    return Segment{x_[j], y_[j], x_[j + 1] - x_[j], y_[j + 1] - y_[j]};
  }

 private:
  std::vector<std::int64_t> x_, y_;
};

/// h(k) = s k + c + A(k) + B(l - k) for the rows' minorants A and B: convex in k, at most g(k).
struct LowerBound {
  std::int64_t l, s, c;
  const Minorant& a;
  const Minorant& b;
  /// ceil(h(k)), exactly.
  std::int64_t ceiling(std::int64_t k) const {
    Wide num, den;
    fraction(k, &num, &den);
    const Wide q = num / den;  // truncated towards zero; den > 0
    return static_cast<std::int64_t>(q * den < num ? q + 1 : q);
  }
  /// ceil(h(k)) < value, exactly and without a division: h(k) <= value - 1.
  bool below(std::int64_t k, std::int64_t value) const {
    Wide num, den;
    fraction(k, &num, &den);
    return num <= static_cast<Wide>(value - 1) * den;
  }
  /// h(k) = num / den, den > 0.
  void fraction(std::int64_t k, Wide* num, Wide* den) const {
    const Minorant::Segment sa = a.segment(k), sb = b.segment(l - k);
    *den = static_cast<Wide>(sa.dx) * sb.dx;
    *num = static_cast<Wide>(s * k + c) * *den + sa.numerator(k) * sb.dx + sb.numerator(l - k) * sa.dx;
  }
  /// h(k + 1) >= h(k), exactly (k + 1 <= the last x of a).
  bool risesAfter(std::int64_t k) const {
    const Minorant::Segment sa = a.segment(k), sb = b.segment(l - k - 1);
    return static_cast<Wide>(s) * sa.dx * sb.dx + static_cast<Wide>(sa.dy) * sb.dx -
               static_cast<Wide>(sb.dy) * sa.dx >=
           0;
  }
};

/// The least g(k) = a(k) + b(l - k) + c(k) over k in [1, l - 1] and the first k attaining it (ties: the
/// smallest k the search evaluates; the exhaustive search's smallest k may differ, the value not).
/// h(k) <= g(k) (LowerBound) is convex in k, so the k that can still beat the incumbent form one
/// interval around h's minimum: found by bisection, then scanned, and the scan stops once g reaches
/// ceil(min h). Exact: only k with ceil(h(k)) >= the incumbent (which cannot improve it) are skipped.
/// `exhaustive` evaluates every k (for the tests).
template <typename G>
std::pair<std::int64_t, std::int64_t> minimize(std::int64_t l, bool exhaustive, const G& g,
                                               const LowerBound& h, std::int64_t guess) {
  std::int64_t bestK = 1, best = g(1);
  const auto consider = [&](std::int64_t k) {
    const std::int64_t value = g(k);
    if (value < best || (value == best && k < bestK)) best = value, bestK = k;
  };
  if (exhaustive) {
    for (std::int64_t k = 2; k < l; ++k) consider(k);
    return {bestK, best};
  }
  for (std::int64_t k : {guess, guess + 1, l - 1}) {
    if (k >= 1 && k < l) consider(k);
  }
  // h's minimum: the first k with h(k + 1) >= h(k) (h convex: false, then true; l - 1 if none in
  // [1, l - 2]). Bracketed from the guess outwards in doubling steps, then bisected: the k a bisection
  // over [1, l - 1] finds, in fewer evaluations (the minimum moves little from one l to the next).
  std::int64_t lo = 1, hi = l - 1;
  const auto rises = [&](std::int64_t k) { return h.risesAfter(k); };
  const std::int64_t start = std::min(std::max(guess, lo), hi);
  if (start < hi && !rises(start)) {
    lo = start + 1;
    for (std::int64_t step = 1; lo + step - 1 < hi; step *= 2) {
      const std::int64_t k = lo + step - 1;
      if (rises(k)) {
        hi = k;
        break;
      }
      lo = k + 1;
    }
  } else {
    hi = start;
    for (std::int64_t step = 1; hi - step >= lo; step *= 2) {
      const std::int64_t k = hi - step;
      if (!rises(k)) {
        lo = k + 1;
        break;
      }
      hi = k;
    }
  }
  while (lo < hi) {
    const std::int64_t mid = lo + (hi - lo) / 2;
    if (rises(mid))
      hi = mid;
    else
      lo = mid + 1;
  }
  const std::int64_t kMin = lo;
  const std::int64_t floorValue = h.ceiling(kMin);
  if (floorValue >= best) return {bestK, best};
  // The first k <= kMin whose bound is below the incumbent (bounds fall towards kMin; kMin's is):
  // bracketed down from kMin in doubling steps, then bisected.
  lo = 1, hi = kMin;
  for (std::int64_t step = 1; hi - step >= lo; step *= 2) {
    const std::int64_t k = hi - step;
    if (!h.below(k, best)) {
      lo = k + 1;
      break;
    }
    hi = k;
  }
  while (lo < hi) {
    const std::int64_t mid = lo + (hi - lo) / 2;
    if (h.below(mid, best))
      hi = mid;
    else
      lo = mid + 1;
  }
  for (std::int64_t k = lo; k < l; ++k) {
    if (k > kMin && !h.below(k, best)) break;  // bounds rise from kMin on
    const std::int64_t value = g(k);
    if (value < best) best = value, bestK = k;
    if (best == floorValue) break;
  }
  return {bestK, best};
}

}  // namespace

Plan::Plan(std::int64_t steps, std::int64_t memoryUnits, std::int64_t recordUnits)
    : steps_(steps), units_(memoryUnits), recordUnits_(recordUnits) {
  build(false);
}

Plan Plan::exhaustive(std::int64_t steps, std::int64_t memoryUnits, std::int64_t recordUnits) {
  Plan plan;
  plan.steps_ = steps;
  plan.units_ = memoryUnits;
  plan.recordUnits_ = recordUnits;
  plan.build(true);
  return plan;
}

Plan Plan::replayOnly(std::int64_t steps, std::int64_t memoryUnits, std::int64_t recordUnits) {
  Plan plan;
  plan.steps_ = steps;
  plan.units_ = memoryUnits;
  plan.recordUnits_ = recordUnits;
  plan.build(false, false);
  return plan;
}

void Plan::build(bool exhaustiveSearch, bool sweepTables) {
  if (steps_ < 1 || units_ < 1 || recordUnits_ < 1) {
    throw std::invalid_argument("cams plan: steps = " + std::to_string(steps_) +
                                ", memory units = " + std::to_string(units_) +
                                " and record units = " + std::to_string(recordUnits_) + " must all be >= 1");
  }
  const std::int64_t N = steps_;
  // More units than N records can use change nothing.
  const std::int64_t M = std::min(units_, (N + 1) * recordUnits_);
  if ((N + 1) > kMaxTableEntries / (M + 1) || N >= std::numeric_limits<std::int32_t>::max()) {
    throw std::invalid_argument("cams: the plan for " + std::to_string(N) + " steps and " +
                                std::to_string(M) + " state units needs more than " +
                                std::to_string(kMaxTableEntries) +
                                " table entries; add online=1 (online placement, each interval reversed "
                                "optimally), lower cams.budget/cams.checkpoints or use binomial");
  }
  const std::int64_t w = recordUnits_;
  const auto row = static_cast<std::size_t>(N + 1);
  const int tables = sweepTables ? 4 : 2;  // replay tables first: 2 * sweep + record
  narrow_ = N <= kMaxNarrowSteps;
  for (int table = 0; table < tables; ++table) {
    if (narrow_)
      narrowDecisions_[table].assign(row * static_cast<std::size_t>(M + 1), 0);
    else
      decisions_[table].assign(row * static_cast<std::size_t>(M + 1), 0);
  }
  // Values: only rows m, m - 1, m - (w - 1) and m - w are read, so a ring of min(w, M) + 1 rows.
  const std::int64_t ring = std::min(w, M) + 1;
  std::vector<std::int64_t> values[4];
  for (int table = 0; table < tables; ++table) values[table].assign(row * static_cast<std::size_t>(ring), 0);
  // Table index: 2 * sweep + record (the anchor's kind).
  const auto V = [&](int table, std::int64_t m, std::int64_t l) -> std::int64_t& {
    return values[table][static_cast<std::size_t>(m % ring) * row + static_cast<std::size_t>(l)];
  };
  constexpr int kReplay = 0, kSweep = 2, kState = 0, kRecord = 1;
  std::int64_t stateAnchor = std::numeric_limits<std::int64_t>::max();
  std::int64_t recordAnchor = std::numeric_limits<std::int64_t>::max();
  std::int64_t l0 = 1;
  // The convex minorant of every row in the ring, grown with the row (lower bounds for the search).
  std::vector<Minorant> minorants(static_cast<std::size_t>(4 * ring));
  const auto Mn = [&](int table, std::int64_t m) -> Minorant& {
    return minorants[static_cast<std::size_t>(table * ring + m % ring)];
  };
  for (std::int64_t m = 0; m <= M; ++m) {
    for (int table = 0; table < tables; ++table) {
      V(table, m, 0) = 0;
      V(table, m, 1) = 1;
      Mn(table, m).reset();
      Mn(table, m).push(0, 0);
      Mn(table, m).push(1, 1);
    }
    const std::size_t base = static_cast<std::size_t>(m) * row;
    // The split of the interval one step shorter seeds the search.
    const auto guess = [&](int table) {
      const std::int32_t d = storedDecision(table, base + static_cast<std::size_t>(l0));
      return d == kUpgradeAnchor ? std::int64_t{0} : std::abs(static_cast<std::int64_t>(d));
    };
    for (std::int64_t l = 2; l <= N; ++l) {
      // Planning a long trajectory takes seconds to minutes: an interrupt (engine/interrupt.h; Ctrl-C
      // in Python) must not wait for it. One atomic load when nothing is installed.
      if ((l & 255) == 0) pollInterrupt();
      l0 = l - 1;
      for (int sweep = 0; sweep < tables / 2; ++sweep) {
        // sweep = 0: replay interval (advancing to a checkpoint costs its steps); 1: the forward sweep runs
        // through the interval (advancing is free, its checkpoints are stored on the way).
        const int own = sweep == 1 ? kSweep : kReplay;
        const std::int64_t advance = sweep == 1 ? 0 : 1;
        for (int t = kState; t <= kRecord; ++t) {
          std::int64_t best = noCheckpointCost(l), decision = 0;
          const Minorant& left = Mn(kReplay + t, m);
          if (m >= 1) {
            // State checkpoint at k: the left part keeps the anchor, the right part starts at the state.
            const Minorant& right = Mn(own + kState, m - 1);
            const auto a = minimize(
                l, exhaustiveSearch,
                [&](std::int64_t k) {
                  return advance * k + V(kReplay + t, m, k) + V(own + kState, m - 1, l - k);
                },
                LowerBound{l, advance, 0, left, right}, guess(own + t));
            if (a.second < best) best = a.second, decision = a.first;
          }
          if (m >= w) {
            // Record of step k: it saves that step's adjoint recomputation (in a replay interval only when
            // the right part has two steps or more: for one step the capture costs the advance it saves).
            const Minorant& right = Mn(own + kRecord, m - w);
            const auto b = minimize(
                l, exhaustiveSearch,
                [&](std::int64_t k) {
                  return advance * k + V(kReplay + t, m, k) + V(own + kRecord, m - w, l - k) -
                         (sweep == 1 || l - k >= 2 ? 1 : 0);
                },
                LowerBound{l, advance, -1, left, right}, guess(own + t));
            if (b.second < best) best = b.second, decision = -b.first;
          }
          // Upgrade: the anchor (a state, on top of the stack) grows into the record of its step with w - 1
          // more units; the interval's first advance captures the stage values, and that step's adjoint is
          // free.
          if (sweep == 0 && t == kState && w >= 2 && m >= w - 1 &&
              V(kReplay + kRecord, m - (w - 1), l) - 1 < best) {
            best = V(kReplay + kRecord, m - (w - 1), l) - 1;
            decision = kUpgradeAnchor;
          }
          V(own + t, m, l) = best;
          Mn(own + t, m).push(l, best);
          storeDecision(own + t, base + static_cast<std::size_t>(l), decision);
        }
      }
    }
    // Row m is complete; the top-level optimum needs rows M - 1 and M - w, read before they are overwritten.
    if (!sweepTables) continue;
    if (m == M - 1) stateAnchor = N + V(kSweep + kState, m, N);
    if (m == M - w) recordAnchor = N + V(kSweep + kRecord, m, N) - 1;
  }
  // x_0 held as a state, or as a record (its stage values come free with the forward sweep's step 0).
  anchorIsRecord_ = sweepTables && recordAnchor < stateAnchor;
  optimum_ = sweepTables ? std::min(stateAnchor, recordAnchor) : -1;
  units_ = M;
}

std::int64_t Plan::decision(bool sweep, bool recordAnchor, std::int64_t l, std::int64_t m) const {
  assert(l >= 1 && l <= steps_ && m >= 0 && m <= units_ &&
         !(narrow_ ? narrowDecisions_ : decisions_)[sweep ? 2 : 0].empty());
  const auto index =
      static_cast<std::size_t>(m) * static_cast<std::size_t>(steps_ + 1) + static_cast<std::size_t>(l);
  return storedDecision((sweep ? 2 : 0) + (recordAnchor ? 1 : 0), index);
}

// ---- Executor ----

void Executor::reset(const Plan* plan) {
  plan_ = plan;
  checkpoints_.clear();
  tasks_.clear();
  top_ = 0;
  checkpoints_.reserve(static_cast<std::size_t>(std::min(plan->memoryUnits(), plan->steps()) + 1));
  tasks_.reserve(static_cast<std::size_t>(2 * std::min(plan->memoryUnits(), plan->steps()) + 2));
  limit_ = plan->memoryUnits();
  const bool record = plan->anchorIsRecord();
  chainPosition_ = 0;
  chainLength_ = plan->steps();
  chainUnits_ = plan->memoryUnits() - (record ? plan->recordUnits() : 1);
  nextForward_ = 0;
  nextForwardRecord_ = record;
}

void Executor::reserve(std::int64_t checkpoints) {
  // At most one checkpoint per unit or step above the anchor, two tasks per checkpoint.
  checkpoints_.reserve(static_cast<std::size_t>(checkpoints + 2));
  tasks_.reserve(static_cast<std::size_t>(2 * checkpoints + 2));
  revolve_.reserve(checkpoints + 1);
  revolvePositions_.reserve(static_cast<std::size_t>(checkpoints + 1));
}

void Executor::beginInterval(const Plan* plan, std::int64_t position, std::int64_t ref, std::int64_t length,
                             std::int64_t units) {
  assert(length >= 1 && units >= 0);
  plan_ = plan;
  checkpoints_.clear();
  tasks_.clear();
  revolveInterval_ = length > plan->steps();
  if (revolveInterval_) {
    // Revolve over the anchor's unit and the free ones above it (onlineIntervalPlan).
    const std::int64_t slots = std::min(units, length - 1) + 1;
    revolve_.reserve(slots);
    revolve_.reset(length, slots, false);
    revolvePositions_.assign(static_cast<std::size_t>(slots), position);
    revolveStart_ = position;
    revolveRef_ = ref;
    revolveAt_ = position;
    top_ = ref + slots;
    limit_ = top_;
    nextForward_ = -1;
    return;
  }
  units = std::min(units, plan->memoryUnits());  // more cannot help
  reserve(std::min(units, length));
  checkpoints_.push_back(Checkpoint{position, ref, false, false});
  lastStored_ = Stored{false, false, false, length, units};
  top_ = ref + 1;
  limit_ = top_ + units;
  tasks_.push_back(Task{0, length, units, false, -1});
  nextForward_ = -1;
}

std::int64_t Executor::push(std::int64_t position, bool record) {
  const std::int64_t units = record ? plan_->recordUnits() : 1;
  checkpoints_.push_back(Checkpoint{position, top_, record, false});
  top_ += units;
  assert(top_ <= limit_);
  return static_cast<std::int64_t>(checkpoints_.size()) - 1;
}

void Executor::pop() {
  const Checkpoint& c = checkpoints_.back();
  top_ = c.ref;
  checkpoints_.pop_back();
}

std::int64_t Executor::recordForward(std::int64_t n, bool* isRecord) {
  *isRecord = false;
  if (n != nextForward_) return -1;
  const bool record = nextForwardRecord_;
  const std::int64_t index = push(n, record);
  checkpoints_.back().filled = record;
  if (n == 0) tasks_.push_back(Task{index, chainLength_, chainUnits_, true, -1});
  lastStored_ = Stored{true, record, record, chainLength_, chainUnits_};
  // The next checkpoint of the chain: the sweep interval starting here.
  const std::int64_t k = chainLength_ >= 2 ? plan_->decision(true, record, chainLength_, chainUnits_) : 0;
  if (k == 0) {
    nextForward_ = -1;
  } else {
    nextForwardRecord_ = k < 0;
    const std::int64_t offset = k < 0 ? -k : k;
    chainPosition_ = n + offset;
    chainLength_ -= offset;
    chainUnits_ -= k < 0 ? plan_->recordUnits() : 1;
    nextForward_ = chainPosition_;
  }
  *isRecord = record;
  return checkpoints_.back().ref;
}

Executor::AnchorUse Executor::lastStoredUse() const {
  // restoreStep's treatment of an anchor, step by step: the left part of a split keeps the anchor and its
  // units; only the advances from the anchor and its record's capture matter here.
  AnchorUse use;
  bool record = lastStored_.record, filled = lastStored_.filled;
  std::int64_t length = lastStored_.length, units = lastStored_.units;
  if (lastStored_.sweep && length >= 2) {
    const std::int64_t k = plan_->decision(true, record, length, units);
    if (k == 0) {
      use.advances = length - 1;
      length = 1;
    } else {
      length = k < 0 ? -k : k;  // the left part, a replay interval
    }
  }
  while (length >= 2) {
    const std::int64_t k = plan_->decision(false, record, length, units);
    if (k == Plan::kUpgradeAnchor) {
      record = true;
      filled = false;
      units -= plan_->recordUnits() - 1;
      continue;
    }
    // The first advance from a record captures its stage values.
    if (record) filled = true;
    if (k == 0) {
      use.advances += length - 1;
      break;
    }
    ++use.advances;
    length = k < 0 ? -k : k;
  }
  use.filledAtDelivery = record && filled;
  return use;
}

// ---- Simulation without states ----

namespace {

struct CountingVisitor {
  PlanCounts& counts;
  const Executor& executor;
  std::vector<Action>* actions;
  void load(std::int64_t) {}
  void advance(std::int64_t from, std::int64_t to) {
    counts.recomputedSteps += to - from;
    if (actions != nullptr) {
      if (!actions->empty() && actions->back().kind == Action::Kind::Advance && actions->back().to == from)
        actions->back().to = to;
      else
        actions->push_back(Action{Action::Kind::Advance, from, to, false});
    }
  }
  void capture(std::int64_t, std::int64_t) { ++counts.recordsStored; }
  void upgrade(std::int64_t, std::int64_t position) {
    counts.peakUnits = std::max(counts.peakUnits, executor.heldUnits());
    if (actions != nullptr) actions->push_back(Action{Action::Kind::StoreRecord, position, position, false});
  }
  void store(std::int64_t, std::int64_t position, bool record) {
    if (!record) ++counts.statesStored;
    counts.peakUnits = std::max(counts.peakUnits, executor.heldUnits());
    if (actions != nullptr)
      actions->push_back(
          Action{record ? Action::Kind::StoreRecord : Action::Kind::StoreState, position, position, false});
  }
  void deliver(std::int64_t position, std::int64_t, bool filled) {
    if (!filled) ++counts.adjointRecomputations;
    if (actions != nullptr) actions->push_back(Action{Action::Kind::Deliver, position, position, filled});
  }
};

}  // namespace

PlanCounts simulate(const Plan& plan, std::vector<Action>* actions) {
  PlanCounts counts;
  counts.steps = plan.steps();
  counts.forwardSteps = plan.steps();
  Executor executor;
  executor.reset(&plan);
  for (std::int64_t n = 0; n < plan.steps(); ++n) {
    bool record = false;
    if (executor.recordForward(n, &record) >= 0) {
      ++counts.forwardStores;
      if (record)
        ++counts.recordsStored;
      else
        ++counts.statesStored;
      counts.peakUnits = std::max(counts.peakUnits, executor.heldUnits());
      if (actions != nullptr)
        actions->push_back(
            Action{record ? Action::Kind::StoreRecord : Action::Kind::StoreState, n, n, false});
    }
  }
  CountingVisitor visitor{counts, executor, actions};
  for (std::int64_t e = plan.steps() - 1; e >= 0; --e) {
    if ((e & 0xffff) == 0) pollInterrupt();  // up to 2^24 steps (engine/interrupt.h)
    executor.restoreStep(e, visitor);
  }
  return counts;
}

// ---- Online mode ----

std::int64_t onlineIntervalPlanSteps(std::int64_t longest, std::int64_t memoryUnits,
                                     std::int64_t recordUnits) {
  const std::int64_t units = std::max<std::int64_t>(memoryUnits - 1, 1);
  // The longest interval, up to kMaxIntervalPlanSteps, whose plan is within Plan::kMaxTableEntries (it uses
  // min(units, (l + 1) w) units); longer ones are reversed by revolve.
  const auto entries = [&](std::int64_t l) {
    const UnsignedInt128 used = std::min<UnsignedInt128>(static_cast<UnsignedInt128>(units),
                                                         static_cast<UnsignedInt128>(l + 1) * recordUnits);
    return static_cast<UnsignedInt128>(l + 1) * (used + 1);
  };
  std::int64_t lo = 1, hi = std::max<std::int64_t>(std::min(longest, kMaxIntervalPlanSteps), 1);
  while (lo < hi) {
    const std::int64_t mid = lo + (hi - lo + 1) / 2;
    if (entries(mid) <= static_cast<UnsignedInt128>(Plan::kMaxTableEntries))
      lo = mid;
    else
      hi = mid - 1;
  }
  return lo;
}

const Plan& onlineIntervalPlan(std::unique_ptr<Plan>& cached, std::int64_t longest, std::int64_t memoryUnits,
                               std::int64_t recordUnits) {
  const std::int64_t units = std::max<std::int64_t>(memoryUnits - 1, 1);
  const std::int64_t length = onlineIntervalPlanSteps(longest, memoryUnits, recordUnits);
  if (!cached || cached->steps() < length || cached->recordUnits() != recordUnits ||
      cached->memoryUnits() < std::min(units, (length + 1) * recordUnits)) {
    cached = std::make_unique<Plan>(Plan::replayOnly(length, units, recordUnits));
  }
  return *cached;
}

PlanCounts simulateOnline(std::int64_t steps, std::int64_t memoryUnits, std::int64_t recordUnits,
                          std::unique_ptr<Plan>* plan) {
  if (steps < 1 || memoryUnits < 2)
    throw std::invalid_argument("cams online mode: steps = " + std::to_string(steps) +
                                " and memory units = " + std::to_string(memoryUnits) +
                                " must be >= 1 and >= 2");
  PlanCounts counts;
  counts.steps = steps;
  counts.forwardSteps = steps;
  const std::vector<std::int64_t> positions =
      internal::OnlinePlacement::simulate(steps, memoryUnits - 1, &counts.forwardStores, &counts.peakUnits);
  ++counts.forwardStores;  // and x_{N-1}, the working state
  ++counts.peakUnits;
  counts.statesStored = counts.forwardStores;
  counts.adjointRecomputations = 1;  // step N - 1, from the working state
  if (steps == 1) return counts;
  std::unique_ptr<Plan> local;
  std::unique_ptr<Plan>& cached = plan != nullptr ? *plan : local;
  const Plan& intervalPlan = onlineIntervalPlan(
      cached, internal::OnlinePlacement::longestInterval(positions, steps), memoryUnits, recordUnits);
  Executor executor;
  CountingVisitor visitor{counts, executor, nullptr};
  internal::OnlinePlacement::Interval interval{static_cast<std::int64_t>(positions.size()), steps, 0};
  for (std::int64_t e = steps - 2; e >= 0; --e) {
    if ((e & 0xffff) == 0) pollInterrupt();  // up to 2^24 steps (engine/interrupt.h)
    if (e < interval.start) {
      // Interval j: its checkpoint in unit j, the units above it free.
      interval = internal::OnlinePlacement::intervalOf(positions, steps, e, interval.index);
      executor.beginInterval(&intervalPlan, interval.start, interval.index, interval.length,
                             memoryUnits - interval.index - 1);
    }
    executor.restoreStep(e, visitor);
  }
  return counts;
}

// ---- Brute force ----

std::int64_t bruteForceStepEvaluations(std::int64_t steps, std::int64_t memoryUnits,
                                       std::int64_t recordUnits) {
  // States: per position a digit (0 none, 1 state, 2 record without stage values, 3 record with them),
  // the current position (-1: none usable), the next adjoint step e (-1: done). 0-1 BFS on the costs.
  const int N = static_cast<int>(steps);
  if (N < 1 || N > 7) throw std::invalid_argument("bruteForceStepEvaluations: steps must be in [1, 7]");
  std::int64_t digits = 1;
  for (int i = 0; i < N; ++i) digits *= 4;
  const std::int64_t curCount = N + 1, eCount = N + 1;
  const std::int64_t total = digits * curCount * eCount;
  std::vector<std::int64_t> dist(static_cast<std::size_t>(total), std::numeric_limits<std::int64_t>::max());
  const auto encode = [&](std::int64_t held, int cur, int e) {
    return (held * curCount + (cur + 1)) * eCount + (e + 1);
  };
  const auto digit = [](std::int64_t held, int p) { return static_cast<int>((held >> (2 * p)) & 3); };
  const auto with = [](std::int64_t held, int p, int d) {
    return (held & ~(std::int64_t{3} << (2 * p))) | (std::int64_t{d} << (2 * p));
  };
  const auto units = [&](std::int64_t held) {
    std::int64_t u = 0;
    for (int p = 0; p < N; ++p) u += digit(held, p) == 0 ? 0 : (digit(held, p) == 1 ? 1 : recordUnits);
    return u;
  };
  std::deque<std::int64_t> queue;
  // Forward sweep: any set of states and (filled) records within the memory, at cost N.
  std::int64_t configs = 1;
  for (int i = 0; i < N; ++i) configs *= 3;
  for (std::int64_t c = 0; c < configs; ++c) {
    std::int64_t held = 0, rest = c;
    for (int p = 0; p < N; ++p, rest /= 3) {
      const int choice = static_cast<int>(rest % 3);
      held = with(held, p, choice == 0 ? 0 : (choice == 1 ? 1 : 3));
    }
    if (units(held) > memoryUnits) continue;
    const std::int64_t s = encode(held, -1, N - 1);
    if (dist[static_cast<std::size_t>(s)] > steps) {
      dist[static_cast<std::size_t>(s)] = steps;
      queue.push_back(s);
    }
  }
  std::int64_t best = std::numeric_limits<std::int64_t>::max();
  while (!queue.empty()) {
    const std::int64_t s = queue.front();
    queue.pop_front();
    const std::int64_t d = dist[static_cast<std::size_t>(s)];
    const int e = static_cast<int>(s % eCount) - 1;
    const int cur = static_cast<int>((s / eCount) % curCount) - 1;
    const std::int64_t held = s / eCount / curCount;
    if (e < 0) {
      best = std::min(best, d);
      continue;
    }
    const auto relax = [&](std::int64_t next, std::int64_t cost) {
      if (dist[static_cast<std::size_t>(next)] > d + cost) {
        dist[static_cast<std::size_t>(next)] = d + cost;
        if (cost == 0)
          queue.push_front(next);
        else
          queue.push_back(next);
      }
    };
    // Adjoint step e: free with a filled record at e, else from the current state x_e at the cost of a step.
    if (digit(held, e) == 3) relax(encode(held, cur, e - 1), 0);
    if (cur == e) relax(encode(held, cur, e - 1), 1);
    for (int p = 0; p < N; ++p) {
      const int dp = digit(held, p);
      if (dp != 0) {
        relax(encode(held, p, e), 0);                // load
        relax(encode(with(held, p, 0), cur, e), 0);  // delete
      }
    }
    if (cur >= 0 && cur < N - 1) {
      // Advance one step; it fills an unfilled record at cur.
      const std::int64_t filled = digit(held, cur) == 2 ? with(held, cur, 3) : held;
      relax(encode(filled, cur + 1, e), 1);
    }
    if (cur >= 0 && digit(held, cur) == 0) {
      if (units(held) + 1 <= memoryUnits) relax(encode(with(held, cur, 1), cur, e), 0);
      if (units(held) + recordUnits <= memoryUnits) relax(encode(with(held, cur, 2), cur, e), 0);
    }
  }
  return best;
}

}  // namespace cams

// ---- CamsCheckpointing ----

CamsCheckpointing::CamsCheckpointing(std::int64_t checkpoints, std::int64_t budgetBytes, bool online)
    : TrajectoryStorage(budgetBytes), checkpoints_(checkpoints), online_(online) {
  if (checkpoints < 0 || checkpoints > kMaxCheckpoints) {
    throw std::invalid_argument("cams.checkpoints = " + std::to_string(checkpoints) +
                                " must be an integer in [1, " + std::to_string(kMaxCheckpoints) + "]");
  }
}

std::unique_ptr<TrajectoryStorage> CamsCheckpointing::create(const StorageSpec& spec) {
  if (spec.has("checkpoints") == spec.has("budget")) {
    throw std::invalid_argument(
        "cams needs exactly one of cams.budget=BYTES (e.g. cams:budget=1MiB) and "
        "cams.checkpoints=C (the bytes of binomial:checkpoints=C), C in [1, " +
        std::to_string(kMaxCheckpoints) + "]");
  }
  const bool online = spec.integer("online", 0, 0, 1) == 1;
  if (spec.has("checkpoints")) {
    return std::make_unique<CamsCheckpointing>(spec.integer("checkpoints", 1, 1, kMaxCheckpoints),
                                               kDefaultBudget, online);
  }
  return std::make_unique<CamsCheckpointing>(0, spec.bytes("budget", 1), online);
}

std::string CamsCheckpointing::spec() const {
  return (checkpoints_ > 0 ? "cams:checkpoints=" + std::to_string(checkpoints_)
                           : "cams:budget=" + std::to_string(budgetBytes())) +
         (online_ ? ",online=1" : "");
}

std::int64_t CamsCheckpointing::usableUnits(std::int64_t stateBytes, bool online) const {
  const std::int64_t units =
      online ? std::min(memoryUnits(stateBytes), kMaxCheckpoints + 1) : memoryUnits(stateBytes);
  if (checkpoints_ > 0 && units > budgetBytes() / stateBytes) {
    // As binomial:checkpoints=C refuses C + 1 states beyond its budget, so does the same byte budget here.
    throw std::invalid_argument(
        "cams.checkpoints = " + std::to_string(checkpoints_) + " needs " + std::to_string(units) +
        " states of " + formatBytes(stateBytes) +
        ", more than the budget of binomial:checkpoints=" + std::to_string(checkpoints_) + " (" +
        formatBytes(budgetBytes()) + "); lower the checkpoints or use cams:budget=BYTES");
  }
  if (units < (online ? 2 : 1)) {
    throw std::invalid_argument(
        "cams.budget = " + formatBytes(budgetBytes()) + " holds " + std::to_string(units) + " state(s) of " +
        formatBytes(stateBytes) + "; " +
        (online ? "the online mode (adaptive steps or online=1) needs two, a checkpoint and "
                  "the working state"
                : "cams needs at least one") +
        "; raise the budget");
  }
  return units;
}

void CamsCheckpointing::releaseAll() {
  if (heldBytes_ > 0) releaseBytes(heldBytes_);
  heldBytes_ = 0;
  memory_.reset();
}

void CamsCheckpointing::doBegin() {
  heldBytes_ = 0;  // the base class has released what a previous run held
  releaseAll();
  const std::int64_t steps = info().stepCount;
  onlineRun_ = online_ || steps < 1;
  const std::int64_t n = info().stateSize;
  units_ = usableUnits(stateBytes(), onlineRun_);
  // A record is the state and the step's stage values; with no step data, records are impossible.
  recordUnits_ = info().stepDataSize > 0 ? 1 + (info().stepDataSize + n - 1) / n
                                         : std::numeric_limits<std::int32_t>::max();
  delivered_ = nullptr;
  pendingRecord_ = -1;
  if (onlineRun_) {
    // All M units are held from the start (the forward sweep may fill them before thinning); N is unknown,
    // so M is capped like online's checkpoints (usableUnits), not by (N + 1) w as offline.
    holdBytes(units_ * stateBytes());
    heldBytes_ = units_ * stateBytes();
    memory_.reset(new double[static_cast<std::size_t>(units_ * n)]);
    placement_.reset(units_ - 1);
    workingValid_ = false;
    intervalStart_ = -1;
    return;
  }
  const std::int64_t capped = std::min(units_, (steps + 1) * recordUnits_);
  if ((steps + 1) > cams::Plan::kMaxTableEntries / (capped + 1)) {
    throw std::invalid_argument("cams: the optimal plan for " + std::to_string(steps) + " steps and " +
                                std::to_string(capped) + " state units needs more than " +
                                std::to_string(cams::Plan::kMaxTableEntries) +
                                " table entries; add online=1 (cams:...,online=1: online placement, optimal "
                                "reversal of each interval) or lower cams.budget/cams.checkpoints");
  }
  if (!plan_ || plan_->steps() != steps || plan_->recordUnits() != recordUnits_ ||
      plan_->memoryUnits() != capped) {
    const Stopwatch planning;
    plan_ = std::make_unique<cams::Plan>(steps, units_, recordUnits_);
    mutableCounters().planningSeconds += planning.seconds();
  }
  const std::int64_t held = std::min(units_, plan_->memoryUnits());
  holdBytes(held * stateBytes());  // throws StorageError beyond the budget
  heldBytes_ = held * stateBytes();
  memory_.reset(new double[static_cast<std::size_t>(held * n)]);
  executor_.reset(plan_.get());
}

void CamsCheckpointing::doRecord(std::int64_t step, double, ConstVectorRef z, ConstVectorRef) {
  const std::int64_t n = info().stateSize;
  const auto bytes = static_cast<std::size_t>(n) * 8;
  if (onlineRun_) {
    // The working state (unit M - 1) holds the last recorded state; it becomes a candidate when the next
    // record shows it was not the last (internal::OnlinePlacement, as `online` places its checkpoints).
    double* working = memory_.get() + (units_ - 1) * n;
    if (workingValid_ && placement_.isCandidate(step - 1)) {
      const std::int64_t slot = placement_.commit(step - 1, [&](std::int64_t from, std::int64_t to) {
        if (from != to) std::memcpy(memory_.get() + to * n, memory_.get() + from * n, bytes);
      });
      if (slot >= 0) {
        std::memcpy(memory_.get() + slot * n, working, bytes);
        ++mutableCounters().statesStored;
      }
    }
    std::memcpy(working, z.data(), bytes);
    workingValid_ = true;
    return;
  }
  bool record = false;
  const std::int64_t ref = executor_.recordForward(step, &record);
  pendingRecord_ = -1;
  if (ref < 0) return;
  std::memcpy(memory_.get() + ref * n, z.data(), bytes);
  ++mutableCounters().statesStored;
  if (record) pendingRecord_ = ref;
}

void CamsCheckpointing::doRecordStepData(std::int64_t, ConstVectorRef data) {
  if (pendingRecord_ < 0) return;  // (the online mode keeps no records in the forward sweep)
  const std::int64_t n = info().stateSize;
  std::memcpy(memory_.get() + pendingRecord_ * n + n, data.data(), static_cast<std::size_t>(data.size()) * 8);
  ++mutableCounters().stepDataStored;
  pendingRecord_ = -1;
}

void CamsCheckpointing::doFinish(double, ConstVectorRef, ConstVectorRef) {
  if (!onlineRun_) return;
  ++mutableCounters().statesStored;  // x_{N-1}, the working state (as `online` counts it)
  const std::int64_t steps = stepCount();
  if (steps >= 2) {
    const Stopwatch planning;
    const std::int64_t longest = internal::OnlinePlacement::longestInterval(placement_.positions(), steps);
    cams::onlineIntervalPlan(intervalPlan_, longest, units_, recordUnits_);
    mutableCounters().planningSeconds += planning.seconds();
    executor_.reserve(std::min(units_, longest + 1));  // no allocation in the restores
  }
}

void CamsCheckpointing::doRestore(std::int64_t step, VectorRef z) {
  struct Visitor {
    CamsCheckpointing& self;
    VectorRef z;
    std::int64_t n;
    void load(std::int64_t ref) {
      std::memcpy(z.data(), self.memory_.get() + ref * n, static_cast<std::size_t>(n) * 8);
    }
    void store(std::int64_t ref, std::int64_t, bool) {
      std::memcpy(self.memory_.get() + ref * n, z.data(), static_cast<std::size_t>(n) * 8);
    }
    void advance(std::int64_t from, std::int64_t to) {
      for (std::int64_t k = from; k < to; ++k) self.recompute(k, z);
    }
    void upgrade(std::int64_t, std::int64_t) {}  // the state stays; the stage values come with capture()
    void capture(std::int64_t ref, std::int64_t) {
      const auto size = static_cast<Eigen::Index>(self.info().stepDataSize);
      Eigen::Map<Vector> data(self.memory_.get() + ref * n + n, size);
      self.recomputedStepData(data);
      ++self.mutableCounters().stepDataStored;
    }
    void deliver(std::int64_t, std::int64_t ref, bool filled) {
      self.delivered_ = filled ? self.memory_.get() + ref * n + n : nullptr;
    }
  } visitor{*this, z, info().stateSize};
  if (onlineRun_) {
    const std::int64_t n = info().stateSize;
    if (workingValid_) {
      assert(step == stepCount() - 1);
      std::memcpy(z.data(), memory_.get() + (units_ - 1) * n, static_cast<std::size_t>(n) * 8);
      workingValid_ = false;
      delivered_ = nullptr;
      if (step == 0 && info().stepDataSize == 0) releaseAll();
      return;
    }
    if (intervalStart_ < 0 || step < intervalStart_) {
      // As cams::simulateOnline: interval j's checkpoint in unit j, the units above it free.
      const internal::OnlinePlacement::Interval interval = internal::OnlinePlacement::intervalOf(
          placement_.positions(), stepCount(), step, intervalStart_ < 0 ? units_ : intervalIndex_);
      executor_.beginInterval(intervalPlan_.get(), interval.start, interval.index, interval.length,
                              units_ - interval.index - 1);
      intervalStart_ = interval.start;
      intervalIndex_ = interval.index;
    }
  }
  executor_.restoreStep(step, visitor);
  if (step == 0 && info().stepDataSize == 0) releaseAll();
}

bool CamsCheckpointing::doRestoreStepData(std::int64_t step, VectorRef data) {
  const bool restored = delivered_ != nullptr;
  if (restored) std::memcpy(data.data(), delivered_, static_cast<std::size_t>(data.size()) * 8);
  delivered_ = nullptr;
  if (step == 0) releaseAll();
  return restored;
}

void CamsCheckpointing::predict(const TrajectoryStorage& storage, const StorageSpec&,
                                const PredictionRequest& request, SchedulePrediction& p) {
  // The same model-free plan the strategy runs (engine/cams_checkpointing.h), with the step record of
  // an explicit Runge-Kutta method: the state and S - 1 stage states (rk4: 4 state units), as
  // CamsCheckpointing::doBegin sizes it for Integrator::stepDataSize() = (S - 1) n.
  const auto& strategy = dynamic_cast<const CamsCheckpointing&>(storage);
  const std::int64_t steps = request.steps, stateBytes = request.stateBytes;
  const int stages = request.stages;

  const bool online = strategy.onlineRequested();
  if (online && steps > prediction::kMaxWalkedSteps) {
    throw std::invalid_argument(
        "cams with online=1 is predicted up to --steps = " + std::to_string(prediction::kMaxWalkedSteps) +
        " (2^24; its placement is simulated step by step); --steps = " + std::to_string(steps));
  }
  const std::int64_t units = strategy.usableUnits(stateBytes, online);
  const std::int64_t recordUnits = recordUnitsOfStages(stages);
  cams::PlanCounts c;
  if (online) {
    // Online placement, each interval reversed by the optimal plan.
    std::unique_ptr<cams::Plan> intervalPlan;
    c = cams::simulateOnline(steps, units, recordUnits, &intervalPlan);
    p.plan = "cams online: " + std::to_string(units) +
             " state units, online placement, intervals of at most " +
             std::to_string(intervalPlan ? intervalPlan->steps() : 0) + " steps reversed optimally";
    p.ramWrites = -1;  // thinning rewrites slots; the run does not count its copies either
    p.peakRamBytes = prediction::checkedProduct(units, stateBytes, "peak RAM bytes");
  } else {
    const cams::Plan plan(steps, units, recordUnits);
    c = cams::simulate(plan);
    p.plan = "cams: " + std::to_string(plan.memoryUnits()) + " state units, records of " +
             (stages > 1 ? std::to_string(recordUnits) : std::string("-")) + " units";
    p.ramWrites = c.statesStored + c.recordsStored;
    p.peakRamBytes =
        prediction::checkedProduct(std::min(units, plan.memoryUnits()), stateBytes, "peak RAM bytes");
  }
  p.plan += "; " + std::to_string(c.recordsStored) + " step records, " +
            std::to_string(c.adjointRecomputations) + " adjoint steps recompute their stages";
  p.recomputedSteps = c.recomputedSteps;
  p.adjointRecomputations = c.adjointRecomputations;
  p.stepDataStored = c.recordsStored;
  p.stepDataRestored = steps - c.adjointRecomputations;
  p.statesStored = c.forwardStores;  // the strategy counts the checkpoints of the forward sweep
  p.ramReads = steps;
}

void CamsCheckpointing::writeActions(const TrajectoryStorage& storage, const StorageSpec&,
                                     const PredictionRequest& request, std::ostream& out) {
  const auto& cams = dynamic_cast<const CamsCheckpointing&>(storage);
  if (cams.onlineRequested()) {
    throw std::invalid_argument(
        "--actions prints offline plans; cams with online=1 thins its checkpoints "
        "during the forward sweep (print its counts without --actions)");
  }
  // Step records of `stages` state units (the state and S - 1 stage states), as predict counts them;
  // none for one stage.
  const std::int64_t units = cams.usableUnits(request.stateBytes, false);
  std::vector<cams::Action> actions;
  const std::int64_t recordUnits = recordUnitsOfStages(request.stages);
  cams::simulate(cams::Plan(request.steps, units, recordUnits), &actions);
  for (const cams::Action& a : actions) {
    switch (a.kind) {
      case cams::Action::Kind::StoreState:
        out << "store ram state " << a.from << '\n';
        break;
      case cams::Action::Kind::StoreRecord:
        out << "store ram record " << a.from << '\n';
        break;
      case cams::Action::Kind::Advance:
        out << "advance " << a.from << ' ' << a.to << '\n';
        break;
      case cams::Action::Kind::Deliver:
        out << "restore " << a.from << (a.withStageValues ? " with stages\n" : " recompute stages\n");
        break;
    }
  }
}

}  // namespace hindsight
