// Where the online strategies keep checkpoints while the number of steps is unknown.
//
// CostPlacement (`online`): documented with its guarantee in engine/online_checkpointing.h.
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

  /// The placement of a whole forward sweep of N steps with c checkpoints, without states: the held
  /// positions at its end; *stores (optional) counts the checkpoint writes.
  static std::vector<std::int64_t> simulate(std::int64_t steps, std::int64_t c, std::int64_t* stores) {
    CostPlacement placement;
    placement.reset(c);
    std::int64_t written = 0;
    for (std::int64_t step = 1; step < steps; ++step)
      if (placement.offer(step) != kSkipped) ++written;
    if (stores != nullptr) *stores = written;
    return placement.positions_;
  }

 private:
  __extension__ typedef __int128 Cost;

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
    if (length <= 1) return 0;
    if (slots == 1) return static_cast<Cost>(length) * static_cast<Cost>(length - 1) / 2;
    return static_cast<Cost>(revolve::optimalForwardSteps(length, slots));
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

  /// The placement of a whole forward sweep of N steps with c checkpoints, without states: the held
  /// positions at its end; *stores counts the checkpoint writes, *peak the most checkpoints held at once
  /// (both optional).
  static std::vector<std::int64_t> simulate(std::int64_t steps, std::int64_t c, std::int64_t* stores,
                                            std::int64_t* peak) {
    OnlinePlacement placement;
    placement.reset(c);
    std::int64_t written = 0, most = 0;
    for (std::int64_t step = 1; step < steps; ++step) {
      if (placement.isCandidate(step - 1) &&
          placement.commit(step - 1, [](std::int64_t, std::int64_t) {}) >= 0) {
        ++written;
        most = std::max(most, static_cast<std::int64_t>(placement.positions().size()));
      }
    }
    if (stores != nullptr) *stores = written;
    if (peak != nullptr) *peak = most;
    return placement.positions();
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
