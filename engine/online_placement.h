// Where the online strategies keep checkpoints while the number of steps is unknown.
//
// TwoHorizonPlacement (`online` in a run whose caller's working state holds x_{N-1}) and CostPlacement
// (`online` without it): documented with their guarantees in engine/online_checkpointing.h.
// OnlinePlacement (`cams` with adaptive steps or online=1): the last recorded state is the working
// state; when the next record arrives it becomes a candidate if its position is a multiple of the
// spacing d; checkpoints are all multiples of d among the candidates, at most c while d = 1 and at most
// F = ceil(c / 2) afterwards; reaching the limit drops every other checkpoint and doubles d (repeated
// if needed). Intervals of at most d steps are what cams' record planning relies on.
#pragma once

#include <hindsight/engine/binomial_checkpointing.h>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace hindsight::internal {

__extension__ typedef __int128 PlacementCost;

/// T(L, s): revolve's forward steps over an interval of L positions with s slots, its first sweep
/// included (engine/binomial_checkpointing.h); what an online placement's interval costs once N is known.
inline PlacementCost intervalForwardSteps(std::int64_t length, std::int64_t slots) {
  if (length <= 1) return 0;
  if (slots == 1) return static_cast<PlacementCost>(length) * static_cast<PlacementCost>(length - 1) / 2;
  return static_cast<PlacementCost>(revolve::optimalForwardSteps(length, slots));
}

/// The offline optimum `online` with c checkpoints is measured against: binomial's recomputed steps at the
/// same memory, min(c + 1, N - 1) slots with the working state holding x_{N-1}, T(N, S) - (N - 1); N >= 2.
inline UnsignedInt128 binomialAtSameMemory(std::int64_t steps, std::int64_t c) {
  return revolve::workingStateRecomputedSteps(steps, std::min(c + 1, steps - 1));
}

/// simulatePlacement()'s offer of a record when the placement's offer(step) takes it: true unless it
/// answers kSkipped.
struct OfferRecord {
  template <typename Placement>
  bool operator()(Placement& placement, std::int64_t step) const {
    return placement.offer(step) != Placement::kSkipped;
  }
};

/// The placement of a whole forward sweep of N steps with c checkpoints, without states (the one
/// simulation of every online placement below): the records 1..N-1 offered in order through
/// offer(placement, step), true when the placement writes a checkpoint; returns the held positions at the
/// end. *stores counts the checkpoint writes, those held from reset() on (TwoHorizonPlacement's x_0)
/// included; *peak the most positions held at once (both optional).
template <typename Placement, typename Offer = OfferRecord>
std::vector<std::int64_t> simulatePlacement(std::int64_t steps, std::int64_t c, std::int64_t* stores,
                                            std::int64_t* peak, Offer offer = Offer()) {
  Placement placement;
  placement.reset(c);
  const auto held = [&placement] { return static_cast<std::int64_t>(placement.positions().size()); };
  std::int64_t written = held(), most = held();
  for (std::int64_t step = 1; step < steps; ++step) {
    if (!offer(placement, step)) continue;
    ++written;
    most = std::max(most, held());
  }
  if (stores != nullptr) *stores = written;
  if (peak != nullptr) *peak = most;
  return placement.positions();
}

/// `online`'s placement in a run of the engine, whose caller's working state holds x_{N-1}
/// (TrajectoryInfo::workingStateHoldsLast): the c + 1 slots all hold checkpoints, positions
/// p_0 = 0 < p_1 < ... < p_m (m <= c), and interval i (p_i to p_{i+1}, the last one to N - 1) is
/// reversed later by revolve with c + 1 - i slots: sum_i T(L_i, c + 1 - i) recomputed steps. The record
/// of x_k is stored at once or not (N is unknown). Two-horizon rule (bench/online_working_state.py, the
/// reference and the measurements): among keeping the placement, storing x_k in a free slot and replacing
/// p_j (j >= 1) by it, take the one whose worse ratio (2N + count) / (2N + binomial's count at the same
/// memory), were the run to end at N = k + 1 or N = k + 2, is least (ties: keep, then a free slot, then
/// the least j). A store costs the same at both horizons (the new last interval has 0 or 1 steps); only
/// the last interval changes between stores, so a record costs O(1) evaluations of T, a store into a
/// free slot O(1) and the replacement of p_j O(m - j) (the tables of the intervals from j - 1 on).
class TwoHorizonPlacement {
 public:
  static constexpr std::int64_t kSkipped = -2;   ///< offer(): x_k is not stored
  static constexpr std::int64_t kAppended = -1;  ///< offer(): stored without dropping a checkpoint

