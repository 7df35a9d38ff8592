#include <hindsight/storage/k_level_plan.h>

#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/interrupt.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iterator>
#include <limits>
#include <stdexcept>

namespace hindsight {

namespace {

// The rows of the hierarchical programme's tables: every length 0..min(N, exactLengths), then a geometric
// grid up to N, each length at least `spacing` times the previous one further (and at least one more).
std::vector<std::int64_t> gradedLengths(std::int64_t steps, std::int64_t exactLengths, double spacing) {
  std::vector<std::int64_t> lengths;
  for (std::int64_t l = 0; l <= std::min(steps, exactLengths); ++l) lengths.push_back(l);
  while (lengths.back() < steps) {
    const auto next =
        static_cast<std::int64_t>(std::ceil(static_cast<double>(lengths.back()) * (1.0 + spacing)));
    lengths.push_back(std::min(steps, std::max(next, lengths.back() + 1)));
  }
  return lengths;
}

}  // namespace

// The tables of the programme (storage/k_level_plan.h): for every length l, level L and free-slot vector f
// (mixed radix over capacity + 1), the backward values with and without moves and the forward values.
struct KLevelPlan::Tables {
  std::int64_t steps = 0;
  int levels = 0;
  std::vector<std::int64_t> capacity, stride;  // stride[k]: index step of f_k
  std::int64_t cells = 1;                      // prod(capacity_k + 1)
  struct Entry {
    double cost;
    std::int32_t distance;
    std::int8_t action;
    std::int8_t level;
  };
  // backward: [l][L][cell], forward: [l][cell]. The values without moves (G') are kept for the length at
  // hand only: after a move the executor reads `backward`, which equals them there (a move back, or on to
  // a third level, is never strictly cheaper than the move just made: w_k + G'_k <= w_i + G'_i for the
  // level k chosen and any other i, and w >= 0).
  std::vector<Entry> backward, forward;
  std::size_t at(std::int64_t l, int level, std::int64_t cell) const {
    return static_cast<std::size_t>((l * levels + level) * cells + cell);
  }
  std::size_t at(std::int64_t l, std::int64_t cell) const {
    return static_cast<std::size_t>(l * cells + cell);
  }
  std::int64_t freeAt(std::int64_t cell, int k) const { return (cell / stride[k]) % (capacity[k] + 1); }
};

void KLevelPlan::checkArguments(std::int64_t steps, std::int64_t ramSlots,
                                const std::vector<StorageLevelCosts>& levels, double forwardStep,
                                std::vector<std::int64_t>& capacity, std::vector<double>& write,
                                std::vector<double>& read) {
  if (steps < 1) throw std::invalid_argument("K-level plan: N = " + std::to_string(steps) + " must be >= 1");
  if (ramSlots < 0)
    throw std::invalid_argument("K-level plan: RAM slots = " + std::to_string(ramSlots) + " must be >= 0");
  if (!(forwardStep > 0.0))
    throw std::invalid_argument("K-level plan: the forward step's cost must be positive");
  capacity.assign(1, std::min(ramSlots, steps));
  write.assign(1, 0.0);
  read.assign(1, 0.0);
  for (std::size_t k = 0; k < levels.size(); ++k) {
    const StorageLevelCosts& level = levels[k];
    const std::string name = "K-level plan: level " + std::to_string(k + 1);
    if (level.slots < 0)
      throw std::invalid_argument(name + " slots = " + std::to_string(level.slots) + " must be >= 0");
    if (!(level.write >= 0.0) || !(level.read >= 0.0))
      throw std::invalid_argument(name + ": write and read costs must be >= 0");
    capacity.push_back(std::min(level.slots, steps));
    write.push_back(level.write);
    read.push_back(level.read);
  }
  std::int64_t total = 0;
  for (std::int64_t c : capacity) total += c;
  if (steps >= 2 && (capacity[0] < 1 || total < 2)) {
    throw std::invalid_argument("K-level plan: " + std::to_string(ramSlots) + " RAM slots and " +
                                std::to_string(total - capacity[0]) +
                                " slots below cannot reverse N >= 2 steps; RAM must hold one state and all "
                                "levels two");
  }
}

void KLevelPlan::finish(double uf, const std::vector<double>& write, const std::vector<double>& read) {
  counts_ = walk();
  counts_.cost = static_cast<double>(counts_.recomputedSteps) * uf;
  for (int k = 1; k < levelCount(); ++k) {
    counts_.cost +=
        static_cast<double>(counts_.writes[static_cast<std::size_t>(k)]) *
            write[static_cast<std::size_t>(k)] +
        static_cast<double>(counts_.reads[static_cast<std::size_t>(k)]) * read[static_cast<std::size_t>(k)];
  }
}

KLevelPlan KLevelPlan::optimal(std::int64_t steps, std::int64_t ramSlots,
                               const std::vector<StorageLevelCosts>& levels, double forwardStep) {
  std::vector<std::int64_t> capacity;
  std::vector<double> write, read;
  checkArguments(steps, ramSlots, levels, forwardStep, capacity, write, read);
  auto tables = std::make_shared<Tables>();
  Tables& t = *tables;
  t.steps = steps;
  t.levels = static_cast<int>(capacity.size());
  t.capacity = capacity;
  // The work bound in floating point: the product may overflow 64 bits long before it is refused.
  double work = static_cast<double>(steps) * static_cast<double>(steps) * t.levels * t.levels;
  for (std::int64_t c : capacity) {
    t.stride.push_back(t.cells);
    work *= static_cast<double>(c + 1);
    if (work > static_cast<double>(kMaxWork)) break;
    t.cells *= c + 1;
  }
  if (work > static_cast<double>(kMaxWork)) {
    throw std::invalid_argument(
        "K-level plan: N = " + std::to_string(steps) +
        " with these slots exceeds the reference's work limit N^2 K^2 prod(s_k + 1) <= 2^30");
  }
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const std::size_t size = static_cast<std::size_t>((steps + 1) * t.levels * t.cells);
  t.backward.assign(size, Tables::Entry{kInfinity, 0, kDone, 0});
  t.forward.assign(static_cast<std::size_t>((steps + 1) * t.cells), Tables::Entry{kInfinity, 0, 0, 0});
  std::vector<Tables::Entry> plain(static_cast<std::size_t>(t.levels * t.cells));  // G' at length l
  const auto plainAt = [&](int level, std::int64_t cell) -> Tables::Entry& {
    return plain[static_cast<std::size_t>(level * t.cells + cell)];
  };
  std::vector<std::int64_t> freeSlots(capacity.size());  // of the cell at hand, per level
  const double uf = forwardStep;
  const auto loaded = [&](int level, std::int64_t l, std::int64_t cell) {  // F_L
    return read[level] + t.backward[t.at(l, level, cell)].cost;
  };
  for (std::int64_t l = 1; l <= steps; ++l) {
    pollInterrupt();
    for (std::int64_t cell = 0; cell < t.cells; ++cell) {
      for (int k = 0; k < t.levels; ++k) freeSlots[static_cast<std::size_t>(k)] = t.freeAt(cell, k);
      for (int level = 0; level < t.levels; ++level) {
        Tables::Entry best{l == 1 ? 0.0 : kInfinity, 0, static_cast<std::int8_t>(l == 1 ? kDone : kNone), 0};
        if (l >= 2) {
          best.cost = static_cast<double>(l - 1) * uf + loaded(level, l - 1, cell);
          for (std::int64_t j = 1; j <= l - 2; ++j) {
            const double lower = static_cast<double>(j) * uf + loaded(level, j, cell);
            for (int k = 0; k < t.levels; ++k) {
              if (freeSlots[static_cast<std::size_t>(k)] < 1) continue;
              const double cost = lower + write[k] + t.backward[t.at(l - j, k, cell - t.stride[k])].cost;
              if (cost < best.cost)
                best = {cost, static_cast<std::int32_t>(j), kStore, static_cast<std::int8_t>(k)};
            }
          }
        }
        plainAt(level, cell) = best;
      }
    }
    for (std::int64_t cell = 0; cell < t.cells; ++cell) {
      for (int k = 0; k < t.levels; ++k) freeSlots[static_cast<std::size_t>(k)] = t.freeAt(cell, k);
      for (int level = 0; level < t.levels; ++level) {
        Tables::Entry best = plainAt(level, cell);
        if (l >= 2 && freeSlots[static_cast<std::size_t>(level)] < t.capacity[level]) {
          for (int k = 0; k < t.levels; ++k) {
            if (k == level || freeSlots[static_cast<std::size_t>(k)] < 1) continue;
            const std::int64_t moved = cell - t.stride[k] + t.stride[level];
            const double cost = write[k] + plainAt(k, moved).cost;
            if (cost < best.cost) best = {cost, 0, kMove, static_cast<std::int8_t>(k)};
          }
        }
        t.backward[t.at(l, level, cell)] = best;
      }
    }
    for (std::int64_t cell = 0; cell < t.cells; ++cell) {
      Tables::Entry best{kInfinity, 0, 0, 0};
      for (int level = 0; level < t.levels; ++level) {
        if (t.freeAt(cell, level) < 1) continue;
        const std::int64_t rest = cell - t.stride[level];
        double cost = write[level] + loaded(level, l, rest);
        if (cost < best.cost) best = {cost, 0, static_cast<std::int8_t>(level), 0};
        for (std::int64_t j = 1; j <= l - 1; ++j) {
          cost = write[level] + t.forward[t.at(l - j, rest)].cost + loaded(level, j, rest);
          if (cost < best.cost)
            best = {cost, static_cast<std::int32_t>(j), static_cast<std::int8_t>(level), 0};
        }
      }
      t.forward[t.at(l, cell)] = best;
    }
  }
  const std::int64_t all = t.cells - 1;  // every slot free
  if (!(t.forward[t.at(steps, all)].cost < kInfinity))
    throw std::invalid_argument("K-level plan: no schedule for N = " + std::to_string(steps));
  KLevelPlan plan;
  plan.steps_ = steps;
  plan.capacity_ = capacity;
  plan.optimum_ = t.forward[t.at(steps, all)].cost;
  plan.tables_ = std::move(tables);
  plan.finish(uf, write, read);
  return plan;
}

// ---- the hierarchical family ----

// The programme's tables over rows of segment lengths: every length 1..exact, then (graded()) a geometric
// grid of lengths up to N, each at least `spacing` times the previous one further. Values between rows are
// interpolated linearly. A row is computed level by level and slot count by slot count, ascending, so that
// the values a split needs between the previous row and the current one (the second part with one slot
// less, or at a faster level) are interpolated from entries already done; only what is not done yet is
// extrapolated from the two rows before.
struct KLevelPlan::HierarchicalTables {
  std::int64_t steps = 0;
  std::int64_t exact = 0;   // rows 0..exact are the lengths 0..exact
  std::int64_t window = 0;  // 0: full split search
  double uf = 0.0;
  std::vector<double> write, read;
  std::vector<std::int64_t> capacity, offset;  // offset[k]: first column of level k; columns m = 0..s_k
  std::vector<std::int64_t> lengths;           // lengths[row]
  std::int64_t columns = 0;
  // Entries done: rows 0..rows-1 and the columns 0..columns-1 of the next row, for each table.
  struct Done {
    std::int64_t rows = 0, columns = 0;
  } backwardDone, forwardDone;
  struct Entry {
    double cost;
    std::int32_t distance;
    std::int8_t action;  // E: kDone, kNone, kStore, kMove; W: unused
    std::int8_t level;   // the level stored at (moved to)
  };
  std::vector<Entry> backward, forward;  // [row][column]
  static constexpr double kInfinity = std::numeric_limits<double>::infinity();

