// Where the online strategies keep checkpoints while the number of steps is unknown (shared by
// `online` and `cams` with adaptive steps or online=1). The rule and its guarantee are documented in
// engine/online_checkpointing.h: the last recorded state is the working state; when the next record
// arrives it becomes a candidate if its position is a multiple of the spacing d; checkpoints are all
// multiples of d among the candidates, at most c while d = 1 and at most F = ceil(c / 2) afterwards;
// reaching the limit drops every other checkpoint and doubles d (repeated if needed).
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace hindsight::internal {

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
      if (placement.isCandidate(step - 1) && placement.commit(step - 1, [](std::int64_t, std::int64_t) {}) >= 0) {
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
  static Interval intervalOf(const std::vector<std::int64_t>& positions, std::int64_t steps, std::int64_t step,
                             std::int64_t below) {
    std::int64_t j = std::min(below, static_cast<std::int64_t>(positions.size())) - 1;
    while (positions[static_cast<std::size_t>(j)] > step) --j;
    const std::int64_t start = positions[static_cast<std::size_t>(j)];
    const std::int64_t end =
        j + 1 < static_cast<std::int64_t>(positions.size()) ? positions[static_cast<std::size_t>(j + 1)] : steps - 1;
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