  /// A new forward sweep with c checkpoints (c + 1 slots); x_0 is held in slot 0 from record 0 on.
  void reset(std::int64_t checkpoints) {
    checkpoints_ = checkpoints;
    // No allocation while recording, up to 2^16 slots (a budget-derived c can be far larger than N).
    const auto reserve = static_cast<std::size_t>(std::min<std::int64_t>(checkpoints + 2, 1 << 16));
    for (std::vector<PlacementCost>* table : {&own_, &wide_, &ownPrefix_, &widePrefix_, &bestKey_})
      table->reserve(reserve);
    positions_.reserve(reserve);
    bestIndex_.reserve(reserve);
    positions_.assign(1, 0);
    extend(0);
  }
  /// The held positions, increasing; position i is in slot i.
  const std::vector<std::int64_t>& positions() const { return positions_; }

  /// The record of x_k, k >= 1 (records in order): kSkipped, kAppended (k is now the last position) or
  /// the index j of the dropped checkpoint (positions j + 1.. moved down by one, k appended).
  std::int64_t offer(std::int64_t k) {
    const std::int64_t c = checkpoints_;
    const auto m = static_cast<std::int64_t>(positions_.size()) - 1;
    const std::int64_t last = k - positions_.back();  // the last interval were the run to end at k + 1
    const PlacementCost prefix = ownPrefix_.back();   // the intervals before the last one
    const PlacementCost keepNow = prefix + intervalForwardSteps(last, c + 1 - m);
    const PlacementCost keepNext = prefix + intervalForwardSteps(last + 1, c + 1 - m);
    bool storing = false;
    PlacementCost store = 0;
    std::int64_t index = kAppended;
    if (m < c) {
      store = keepNow;  // the old last interval ends at k with its c + 1 - m slots
      storing = true;
    }
    if (m >= 2) {  // p_j dropped, 1 <= j < m: the intervals after j gain a slot, the last one too
      const PlacementCost value =
          bestKey_.back() + widePrefix_.back() + intervalForwardSteps(last, c + 2 - m);
      if (!storing || value < store) {
        store = value;
        index = bestIndex_.back();
        storing = true;
      }
    }
    if (m >= 1) {  // p_m dropped: the last two intervals merge
      const std::int64_t merged =
          positions_[static_cast<std::size_t>(m)] - positions_[static_cast<std::size_t>(m - 1)] + last;
      const PlacementCost value =
          prefix - own_[static_cast<std::size_t>(m - 1)] + intervalForwardSteps(merged, c + 2 - m);
      if (!storing || value < store) {
        store = value;
        index = m;
        storing = true;
      }
    }
    if (!storing) return kSkipped;
    const UnsignedInt128 nowLimit = binomialLimit(k + 1), nextLimit = binomialLimit(k + 2);
    const Ratio keepScore = worse(ratio(keepNow, k + 1, nowLimit), ratio(keepNext, k + 2, nextLimit));
    const Ratio storeScore = worse(ratio(store, k + 1, nowLimit), ratio(store, k + 2, nextLimit));
    if (!less(storeScore, keepScore)) return kSkipped;
    std::int64_t from = m;  // the first interval whose tables change
    if (index != kAppended) {
      positions_.erase(positions_.begin() + index);
      from = index - 1;
    }
    positions_.push_back(k);
    extend(from);
    return index;
  }

  /// simulatePlacement() of this placement (*stores with x_0).
  static std::vector<std::int64_t> simulate(std::int64_t steps, std::int64_t c, std::int64_t* stores,
                                            std::int64_t* peak) {
    return simulatePlacement<TwoHorizonPlacement>(steps, c, stores, peak);
  }