  std::size_t at(std::int64_t row, int level, std::int64_t m) const {
    return static_cast<std::size_t>(row * columns + offset[static_cast<std::size_t>(level)] + m);
  }
  std::int64_t rows() const { return static_cast<std::int64_t>(lengths.size()); }
  /// The last row whose length is at most l (l >= 0).
  std::int64_t rowOf(std::int64_t l) const {
    if (l <= exact) return l;
    return static_cast<std::int64_t>(std::upper_bound(lengths.begin(), lengths.end(), l) - lengths.begin()) -
           1;
  }
  /// The table's value for a segment of l states (a row's, else interpolated or extrapolated).
  double cost(const std::vector<Entry>& table, std::int64_t l, int level, std::int64_t m) const {
    const std::int64_t row = rowOf(l);
    const double value = table[at(row, level, m)].cost;
    if (lengths[static_cast<std::size_t>(row)] == l) return value;
    const Done& done = &table == &backward ? backwardDone : forwardDone;
    const bool inside = row + 1 < done.rows ||
                        (row + 1 == done.rows && offset[static_cast<std::size_t>(level)] + m < done.columns);
    const std::int64_t other = inside ? row + 1 : row - 1;
    const double second = table[at(other, level, m)].cost;
    if (!(value < kInfinity) || !(second < kInfinity)) return kInfinity;
    const double x0 = static_cast<double>(lengths[static_cast<std::size_t>(row)]);
    const double x1 = static_cast<double>(lengths[static_cast<std::size_t>(other)]);
    return value + (second - value) * (static_cast<double>(l) - x0) / (x1 - x0);
  }
  double backwardCost(std::int64_t l, int level, std::int64_t m) const { return cost(backward, l, level, m); }
  /// min_{i<k} w_i + E_i(l, s_i - 1): the cheapest store of a segment's first state at a faster level, and
  /// that level (-1: none).
  std::pair<double, int> storeBelow(int k, std::int64_t l) const {
    std::pair<double, int> best{kInfinity, -1};
    for (int i = 0; i < k; ++i) {
      const std::int64_t c = capacity[static_cast<std::size_t>(i)];
      if (c < 1) continue;
      const double value = write[static_cast<std::size_t>(i)] + backwardCost(l, i, c - 1);
      if (value < best.first) best = {value, i};
    }
    return best;
  }
  /// E_k(l, m) (storage/k_level_plan.h) with the splits j = lengths[row], row in [first, last].
  Entry backwardEntry(std::int64_t l, int k, std::int64_t m, std::int64_t first, std::int64_t last) const {
    const std::size_t kk = static_cast<std::size_t>(k);
    if (l == 1) return Entry{0.0, 0, kDone, 0};
    Entry best{kInfinity, 0, kNone, 0};
    // Advancing to the segment's end: beyond the exact lengths only where nothing can be stored (RAM with no
    // free slot, (l - 1) l / 2 steps); elsewhere a store is cheaper for such lengths.
    if (l <= exact)
      best.cost = static_cast<double>(l - 1) * uf + read[kk] + backwardCost(l - 1, k, m);
    else if (k == 0 && m == 0)
      best.cost = 0.5 * static_cast<double>(l - 1) * static_cast<double>(l) * uf;
    double bestSplit = kInfinity;  // the cheapest store, chosen or not
    std::int32_t split = 0;
    for (std::int64_t row = first; row <= last; ++row) {
      const std::int64_t j = lengths[static_cast<std::size_t>(row)];
      const double left = static_cast<double>(j) * uf + read[kk] + backwardCost(j, k, m);
      double value = kInfinity;
      int level = -1;
      if (m >= 1) {
        value = left + write[kk] + backwardCost(l - j, k, m - 1);
        level = k;
      }
      const auto [store, below] = storeBelow(k, l - j);
      if (below >= 0 && left + store < value) {
        value = left + store;
        level = below;
      }
      if (level >= 0 && value < bestSplit) {
        bestSplit = value;
        split = static_cast<std::int32_t>(j);
      }
      if (value < best.cost)
        best = {value, static_cast<std::int32_t>(j), kStore, static_cast<std::int8_t>(level)};
    }
    // Move x_p to a faster level and reverse the whole segment from there (one read instead of many).
    const auto [store, level] = storeBelow(k, l);
    if (level >= 0 && store < best.cost) best = {store, 0, kMove, static_cast<std::int8_t>(level)};
    // An advance or a move keeps the cheapest split as its distance (the executor reads a distance for a
    // store only): the next length's window centres on it, where a distance of 0 would search every
    // length (many free slots with a cheap move to RAM: minutes at N = 1000 with 50 RAM and 1000 disk
    // slots before).
    if (best.action != kStore) best.distance = split;
    return best;
  }
  /// W_k(l, m) without the faster levels' W_{k-1}(l, s_{k-1}), splits as backwardEntry's.
  Entry forwardEntry(std::int64_t l, int k, std::int64_t m, std::int64_t first, std::int64_t last) const {
    const std::size_t kk = static_cast<std::size_t>(k);
    Entry best{kInfinity, 0, 0, 0};
    if (m < 1) return best;
    best = {write[kk] + read[kk] + backwardCost(l, k, m - 1), 0, 0, static_cast<std::int8_t>(k)};
    for (std::int64_t row = first; row <= last; ++row) {
      const std::int64_t j = lengths[static_cast<std::size_t>(row)];
      const double value = write[kk] + cost(forward, l - j, k, m - 1) + read[kk] + backwardCost(j, k, m - 1);
      if (value < best.cost) best = {value, static_cast<std::int32_t>(j), 0, static_cast<std::int8_t>(k)};
    }
    return best;
  }
  /// The rows of the splits searched for length l whose previous row's best split was `previous`, the
  /// splits at most `top`: all, or within `window` rows of the previous best scaled to l.
  std::pair<std::int64_t, std::int64_t> splits(std::int64_t l, std::int64_t previousLength,
                                               std::int64_t previous, std::int64_t top) const {
    const std::int64_t last = rowOf(top);
    if (window <= 0 || previous <= 0) return {1, last};
    std::int64_t center = previous;
    if (l > exact) {
      center = rowOf(static_cast<std::int64_t>(static_cast<double>(previous) * static_cast<double>(l) /
                                               static_cast<double>(previousLength)));
    }
    return {std::max<std::int64_t>(1, center - window), std::min(last, center + window)};
  }
};

KLevelPlan KLevelPlan::hierarchical(std::int64_t steps, std::int64_t ramSlots,
                                    const std::vector<StorageLevelCosts>& levels, double forwardStep,
                                    std::int64_t window) {
  return solveHierarchical(steps, ramSlots, levels, forwardStep, window, steps, 0.0);
}

KLevelPlan KLevelPlan::graded(std::int64_t steps, std::int64_t ramSlots,
                              const std::vector<StorageLevelCosts>& levels, double forwardStep,
                              GradedGrid grid) {
  if (grid.exactLengths < 1 || grid.spacingDivisor < 1) {
    throw std::invalid_argument("K-level plan (graded): the grid's exact lengths (" +
                                std::to_string(grid.exactLengths) + ") and spacing divisor (" +
                                std::to_string(grid.spacingDivisor) + ") must be >= 1");
  }
  return solveHierarchical(steps, ramSlots, levels, forwardStep, kGradedWindow, grid.exactLengths,
                           1.0 / static_cast<double>(grid.spacingDivisor));
}

std::shared_ptr<KLevelPlan::HierarchicalTables> KLevelPlan::hierarchicalTables(
    std::int64_t steps, const std::vector<std::int64_t>& capacity, const std::vector<double>& write,
    const std::vector<double>& read, double uf, std::int64_t window, std::int64_t exactLengths,
    double spacing) {
  auto tables = std::make_shared<HierarchicalTables>();
  HierarchicalTables& t = *tables;
  t.steps = steps;
  t.capacity = capacity;
  t.write = write;
  t.read = read;
  t.uf = uf;
  t.window = window;
  t.exact = std::min(steps, exactLengths);
  t.lengths = gradedLengths(steps, exactLengths, spacing);
  for (std::int64_t c : capacity) {
    t.offset.push_back(t.columns);
    t.columns += c + 1;
  }
  const double rows = static_cast<double>(t.rows() - 1);
  const double splits = window > 0 ? std::min(rows, 2.0 * static_cast<double>(window) + 1) : rows;
  const double work = rows * splits * static_cast<double>(t.columns);
  if (work > static_cast<double>(kMaxHierarchicalWork)) {
    throw std::invalid_argument(
        "K-level plan (hierarchical): N = " + std::to_string(steps) +
        " with these slots exceeds its work limit N min(N, 2 window + 1) sum(s_k + 1) <= 2^33");
  }
  const int levelCount = static_cast<int>(capacity.size());
  const std::size_t size = static_cast<std::size_t>(t.rows() * t.columns);
  t.backward.assign(size, HierarchicalTables::Entry{HierarchicalTables::kInfinity, 0, kDone, 0});
  t.forward.assign(size, HierarchicalTables::Entry{HierarchicalTables::kInfinity, 0, 0, 0});
  for (std::int64_t row = 1; row < t.rows(); ++row) {
    pollInterrupt();
    t.forwardDone = {row, 0};
    const std::int64_t l = t.lengths[static_cast<std::size_t>(row)];
    const std::int64_t previousLength = t.lengths[static_cast<std::size_t>(row - 1)];
    for (int k = 0; k < levelCount; ++k) {
      for (std::int64_t m = 0; m <= capacity[static_cast<std::size_t>(k)]; ++m) {
        t.backwardDone = {row, t.offset[static_cast<std::size_t>(k)] + m};
        const auto [first, last] =
            t.splits(l, previousLength, t.backward[t.at(row - 1, k, m)].distance, l - 2);
        t.backward[t.at(row, k, m)] = t.backwardEntry(l, k, m, first, last);
      }
    }
    t.backwardDone = {row + 1, 0};
    for (int k = 0; k < levelCount; ++k) {
      const std::size_t kk = static_cast<std::size_t>(k);
      for (std::int64_t m = 0; m <= capacity[kk]; ++m) {
        t.forwardDone = {row, t.offset[kk] + m};
        const auto [first, last] =
            t.splits(l, previousLength, t.forward[t.at(row - 1, k, m)].distance, l - 1);
        HierarchicalTables::Entry best = t.forwardEntry(l, k, m, first, last);
        if (k >= 1) {
          const HierarchicalTables::Entry& lower = t.forward[t.at(row, k - 1, capacity[kk - 1])];
          if (lower.cost < best.cost) best = lower;
        }
        t.forward[t.at(row, k, m)] = best;
      }
    }
  }
  t.backwardDone = t.forwardDone = {t.rows(), 0};
  return tables;
}

KLevelPlan KLevelPlan::solveHierarchical(std::int64_t steps, std::int64_t ramSlots,
                                         const std::vector<StorageLevelCosts>& levels, double forwardStep,
                                         std::int64_t window, std::int64_t exactLengths, double spacing) {
  std::vector<std::int64_t> capacity;
  std::vector<double> write, read;
  checkArguments(steps, ramSlots, levels, forwardStep, capacity, write, read);
  std::shared_ptr<HierarchicalTables> tables =
      hierarchicalTables(steps, capacity, write, read, forwardStep, window, exactLengths, spacing);
  const HierarchicalTables& t = *tables;
  const int top = static_cast<int>(capacity.size()) - 1;
  const double optimum = t.forward[t.at(t.rows() - 1, top, capacity[static_cast<std::size_t>(top)])].cost;
  if (!(optimum < HierarchicalTables::kInfinity))
    throw std::invalid_argument("K-level plan (hierarchical): no schedule for N = " + std::to_string(steps));
  KLevelPlan plan;
  plan.steps_ = steps;
  plan.capacity_ = capacity;
  plan.optimum_ = optimum;
  plan.hierarchical_ = std::move(tables);
  plan.finish(forwardStep, write, read);
  return plan;
}

namespace {

// The largest cap c on every level's slots whose columns sum(min(s_k, c) + 1) are at most `columns` (at
// least 1: K levels of two columns each always fit where choose() and segmented() call it).
std::int64_t slotCap(const std::vector<std::int64_t>& capacity, std::int64_t columns) {
  const auto columnsWith = [&](std::int64_t cap) {
    std::int64_t sum = 0;
    for (std::int64_t c : capacity) sum += std::min(c, cap) + 1;
    return sum;
  };
  std::int64_t low = 1, high = std::max<std::int64_t>(1, *std::max_element(capacity.begin(), capacity.end()));
  while (low < high) {
    const std::int64_t middle = low + (high - low + 1) / 2;
    if (columnsWith(middle) <= columns)
      low = middle;
    else
      high = middle - 1;
  }
  return low;
}

}  // namespace

KLevelPlan KLevelPlan::segmented(std::int64_t steps, std::int64_t ramSlots,
                                 const std::vector<StorageLevelCosts>& levels, double forwardStep,
                                 std::int64_t maxLength) {
  std::vector<std::int64_t> capacity;
  std::vector<double> write, read;
  checkArguments(steps, ramSlots, levels, forwardStep, capacity, write, read);
  if (maxLength < 1 || maxLength > kGradedExactLengths) {
    throw std::invalid_argument("K-level plan (segmented): the longest segment (" +
                                std::to_string(maxLength) + ") must be in [1, " +
                                std::to_string(kGradedExactLengths) + "]");
  }
  const std::int64_t longest = std::min(steps, maxLength);
  const std::int64_t cap = slotCap(capacity, kMaxGradedCells / (longest + 1));
  std::vector<std::int64_t> capped = capacity;
  for (std::int64_t& c : capped) c = std::min(c, cap);
  std::shared_ptr<HierarchicalTables> tables =
      hierarchicalTables(longest, capped, write, read, forwardStep, kGradedWindow, longest, 0.0);
  const HierarchicalTables& t = *tables;
  const int top = static_cast<int>(capacity.size()) - 1;
  const std::size_t topIndex = static_cast<std::size_t>(top);
  const std::int64_t slots = capacity[topIndex], topCap = capped[topIndex];
  const double store = write[topIndex] + read[topIndex];  // a segment's first state: written, read once
  const auto reversal = [&](std::int64_t l, std::int64_t c) { return t.backward[t.at(l, top, c)].cost; };
  const auto sweep = [&](std::int64_t l, std::int64_t c) {
    return l == 0 ? 0.0 : t.forward[t.at(l, top, c)].cost;
  };
  double best = HierarchicalTables::kInfinity;
  Segments chosen;
  const auto evaluate = [&](std::int64_t count, std::int64_t tail) {
    const std::int64_t rest = steps - tail;
    const std::int64_t base = rest / count, longer = rest % count;
    if (base < 1 || base + (longer > 0 ? 1 : 0) > longest || count > slots) return;
    const std::int64_t c = std::min(topCap, slots - count);
    double cost = static_cast<double>(count) * store +
                  static_cast<double>(count - longer) * reversal(base, c) + sweep(tail, c);
    if (longer > 0) cost += static_cast<double>(longer) * reversal(base + 1, c);
    if (cost < best) {
      best = cost;
      chosen = Segments{count, base, longer, tail};
    }
  };
  for (std::int64_t tail = 0; tail <= longest && tail < steps; ++tail) {
    pollInterrupt();
    const std::int64_t rest = steps - tail;
    // Every count where the segments' free slots are fewer than the tables hold, else the ends of the
    // intervals of equal base (the cost is linear in count there).
    const std::int64_t most = std::min(rest, slots);
    const std::int64_t plain = std::min(most, slots - topCap);  // counts with c = topCap
    for (std::int64_t count = std::max<std::int64_t>(1, (rest + longest - 1) / longest); count <= plain;) {
      const std::int64_t end = std::min(plain, rest / (rest / count));
      evaluate(count, tail);
      if (end != count) evaluate(end, tail);
      count = end + 1;
    }
    for (std::int64_t count = std::max<std::int64_t>(1, plain + 1); count <= most; ++count)
      evaluate(count, tail);
  }
  if (steps <= longest) {  // the programme alone
    const double alone = sweep(steps, topCap);
    if (alone < best) {
      best = alone;
      chosen = Segments{};
    }
  }
  if (!(best < HierarchicalTables::kInfinity))
    throw std::invalid_argument("K-level plan (segmented): no schedule for N = " + std::to_string(steps) +
                                " in segments and a tail of at most " + std::to_string(longest) +
                                " steps on " + std::to_string(slots) + " slots of the slowest level");
  KLevelPlan plan;
  plan.steps_ = steps;
  plan.capacity_ = capacity;
  plan.optimum_ = best;
  plan.segments_ = chosen;
  plan.hierarchical_ = std::move(tables);
  plan.finish(forwardStep, write, read);
  return plan;
}

KLevelPlan KLevelPlan::choose(std::int64_t steps, std::int64_t ramSlots,
                              const std::vector<StorageLevelCosts>& levels, double forwardStep) {
  std::vector<std::int64_t> capacity;
  std::vector<double> write, read;
  checkArguments(steps, ramSlots, levels, forwardStep, capacity, write, read);
  const double k = static_cast<double>(capacity.size());
  double work = static_cast<double>(steps) * static_cast<double>(steps) * k * k;
  for (std::int64_t c : capacity) work *= static_cast<double>(c + 1);
  const std::int64_t exactWork = capacity.size() == 2 ? kMaxWork : kChooseExactWork;
  if (work <= static_cast<double>(exactWork)) return optimal(steps, ramSlots, levels, forwardStep);
  std::int64_t columns = 0;
  for (std::int64_t c : capacity) columns += c + 1;
  if (gradedRows(steps) * columns <= kMaxGradedCells) return graded(steps, ramSlots, levels, forwardStep);
  // Where the finest grid cannot hold every slot: the finest of the coarser grids that can (where many
  // slots are free, rows are what can be spared: docs/theory/storage.md, "Large disks", the coarse grids'
  // plans are within 0.12 % of the finest one's where both were computed), beyond the coarsest that grid
  // with each level's slots capped so that they fit (a plan with fewer slots is one of the plans with
  // more); and segmented(), which keeps every slot of the slowest level for the forward sweep's stores.
  // The cheaper walk is the plan.
  KLevelPlan grid = [&] {
    for (const GradedGrid& g : kGradedGrids) {
      if (gradedRows(steps, g) * columns <= kMaxGradedCells)
        return graded(steps, ramSlots, levels, forwardStep, g);
    }
    const GradedGrid coarsest = kGradedGrids[std::size(kGradedGrids) - 1];
    const std::int64_t cap = slotCap(capacity, kMaxGradedCells / gradedRows(steps, coarsest));
    std::vector<StorageLevelCosts> capped = levels;
    for (StorageLevelCosts& level : capped) level.slots = std::min(level.slots, cap);
    return graded(steps, std::min(ramSlots, cap), capped, forwardStep, coarsest);
  }();
  // segmented() covers N with at most D segments and a tail, each at most kGradedExactLengths states long,
  // D the slowest level's slots below RAM: with fewer it has no schedule (many RAM slots, a small disk).
  const double reach = (static_cast<double>(capacity.back()) + 1) * static_cast<double>(kGradedExactLengths);
  if (capacity.size() < 2 || reach < static_cast<double>(steps)) return grid;
  KLevelPlan segments = segmented(steps, ramSlots, levels, forwardStep);
  return segments.counts().cost < grid.counts().cost ? segments : grid;
}

std::int64_t KLevelPlan::gradedRows(std::int64_t steps, GradedGrid grid) {
  return static_cast<std::int64_t>(
      gradedLengths(steps, grid.exactLengths, 1.0 / static_cast<double>(grid.spacingDivisor)).size());
}

bool KLevelPlan::onGrid() const { return hierarchical_ && hierarchical_->exact < steps_; }

std::int64_t KLevelPlan::exactLengths() const { return hierarchical_ ? hierarchical_->exact : steps_; }

std::string KLevelPlan::describe() const {
  std::string slots;
  for (std::size_t k = 1; k < peak_.size(); ++k) slots += (k > 1 ? ", " : "") + std::to_string(peak_[k]);
  const std::string used = ": up to " + std::to_string(peak_.empty() ? 0 : peak_[0]) + " RAM states and " +
                           slots + " on the levels below, slots reused";
  if (tables_)
    return "optimal " + std::to_string(levelCount()) + "-level stack schedule (dynamic programme)" + used;
  const Segments& s = segments_;
  if (s.count > 0) {
    return "segmented " + std::to_string(levelCount()) + "-level stack schedule (" + std::to_string(s.count) +
           " forward stores on the slowest level, " + std::to_string(s.base) +
           (s.longer > 0 ? "-" + std::to_string(s.base + 1) : std::string()) + " steps apart, then " +
           std::to_string(s.tail) + " steps; each segment reversed by H-Revolve's structure with moves)" +
           used;
  }
  const bool grid = onGrid();
  return "hierarchical " + std::to_string(levelCount()) +
         "-level stack schedule (H-Revolve's structure with moves" +
         (grid ? ", lengths beyond " + std::to_string(hierarchical_->exact) + " on a geometric grid"
               : std::string()) +
         ")" + used;
}

std::int64_t KLevelPlan::column(int level, std::int64_t free) const {
  return std::min(free, hierarchical_->capacity[static_cast<std::size_t>(level)]);
}

KLevelPlan::Decision KLevelPlan::forwardDecision(std::int64_t length) const {
  const Segments& s = segments_;
  if (s.count > 0 && length > s.tail) {
    // segmented()'s stores at the slowest level, the longer segments first; the tail is the tables'.
    const std::int64_t n = steps_ - length, longPart = s.longer * (s.base + 1);
    const std::int64_t segment = n < longPart ? n / (s.base + 1) : s.longer + (n - longPart) / s.base;
    const std::int64_t distance =
        segment == s.count - 1 && s.tail == 0 ? 0 : (segment < s.longer ? s.base + 1 : s.base);
    return Decision{levelCount() - 1, levelCount() - 1, distance};
  }
  if (hierarchical_) {
    // The forward sweep stores on the level of its last store or a faster one (K - 1 at first).
    const HierarchicalTables& t = *hierarchical_;
    const int level = held_.empty() ? levelCount() - 1 : held_.back().level;
    const std::int64_t row = t.rowOf(length);
    if (t.lengths[static_cast<std::size_t>(row)] == length) {
      const auto& e = t.forward[t.at(row, level, column(level, free_[static_cast<std::size_t>(level)]))];
      return Decision{e.level, e.level, e.distance};
    }
    // Between the rows of a graded grid: the recurrence evaluated for this length, the splits searched as
    // for a row (around the row below's best split scaled to this length).
    const std::int64_t below = t.lengths[static_cast<std::size_t>(row)];
    HierarchicalTables::Entry best{HierarchicalTables::kInfinity, 0, 0, 0};
    for (int k = level; k >= 0; --k) {
      const std::int64_t m = column(
          k, k == level ? free_[static_cast<std::size_t>(level)] : capacity_[static_cast<std::size_t>(k)]);
      const auto [first, last] = t.splits(length, below, t.forward[t.at(row, k, m)].distance, length - 1);
      const HierarchicalTables::Entry e = t.forwardEntry(length, k, m, first, last);
      if (e.cost < best.cost) best = e;
    }
    return Decision{best.level, best.level, best.distance};
  }
  std::int64_t cell = 0;
  for (int k = 0; k < levelCount(); ++k) cell += free_[static_cast<std::size_t>(k)] * tables_->stride[k];
  const Tables::Entry& e = tables_->forward[tables_->at(length, cell)];
  return Decision{e.action, e.action, e.distance};
}

KLevelPlan::Decision KLevelPlan::backwardDecision(int level, std::int64_t length) const {
  if (hierarchical_) {
    const HierarchicalTables& t = *hierarchical_;
    const std::int64_t m = column(level, free_[static_cast<std::size_t>(level)]);
    const std::int64_t row = t.rowOf(length);
    if (t.lengths[static_cast<std::size_t>(row)] == length) {
      const auto& e = t.backward[t.at(row, level, m)];
      return Decision{e.action, e.level, e.distance};
    }
    const auto [first, last] = t.splits(length, t.lengths[static_cast<std::size_t>(row)],
                                        t.backward[t.at(row, level, m)].distance, length - 2);
    const HierarchicalTables::Entry e = t.backwardEntry(length, level, m, first, last);
    return Decision{e.action, e.level, e.distance};
  }
  std::int64_t cell = 0;
  for (int k = 0; k < levelCount(); ++k) cell += free_[static_cast<std::size_t>(k)] * tables_->stride[k];
  const Tables::Entry& e = tables_->backward[tables_->at(length, level, cell)];
  return Decision{e.action, e.level, e.distance};
}

std::int64_t KLevelPlan::takeSlot(int level) {
  // The lowest free slot, so that the slots in use at the most are 0..peak-1: the least released one (a
  // min-heap; every released slot is below the first never used), else the first never used. O(log D)
  // where a scan was O(D) (segmented() holds up to D slots of a level at once).
  const std::size_t k = static_cast<std::size_t>(level);
  std::vector<std::int64_t>& released = released_[k];
  std::int64_t slot = unused_[k];
  if (!released.empty()) {
    std::pop_heap(released.begin(), released.end(), std::greater<>());
    slot = released.back();
    released.pop_back();
  } else {
    ++unused_[k];
  }
  --free_[k];
  peak_[k] = std::max(peak_[k], slot + 1);
  return slot;
}

void KLevelPlan::releaseSlot(const Held& held) {
  const std::size_t k = static_cast<std::size_t>(held.level);
  released_[k].push_back(held.slot);  // within the capacity reserved by rewind(): no allocation
  std::push_heap(released_[k].begin(), released_[k].end(), std::greater<>());
  ++free_[k];
}

void KLevelPlan::rewind() {
  const std::size_t levels = capacity_.size();
  held_.clear();
  released_.resize(levels);
  for (std::size_t k = 0; k < levels; ++k) {
    released_[k].clear();
    released_[k].reserve(static_cast<std::size_t>(capacity_[k]));
  }
  unused_.assign(levels, 0);
  free_ = capacity_;
  nextStore_ = 0;
}

KLevelPlan::Counts KLevelPlan::walk() {
  struct Counter {
    Counts& c;
    bool forward = true;
    void store(int level, std::int64_t) {
      ++c.writes[static_cast<std::size_t>(level)];
      if (forward) ++c.forwardStores;
    }
    void load(int level, std::int64_t) { ++c.reads[static_cast<std::size_t>(level)]; }
    void advance(std::int64_t from, std::int64_t to) { c.recomputedSteps += to - from; }
  };
  Counts c;
  c.writes.assign(capacity_.size(), 0);
  c.reads.assign(capacity_.size(), 0);
  peak_.assign(capacity_.size(), 0);
  Counter counter{c, true};
  rewind();
  for (std::int64_t n = 0; n < steps_; ++n) {
    if ((n & 0xffff) == 0) pollInterrupt();
    recordForward(n, counter);
  }
  counter.forward = false;
  for (std::int64_t e = steps_ - 1; e >= 0; --e) {
    if ((e & 0xffff) == 0) pollInterrupt();
    restoreStep(e, counter);
  }
  rewind();
  return c;
}

// ---- a lower bound on the hierarchical family's optimum for any N ----
//
// docs/theory/storage.md, "A certificate for large N". Two facts carry it:
// (1) E_k(l + d, m) >= E_k(l, m) + d uf for d >= 0: a schedule for l + d states, with the positions 1..d
//     merged into position 0, is one for l states (an advance from position 0 saves d steps; a store at
//     position 0 is dropped where it is at level k and is a move to a faster level elsewhere, both in the
//     family); the same holds for W. So a value at a grid length bounds every length up to the next one.
// (2) Unrolled, E_k(l, m) is a sum over parts: each store at distance j leaves a part of j states that is
//     reversed later (j uf + r_k + w_next + E_k(j, m)) and the chain goes on from the stored state with
//     one slot less at k, or at a faster level i with its s_i - 1 slots; it ends in a terminal (the
//     advance, a move, or one state). The parts sum to l. Dualising that sum with a multiplier lambda
//     (weak duality) gives, for every lambda, E_k(l, m) >= lambda l + V(k, m) with V a shortest path over
//     the states (level, free slots), each edge the least (part - lambda j) over every part length -- no
//     length dimension, so no rounding accumulates along the chain: each part's value is rounded to its
//     grid length once.
namespace {

// The lower convex hull of points appended with increasing x; min over the points of y - lambda x. Written
// here (Andrew's monotone chain, append-only, and a binary search): the packages we use (Eigen, CGAL is not
// one) have no incremental hull with this query.
class LowerHull {
 public:
  void add(double x, double y) {
    if (!(y < std::numeric_limits<double>::infinity())) return;
    while (!points_.empty() && points_.back().first == x) {
      if (points_.back().second <= y) return;
      points_.pop_back();
    }
    while (points_.size() >= 2) {
      const auto& [x1, y1] = points_[points_.size() - 2];
      const auto& [x2, y2] = points_.back();
      // Drop the middle point unless it lies strictly below the chord from (x1, y1) to (x, y).
      if ((y2 - y1) * (x - x1) < (y - y1) * (x2 - x1)) break;
      points_.pop_back();
    }
    points_.emplace_back(x, y);
  }
  double minimum(double lambda) const {
    if (points_.empty()) return std::numeric_limits<double>::infinity();
    // y - lambda x is convex along the hull: the first point whose successor is not lower.
    std::size_t low = 0, high = points_.size() - 1;
    while (low < high) {
      const std::size_t middle = (low + high) / 2;
      const double here = points_[middle].second - lambda * points_[middle].first;
      const double next = points_[middle + 1].second - lambda * points_[middle + 1].first;
      if (next < here)
        low = middle + 1;
      else
        high = middle;
    }
    return points_[low].second - lambda * points_[low].first;
  }