 private:
  struct Ratio {
    UnsignedInt128 numerator, denominator;
  };
  // 2N + binomial's recomputed steps at the same memory (min(c + 1, N - 1) slots, the working state
  // holding x_{N-1}: T(N, S) - (N - 1)), N >= 2.
  UnsignedInt128 binomialLimit(std::int64_t steps) const {
    return 2 * static_cast<UnsignedInt128>(steps) + binomialAtSameMemory(steps, checkpoints_);
  }
  static Ratio ratio(PlacementCost cost, std::int64_t steps, UnsignedInt128 limit) {
    return Ratio{2 * static_cast<UnsignedInt128>(steps) + static_cast<UnsignedInt128>(cost), limit};
  }
  // a/b < c/d exactly, without products (Euclid's continued fraction expansion of both).
  static bool less(Ratio x, Ratio y) {
    UnsignedInt128 a = x.numerator, b = x.denominator, c = y.numerator, d = y.denominator;
    for (;;) {
      const UnsignedInt128 qa = a / b, qc = c / d;
      if (qa != qc) return qa < qc;
      a -= qa * b;
      c -= qc * d;
      if (a == 0 || c == 0) return a == 0 && c != 0;
      // a/b < c/d with both in (0, 1) exactly when d/c < b/a.
      const UnsignedInt128 na = d, nb = c, nc = b, nd = a;
      a = na;
      b = nb;
      c = nc;
      d = nd;
    }
  }
  static Ratio worse(Ratio x, Ratio y) { return less(x, y) ? y : x; }

  // The tables of the intervals 0..m-1 (the last one, m, changes every record) from interval `from` on;
  // those before it are kept. With W_i = T(L_i, c + 2 - i) (interval i with one slot more, as when a
  // checkpoint before it is dropped), dropping p_j (1 <= j < m) costs, without the last interval's part,
  //   sum_{i < j-1} own_i + T(p_{j+1} - p_{j-1}, c + 2 - j) + sum_{j < i < m} W_i = key_j + sum_{i < m} W_i,
  // key_j = ownPrefix_[j - 1] + T(p_{j+1} - p_{j-1}, c + 2 - j) - widePrefix_[j + 1], which depends on
  // the intervals up to j only; bestKey_/bestIndex_[j] hold the least key_1..key_j (the least index at
  // ties). A store into a free slot (from = m - 1 of the new m) costs O(1), dropping p_j O(m - j).
  void extend(std::int64_t from) {
    const std::int64_t c = checkpoints_;
    const auto m = static_cast<std::int64_t>(positions_.size()) - 1;
    const auto keep = static_cast<std::size_t>(from);
    own_.resize(keep);
    wide_.resize(keep);
    ownPrefix_.resize(keep + 1, 0);
    widePrefix_.resize(keep + 1, 0);
    bestKey_.resize(std::max<std::size_t>(keep, 1), 0);  // entry 0 unused: p_0 is never dropped
    bestIndex_.resize(std::max<std::size_t>(keep, 1), -1);
    for (std::int64_t i = from; i < m; ++i) {
      const auto u = static_cast<std::size_t>(i);
      const std::int64_t length = positions_[u + 1] - positions_[u];
      own_.push_back(intervalForwardSteps(length, c + 1 - i));
      wide_.push_back(intervalForwardSteps(length, c + 2 - i));
      ownPrefix_.push_back(ownPrefix_.back() + own_.back());
      widePrefix_.push_back(widePrefix_.back() + wide_.back());
    }
    for (std::int64_t j = std::max<std::int64_t>(from, 1); j < m; ++j) {
      const auto u = static_cast<std::size_t>(j);
      const PlacementCost key = ownPrefix_[u - 1] +
                                intervalForwardSteps(positions_[u + 1] - positions_[u - 1], c + 2 - j) -
                                widePrefix_[u + 1];
      const bool better = j == 1 || key < bestKey_.back();
      bestKey_.push_back(better ? key : bestKey_.back());
      bestIndex_.push_back(better ? j : bestIndex_.back());
    }
  }

  std::int64_t checkpoints_ = 1;
  std::vector<std::int64_t> positions_{0};
  std::vector<PlacementCost> own_, wide_, ownPrefix_, widePrefix_, bestKey_;
  std::vector<std::int64_t> bestIndex_;
};

/// `online`'s placement (the rules and what is known of them: engine/online_checkpointing.h). Once c
/// checkpoints are held, each record offers the previous working state q; the intervals L_i between the
/// held positions are reversed later by revolve with c + 1 - i slots (T(L_i, c + 1 - i) recomputed steps:
/// its own slot, those of the later checkpoints and the working state's, free once x_{N-1} is consumed).
///  * Cost rule (run lengths N <= beta(c + 1, 2) and N > beta(c + 1, 3)): q replaces the checkpoint
///    j >= 1 whose removal (its two intervals merge, the later ones gain a slot each, q starts a new last
///    interval) gives the least total sum_i T(L_i, c + 1 - i) were the run to end at this record,
///    provided that total is not above keeping the placement (ties: the earlier j, and replacing). Only
///    the last interval changes between replacements, so a record costs O(1) evaluations of T and a
///    replacement O(c).
///  * Six-step rule (beta(c + 1, 2) < N <= beta(c + 1, 3), Stumm & Walther's three-step rule moved to
///    this game): q is taken when the last interval has reached beta(2, 2) = 6 steps (what its two slots
///    reverse at repetition number 2; Stumm & Walther's 3 = beta(1, 2) is that of their one slot), or
///    when q is the next of the final positions F_k = sum_{i<k} beta(c + 1 - i, 2) (the placement with
///    every interval at the most its c + 1 - i slots reverse at repetition number 2) in order; a
///    checkpoint taken at F_k stays until beta(c + 1, 3). q replaces the latest checkpoint j >= 1 not at
///    a final position whose two intervals merge into at most beta(s, 2) steps, s = c + 2 - j the slots
///    of the merged interval; landing on F_k before the last interval has 6 steps replaces the latest
///    checkpoint if it is not final. O(c) per taken candidate, about every sixth record.
class CostPlacement {
 public:
  static constexpr std::int64_t kSkipped = -2;   ///< offer(): the candidate is not kept
  static constexpr std::int64_t kAppended = -1;  ///< offer(): kept without dropping a checkpoint

  void reset(std::int64_t checkpoints) {
    checkpoints_ = checkpoints;
    positions_.clear();
    // No allocation while recording, up to 2^16 checkpoints (a budget-derived c can be far larger than N).
    const auto reserve = static_cast<std::size_t>(std::min<std::int64_t>(checkpoints, 1 << 16));
    positions_.reserve(reserve);
    final_.reserve(reserve);
    final_.clear();
    own_.reserve(reserve);
    grow_.reserve(reserve);
    suffix_.reserve(reserve + 1);
    innerBest_ = 0;
    innerIndex_ = -1;
    second_ = revolve::beta(checkpoints + 1, 2);
    third_ = revolve::beta(checkpoints + 1, 3);
    nextFinal_ = second_;
    finalCount_ = 1;
    stale_ = false;
  }
  /// The held positions, increasing; position i is in slot i.
  const std::vector<std::int64_t>& positions() const { return positions_; }

  /// The record of `step` >= 1 arrived: decides about the candidate q = step - 1 (the working state
  /// until now). Returns kSkipped, kAppended (q is now the last position) or the index j of the dropped
  /// checkpoint (positions j + 1.. moved down by one, q appended).
  std::int64_t offer(std::int64_t step) {
    const std::int64_t q = step - 1;
    const auto held = static_cast<std::int64_t>(positions_.size());
    const std::int64_t c = checkpoints_;
    if (held < c) {
      positions_.push_back(q);
      final_.push_back(held == 0);  // x_0 is never dropped
      if (held + 1 == c) rebuild();
      return kAppended;
    }
    if (c == 1) return kSkipped;                               // one interval: nothing to merge
    const auto steps = static_cast<UnsignedInt128>(step) + 1;  // the run's length were it to end now
    if (steps > second_ && steps <= third_) return offerSixStep(q);
    if (stale_) {
      rebuild();
      stale_ = false;
    }
    const std::int64_t last = q - positions_.back();  // the last interval if q is kept (>= 1)
    // Keeping the placement: the last interval (2 slots) grows by one step. Taking q: the old last
    // interval ends at q and moves up (3 slots, or merged), the new one (one step) costs nothing.
    const Cost lastOwn = revolveSteps(last, 2);
    const Cost skip = revolveSteps(last + 1, 2) - lastOwn;
    Cost best = 0;
    std::int64_t index = -1;
    if (innerIndex_ >= 1) {
      best = innerBest_ + (revolveSteps(last, 3) - lastOwn);  // the last interval moves up, to 3 slots
      index = innerIndex_;
    }
    const std::size_t before = static_cast<std::size_t>(c - 2);
    const Cost lastPair =
        revolveSteps(positions_[before + 1] - positions_[before] + last, 3) - own_[before] - lastOwn;
    if (index < 0 || lastPair < best) {
      best = lastPair;
      index = c - 1;
    }
    if (best > skip) return kSkipped;
    drop(index, q, false);
    rebuild();
    return index;
  }