 private:
  std::vector<std::pair<double, double>> points_;
};

}  // namespace

KLevelPlan::GradedGrid KLevelPlan::boundGrid(std::int64_t steps, std::int64_t columns) {
  const auto cells = [&](GradedGrid g) {
    return static_cast<double>(gradedRows(steps, g)) * static_cast<double>(columns);
  };
  // Finer than {1024, 1024} where it is cheap (few slots), else {1024, 1024} or coarser where it fits.
  std::size_t i = 0;
  for (; kBoundGrids[i].spacingDivisor > 1024; ++i) {
    const GradedGrid& g = kBoundGrids[i];
    const double exact = static_cast<double>(std::min(steps, g.exactLengths));
    if (cells(g) <= static_cast<double>(kBoundGridCells) &&
        exact * exact * static_cast<double>(columns) <= static_cast<double>(std::int64_t{1} << 28))
      return g;
  }
  for (; i < std::size(kBoundGrids); ++i) {
    if (cells(kBoundGrids[i]) <= static_cast<double>(kMaxBoundCells)) return kBoundGrids[i];
  }
  return kBoundGrids[std::size(kBoundGrids) - 1];  // lowerBound() names what does not fit
}

KLevelPlan::LowerBound KLevelPlan::lowerBound(std::int64_t steps, std::int64_t ramSlots,
                                              const std::vector<StorageLevelCosts>& levels,
                                              double forwardStep) {
  std::vector<std::int64_t> capacity;
  std::vector<double> write, read;
  checkArguments(steps, ramSlots, levels, forwardStep, capacity, write, read);
  std::int64_t columns = 0;
  for (std::int64_t c : capacity) columns += c + 1;
  return lowerBound(steps, ramSlots, levels, forwardStep, boundGrid(steps, columns));
}

KLevelPlan::LowerBound KLevelPlan::lowerBound(std::int64_t steps, std::int64_t ramSlots,
                                              const std::vector<StorageLevelCosts>& levels,
                                              double forwardStep, GradedGrid grid) {
  if (grid.exactLengths < 1 || grid.spacingDivisor < 1) {
    throw std::invalid_argument("K-level lower bound: the grid's exact lengths (" +
                                std::to_string(grid.exactLengths) + ") and spacing divisor (" +
                                std::to_string(grid.spacingDivisor) + ") must be >= 1");
  }
  std::vector<std::int64_t> capacity;
  std::vector<double> write, read;
  checkArguments(steps, ramSlots, levels, forwardStep, capacity, write, read);
  const double uf = forwardStep;
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const int levelCount = static_cast<int>(capacity.size());
  std::vector<std::int64_t> offset;
  std::int64_t columns = 0;
  for (std::int64_t c : capacity) {
    offset.push_back(columns);
    columns += c + 1;
  }
  const std::vector<std::int64_t> lengths =
      gradedLengths(steps, grid.exactLengths, 1.0 / static_cast<double>(grid.spacingDivisor));
  const auto rows = static_cast<std::int64_t>(lengths.size());
  if (static_cast<double>(rows) * static_cast<double>(columns) > static_cast<double>(kMaxBoundCells)) {
    throw std::invalid_argument("K-level lower bound: N = " + std::to_string(steps) + " with " +
                                std::to_string(columns) + " slot counts needs " + std::to_string(rows) +
                                " rows of them, more than " + std::to_string(kMaxBoundCells) + " entries");
  }
  // The exact lengths: hierarchical()'s full split search.
  const std::int64_t exact = std::min(steps, grid.exactLengths);
  std::shared_ptr<HierarchicalTables> tables =
      hierarchicalTables(exact, capacity, write, read, uf, 0, exact, 0.0);
  const HierarchicalTables& t = *tables;
  LowerBound result;
  result.exactLengths = exact;
  result.rows = rows;
  const auto column = [&](int k, std::int64_t m) {
    return static_cast<std::size_t>(offset[static_cast<std::size_t>(k)] + m);
  };
  if (steps == exact) {
    result.bound = t.forward[t.at(exact, levelCount - 1, capacity.back())].cost;
    return result;
  }
  const std::size_t cols = static_cast<std::size_t>(columns);
  std::vector<double> bound(lengths.size() * cols, kInfinity);  // [row][column]: E's lower bounds
  for (std::int64_t row = 1; row <= exact; ++row) {
    for (int k = 0; k < levelCount; ++k) {
      for (std::int64_t m = 0; m <= capacity[static_cast<std::size_t>(k)]; ++m)
        bound[static_cast<std::size_t>(row) * cols + column(k, m)] = t.backward[t.at(row, k, m)].cost;
    }
  }
  tables.reset();
  // The multipliers: geometric from uf/2 (a part's marginal cost is at least uf) to where no segment's is.
  double dearest = uf;
  for (int k = 1; k < levelCount; ++k)
    dearest = std::max(dearest, write[static_cast<std::size_t>(k)] + read[static_cast<std::size_t>(k)]);
  std::vector<double> multipliers;
  for (double lambda = 0.5 * uf; lambda <= 64.0 * (uf + dearest); lambda *= kBoundMultiplierRatio)
    multipliers.push_back(lambda);
  // E_0(l, m): revolve's least number of forward steps T(l, m + 1) (docs/theory/storage.md: RAM alone is
  // revolve), whose increments are the repetition number, nondecreasing in l.
  const std::size_t ramColumns = static_cast<std::size_t>(capacity[0] + 1);
  const auto revolveSteps = [uf](std::int64_t l, std::int64_t m) {
    return static_cast<double>(revolve::optimalForwardSteps(l, m + 1)) * uf;
  };
  // Per column, the hull of (j, j uf + E_k(j, m)) and of (j, E_k(j, m)) over the lengths of finished rows;
  // a row's value bounds its interval [g, g' - 1] with slope uf (fact (1)), so each row adds both ends.
  std::vector<LowerHull> parts(cols), values(cols);
  const auto addRow = [&](std::size_t row) {
    const double g = static_cast<double>(lengths[row]);
    const double end = static_cast<double>(row + 1 < lengths.size() ? lengths[row + 1] - 1 : lengths[row]);
    for (std::size_t c = 0; c < cols; ++c) {
      const double y = bound[row * cols + c];
      // RAM is revolve, convex in the length: its increment at g bounds every later one.
      const double slope =
          c < ramColumns ? revolveSteps(lengths[row] + 1, static_cast<std::int64_t>(c)) - y : uf;
      parts[c].add(g, g * uf + y);
      values[c].add(g, y);
      if (end > g) {
        parts[c].add(end, end * uf + y + (end - g) * slope);
        values[c].add(end, y + (end - g) * slope);
      }
    }
  };
  for (std::size_t row = 1; row <= static_cast<std::size_t>(exact); ++row) addRow(row);
  std::vector<double> path(cols), best(cols);
  for (std::size_t row = static_cast<std::size_t>(exact) + 1; row < lengths.size(); ++row) {
    pollInterrupt();
    const double l = static_cast<double>(lengths[row]);
    std::fill(best.begin(), best.end(), -kInfinity);
    for (const double lambda : multipliers) {
      for (int k = 0; k < levelCount; ++k) {
        const std::size_t kk = static_cast<std::size_t>(k);
        // The faster levels a store or a move can go to, with their full slots less one.
        double below = kInfinity, moveBelow = kInfinity;
        for (int i = 0; i < k; ++i) {
          const std::size_t ii = static_cast<std::size_t>(i);
          if (capacity[ii] < 1) continue;
          const std::size_t c = column(i, capacity[ii] - 1);
          below = std::min(below, write[ii] + path[c]);
          moveBelow = std::min(moveBelow, write[ii] + values[c].minimum(lambda));
        }
        for (std::int64_t m = 0; m <= capacity[kk]; ++m) {
          const std::size_t c = column(k, m);
          const double part = parts[c].minimum(lambda) + read[kk];  // min_j j uf + r_k + E_k(j, m) - lambda j
          // Terminals: one state (0 - lambda), the advance (L = j + 1: part - lambda), a move (L <= l - 1;
          // a move of the whole segment is taken below, exactly).
          double v = std::min({-lambda, part - lambda, moveBelow});
          double next = below;
          if (m >= 1) next = std::min(next, write[kk] + path[c - 1]);
          v = std::min(v, part + next);
          path[c] = v;
          best[c] = std::max(best[c], lambda * l + v);
        }
      }
    }
    const double previous = static_cast<double>(lengths[row - 1]);
    for (int k = 0; k < levelCount; ++k) {
      const std::size_t kk = static_cast<std::size_t>(k);
      double move = kInfinity;  // the whole segment moved to a faster level: exact on this row
      for (int i = 0; i < k; ++i) {
        const std::size_t ii = static_cast<std::size_t>(i);
        if (capacity[ii] >= 1)
          move = std::min(move, write[ii] + bound[row * cols + column(i, capacity[ii] - 1)]);
      }
      for (std::int64_t m = 0; m <= capacity[kk]; ++m) {
        const std::size_t c = column(k, m);
        double value = std::min(best[c], move);
        // Fact (1) from the previous row.
        value = std::max(value, bound[(row - 1) * cols + c] + (l - previous) * uf);
        // RAM alone is revolve (no faster level to move to): its count, exactly.
        if (k == 0) value = revolveSteps(lengths[row], m);
        bound[row * cols + c] = value;
      }
    }
    addRow(row);
  }
  // The forward sweep, W: parts w_k + r_k + E_k(j, m - 1) on the chain (k, m) -> (k, m - 1), a
  // terminal of the same form, and the switch to the faster level k - 1 with its full slots.
  const double n = static_cast<double>(steps);
  std::vector<double> w(cols);
  const auto forwardAt = [&](double lambda) {
    for (int k = 0; k < levelCount; ++k) {
      const std::size_t kk = static_cast<std::size_t>(k);
      for (std::int64_t m = 0; m <= capacity[kk]; ++m) {
        const std::size_t c = column(k, m);
        double v = k >= 1 ? w[column(k - 1, capacity[kk - 1])] : kInfinity;
        if (m >= 1) {
          const double part = write[kk] + read[kk] + values[c - 1].minimum(lambda);
          v = std::min(v, part + std::min(0.0, w[c - 1]));
        }
        w[c] = v;
      }
    }
    return lambda * n + w[column(levelCount - 1, capacity.back())];
  };
  // The bound at N is a concave function of lambda (a minimum of affine ones): the best multiplier of the
  // geometric set, then a golden-section search between its neighbours (cheap: one path per evaluation).
  std::size_t top = 0;
  double forward = -kInfinity;
  for (std::size_t i = 0; i < multipliers.size(); ++i) {
    const double value = forwardAt(multipliers[i]);
    if (value > forward) {
      forward = value;
      top = i;
    }
  }
  double low = multipliers[top > 0 ? top - 1 : 0];
  double high = multipliers[std::min(top + 1, multipliers.size() - 1)];
  constexpr double kGolden = 0.6180339887498949;
  double a = high - kGolden * (high - low), b = low + kGolden * (high - low);
  double fa = forwardAt(a), fb = forwardAt(b);
  for (int iteration = 0; iteration < 60; ++iteration) {
    if (fa < fb) {
      low = a;
      a = b;
      fa = fb;
      b = low + kGolden * (high - low);
      fb = forwardAt(b);
    } else {
      high = b;
      b = a;
      fb = fa;
      a = high - kGolden * (high - low);
      fa = forwardAt(a);
    }
  }
  forward = std::max({forward, fa, fb});
  // Less a margin far above the rounding of these sums (their terms are exact or a few ulps off), so that
  // the bound stays below an optimum it equals.
  result.bound = std::max(0.0, forward - 1e-9 * std::abs(forward));
  return result;
}

}  // namespace hindsight