  /// simulatePlacement() of this placement.
  static std::vector<std::int64_t> simulate(std::int64_t steps, std::int64_t c, std::int64_t* stores) {
    return simulatePlacement<CostPlacement>(steps, c, stores, nullptr);
  }

 private:
  typedef PlacementCost Cost;

  // Drops checkpoint j and appends q (marked final or not).
  void drop(std::int64_t j, std::int64_t q, bool final) {
    positions_.erase(positions_.begin() + j);
    final_.erase(final_.begin() + j);
    positions_.push_back(q);
    final_.push_back(final);
  }
  // The six-step rule (class comment). The cost rule's tables are rebuilt once it resumes.
  std::int64_t offerSixStep(std::int64_t q) {
    const std::int64_t c = checkpoints_;
    const bool landing = finalCount_ < c && static_cast<UnsignedInt128>(q) == nextFinal_;
    const bool early = q - positions_.back() < 6;
    if (early && !landing) return kSkipped;
    for (std::int64_t j = c - 1; j >= 1; --j) {
      const auto u = static_cast<std::size_t>(j);
      if (final_[u]) continue;
      const std::int64_t end = j + 1 < c ? positions_[u + 1] : q;
      // Landing early on a final position drops the latest checkpoint whatever its merged length.
      if (!(early && j == c - 1) &&
          static_cast<UnsignedInt128>(end - positions_[u - 1]) > revolve::beta(c - j + 2, 2))
        continue;
      drop(j, q, landing);
      if (landing) {
        nextFinal_ += revolve::beta(c + 1 - finalCount_, 2);
        ++finalCount_;
      }
      stale_ = true;
      return j;
    }
    return kSkipped;
  }
  static Cost revolveSteps(std::int64_t length, std::int64_t slots) {
    return intervalForwardSteps(length, slots);
  }
  // With c checkpoints held: the intervals 0..c-2 (the last one changes every record), their costs
  // own_[i] = T(L_i, c + 1 - i) and grow_[i] = T(L_i, c + 2 - i) - own_[i] (one slot more, as when an
  // earlier checkpoint is dropped), and the best drop among j = 1..c-2 without the last interval's part.
  void rebuild() {
    const std::int64_t c = checkpoints_;
    own_.clear();
    grow_.clear();
    for (std::int64_t i = 0; i + 1 < c; ++i) {
      const std::int64_t length =
          positions_[static_cast<std::size_t>(i + 1)] - positions_[static_cast<std::size_t>(i)];
      own_.push_back(revolveSteps(length, c + 1 - i));
      grow_.push_back(revolveSteps(length, c + 2 - i) - own_.back());
    }
    suffix_.assign(static_cast<std::size_t>(c), 0);  // suffix_[k] = sum of grow_[k..c-2]
    for (std::int64_t k = c - 2; k >= 0; --k)
      suffix_[static_cast<std::size_t>(k)] =
          suffix_[static_cast<std::size_t>(k + 1)] + grow_[static_cast<std::size_t>(k)];
    innerIndex_ = -1;
    for (std::int64_t j = 1; j + 1 < c; ++j) {
      const auto u = static_cast<std::size_t>(j);
      const std::int64_t merged = positions_[u + 1] - positions_[u - 1];
      const Cost cost = revolveSteps(merged, c + 2 - j) - own_[u - 1] - own_[u] + suffix_[u + 1];
      if (innerIndex_ < 0 || cost < innerBest_) {
        innerBest_ = cost;
        innerIndex_ = j;
      }
    }
  }

  std::int64_t checkpoints_ = 1;
  std::vector<std::int64_t> positions_;
  std::vector<char> final_;  // position i is a final position of the six-step rule (or x_0)
  UnsignedInt128 second_ = 0, third_ = 0, nextFinal_ = 0;
  std::int64_t finalCount_ = 1;  // final positions held, x_0 included
  bool stale_ = false;           // own_, grow_, suffix_ not rebuilt since the six-step rule moved
  std::vector<Cost> own_, grow_, suffix_;
  Cost innerBest_ = 0;
  std::int64_t innerIndex_ = -1;
};

class OnlinePlacement {
 public:
  /// Forward-sweep checkpoint limit F = ceil(c / 2).
  static std::int64_t forwardCheckpoints(std::int64_t c) { return (c + 1) / 2; }
  /// The final spacing d for N steps: positions 0..N-2 are candidates (N - 1 stays the working state).
  static std::int64_t finalSpacing(std::int64_t steps, std::int64_t c) {
    if (steps - 2 < c) return 1;
    const std::int64_t forward = forwardCheckpoints(c);
    std::int64_t spacing = 2;
    while (forward * spacing <= steps - 2) spacing *= 2;
    return spacing;
  }

  /// simulatePlacement() of this placement: the record of `step` offers the working state x_{step-1}.
  static std::vector<std::int64_t> simulate(std::int64_t steps, std::int64_t c, std::int64_t* stores,
                                            std::int64_t* peak) {
    return simulatePlacement<OnlinePlacement>(
        steps, c, stores, peak, [](OnlinePlacement& placement, std::int64_t step) {
          return placement.isCandidate(step - 1) &&
                 placement.commit(step - 1, [](std::int64_t, std::int64_t) {}) >= 0;
        });
  }

  /// An interval of the backward sweep: from held position `start` (index `index`) over `length` steps, to
  /// the next held position or N - 1.
  struct Interval {
    std::int64_t index, start, length;
  };
  /// The interval holding `step` (< N - 1): the last held position at or before it, searched downwards
  /// from index `below` - 1 (the previous interval's index, or positions.size()), so the lookups of a whole
  /// backward sweep cost O(positions) in total.
  static Interval intervalOf(const std::vector<std::int64_t>& positions, std::int64_t steps,
                             std::int64_t step, std::int64_t below) {
    std::int64_t j = std::min(below, static_cast<std::int64_t>(positions.size())) - 1;
    while (positions[static_cast<std::size_t>(j)] > step) --j;
    const std::int64_t start = positions[static_cast<std::size_t>(j)];
    const std::int64_t end = j + 1 < static_cast<std::int64_t>(positions.size())
                                 ? positions[static_cast<std::size_t>(j + 1)]
                                 : steps - 1;
    return Interval{j, start, end - start};
  }
  /// The longest interval of a placement of N steps (0 for N <= 1).
  static std::int64_t longestInterval(const std::vector<std::int64_t>& positions, std::int64_t steps) {
    std::int64_t longest = 0;
    for (std::size_t j = 0; j < positions.size(); ++j)
      longest = std::max(longest, (j + 1 < positions.size() ? positions[j + 1] : steps - 1) - positions[j]);
    return longest;
  }

  void reset(std::int64_t checkpoints) {
    checkpoints_ = checkpoints;
    limit_ = forwardCheckpoints(checkpoints);
    spacing_ = 1;
    positions_.clear();
    // No allocation while recording, up to 2^16 checkpoints (a budget-derived c can be far larger than N).
    positions_.reserve(static_cast<std::size_t>(std::min<std::int64_t>(checkpoints, 1 << 16)));
  }
  std::int64_t spacing() const { return spacing_; }
  /// The held positions; position i is in slot i.
  const std::vector<std::int64_t>& positions() const { return positions_; }
  /// Whether the working state at `position`, about to be replaced, is a candidate.
  bool isCandidate(std::int64_t position) const { return position % spacing_ == 0; }
  /// Offers a candidate. Thinning moves the checkpoint of slot `from` to slot `to` (to <= from, in
  /// increasing order) through move(from, to). Returns the slot the state goes to, or -1 when thinning
  /// made the position no longer a multiple of d.
  template <typename Move>
  std::int64_t commit(std::int64_t position, Move&& move) {
    while (static_cast<std::int64_t>(positions_.size()) >= (spacing_ == 1 ? checkpoints_ : limit_)) {
      std::size_t kept = 0;
      for (std::size_t i = 0; i < positions_.size(); i += 2, ++kept) {
        positions_[kept] = positions_[i];
        move(static_cast<std::int64_t>(i), static_cast<std::int64_t>(kept));
      }
      positions_.resize(kept);
      spacing_ *= 2;
      if (position % spacing_ != 0) return -1;
    }
    positions_.push_back(position);
    return static_cast<std::int64_t>(positions_.size()) - 1;
  }

 private:
  std::int64_t checkpoints_ = 1, limit_ = 1, spacing_ = 1;
  std::vector<std::int64_t> positions_;
};

}  // namespace hindsight::internal
