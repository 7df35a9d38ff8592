#include <hindsight/storage/k_level_plan.h>

#include <hindsight/engine/interrupt.h>

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace hindsight {

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
  std::vector<Entry> backward, plain, forward;  // backward/plain: [l][L][cell], forward: [l][cell]
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
  t.plain.assign(size, Tables::Entry{kInfinity, 0, kDone, 0});
  t.forward.assign(static_cast<std::size_t>((steps + 1) * t.cells), Tables::Entry{kInfinity, 0, 0, 0});
  const double uf = forwardStep;
  const auto loaded = [&](int level, std::int64_t l, std::int64_t cell) {  // F_L
    return read[level] + t.backward[t.at(l, level, cell)].cost;
  };
  for (std::int64_t l = 1; l <= steps; ++l) {
    pollInterrupt();
    for (std::int64_t cell = 0; cell < t.cells; ++cell) {
      for (int level = 0; level < t.levels; ++level) {
        Tables::Entry best{l == 1 ? 0.0 : kInfinity, 0, static_cast<std::int8_t>(l == 1 ? kDone : kNone), 0};
        if (l >= 2) {
          best.cost = static_cast<double>(l - 1) * uf + loaded(level, l - 1, cell);
          for (std::int64_t j = 1; j <= l - 2; ++j) {
            const double lower = static_cast<double>(j) * uf + loaded(level, j, cell);
            for (int k = 0; k < t.levels; ++k) {
              if (t.freeAt(cell, k) < 1) continue;
              const double cost = lower + write[k] + t.backward[t.at(l - j, k, cell - t.stride[k])].cost;
              if (cost < best.cost)
                best = {cost, static_cast<std::int32_t>(j), kStore, static_cast<std::int8_t>(k)};
            }
          }
        }
        t.plain[t.at(l, level, cell)] = best;
      }
    }
    for (std::int64_t cell = 0; cell < t.cells; ++cell) {
      for (int level = 0; level < t.levels; ++level) {
        Tables::Entry best = t.plain[t.at(l, level, cell)];
        if (l >= 2 && t.freeAt(cell, level) < t.capacity[level]) {
          for (int k = 0; k < t.levels; ++k) {
            if (k == level || t.freeAt(cell, k) < 1) continue;
            const std::int64_t moved = cell - t.stride[k] + t.stride[level];
            const double cost = write[k] + t.plain[t.at(l, k, moved)].cost;
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

struct KLevelPlan::HierarchicalTables {
  std::int64_t steps = 0;
  std::vector<std::int64_t> capacity, offset;  // offset[k]: first column of level k; columns m = 0..s_k
  std::int64_t columns = 0;
  struct Entry {
    double cost;
    std::int32_t distance;
    std::int8_t action;  // E: kDone, kNone, kStore; W: unused
    std::int8_t level;   // the level stored at
  };
  std::vector<Entry> backward, forward;  // [l][column]
  std::size_t at(std::int64_t l, int level, std::int64_t m) const {
    return static_cast<std::size_t>(l * columns + offset[static_cast<std::size_t>(level)] + m);
  }
};

KLevelPlan KLevelPlan::hierarchical(std::int64_t steps, std::int64_t ramSlots,
                                    const std::vector<StorageLevelCosts>& levels, double forwardStep,
                                    std::int64_t window) {
  std::vector<std::int64_t> capacity;
  std::vector<double> write, read;
  checkArguments(steps, ramSlots, levels, forwardStep, capacity, write, read);
  auto tables = std::make_shared<HierarchicalTables>();
  HierarchicalTables& t = *tables;
  t.steps = steps;
  t.capacity = capacity;
  for (std::int64_t c : capacity) {
    t.offset.push_back(t.columns);
    t.columns += c + 1;
  }
  const double splits = window > 0
                            ? std::min(static_cast<double>(steps), 2.0 * static_cast<double>(window) + 1)
                            : static_cast<double>(steps);
  const double work = static_cast<double>(steps) * splits * static_cast<double>(t.columns);
  if (work > static_cast<double>(kMaxHierarchicalWork)) {
    throw std::invalid_argument(
        "K-level plan (hierarchical): N = " + std::to_string(steps) +
        " with these slots exceeds its work limit N min(N, 2 window + 1) sum(s_k + 1) <= 2^33");
  }
  const int levelCount = static_cast<int>(capacity.size());
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const std::size_t size = static_cast<std::size_t>((steps + 1) * t.columns);
  t.backward.assign(size, HierarchicalTables::Entry{kInfinity, 0, kDone, 0});
  t.forward.assign(size, HierarchicalTables::Entry{kInfinity, 0, 0, 0});
  const double uf = forwardStep;
  // The splits searched for length l: all of 1..top, or a window around the best split of length l - 1.
  const auto range = [window](std::int64_t previous, std::int64_t top) {
    if (window <= 0 || previous <= 0) return std::pair<std::int64_t, std::int64_t>{1, top};
    return std::pair<std::int64_t, std::int64_t>{std::max<std::int64_t>(1, previous - window),
                                                 std::min(top, previous + window)};
  };
  // below[k][l]: the cheapest store of a state that starts a segment of l states at a level under k,
  // min_{i<k} w_i + E_i(l, s_i - 1), and that level.
  std::vector<std::vector<std::pair<double, int>>> below(
      static_cast<std::size_t>(levelCount),
      std::vector<std::pair<double, int>>(static_cast<std::size_t>(steps + 1), {kInfinity, -1}));
  for (std::int64_t l = 1; l <= steps; ++l) {
    pollInterrupt();
    for (int k = 0; k < levelCount; ++k) {
      const auto& lower = below[static_cast<std::size_t>(k)];
      for (std::int64_t m = 0; m <= capacity[static_cast<std::size_t>(k)]; ++m) {
        HierarchicalTables::Entry best{l == 1 ? 0.0 : kInfinity, 0,
                                       static_cast<std::int8_t>(l == 1 ? kDone : kNone), 0};
        if (l >= 2) {
          best.cost = static_cast<double>(l - 1) * uf + read[static_cast<std::size_t>(k)] +
                      t.backward[t.at(l - 1, k, m)].cost;
          const auto [first, last] = range(t.backward[t.at(l - 1, k, m)].distance, l - 2);
          for (std::int64_t j = first; j <= last; ++j) {
            const double left = static_cast<double>(j) * uf + read[static_cast<std::size_t>(k)] +
                                t.backward[t.at(j, k, m)].cost;
            if (m >= 1) {
              const double cost =
                  left + write[static_cast<std::size_t>(k)] + t.backward[t.at(l - j, k, m - 1)].cost;
              if (cost < best.cost)
                best = {cost, static_cast<std::int32_t>(j), kStore, static_cast<std::int8_t>(k)};
            }
            const auto& [store, level] = lower[static_cast<std::size_t>(l - j)];
            if (level >= 0 && left + store < best.cost)
              best = {left + store, static_cast<std::int32_t>(j), kStore, static_cast<std::int8_t>(level)};
          }
          // Move x_p to a faster level and reverse the whole segment from there (one read instead of many).
          const auto& [store, level] = lower[static_cast<std::size_t>(l)];
          if (level >= 0 && store < best.cost) best = {store, 0, kMove, static_cast<std::int8_t>(level)};
        }
        t.backward[t.at(l, k, m)] = best;
      }
      if (k + 1 < levelCount) {  // the stores below level k + 1 for segments of l states
        const std::int64_t c = capacity[static_cast<std::size_t>(k)];
        auto entry = below[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)];
        if (c >= 1) {
          const double cost = write[static_cast<std::size_t>(k)] + t.backward[t.at(l, k, c - 1)].cost;
          if (cost < entry.first) entry = {cost, k};
        }
        below[static_cast<std::size_t>(k) + 1][static_cast<std::size_t>(l)] = entry;
      }
    }
    for (int k = 0; k < levelCount; ++k) {
      const std::size_t kk = static_cast<std::size_t>(k);
      for (std::int64_t m = 0; m <= capacity[kk]; ++m) {
        HierarchicalTables::Entry best{kInfinity, 0, 0, 0};
        if (m >= 1) {
          best = {write[kk] + read[kk] + t.backward[t.at(l, k, m - 1)].cost, 0, 0,
                  static_cast<std::int8_t>(k)};
          const auto [first, last] = range(t.forward[t.at(l - 1, k, m)].distance, l - 1);
          for (std::int64_t j = first; j <= last; ++j) {
            const double cost = write[kk] + t.forward[t.at(l - j, k, m - 1)].cost + read[kk] +
                                t.backward[t.at(j, k, m - 1)].cost;
            if (cost < best.cost) best = {cost, static_cast<std::int32_t>(j), 0, static_cast<std::int8_t>(k)};
          }
        }
        if (k >= 1) {
          const HierarchicalTables::Entry& lower = t.forward[t.at(l, k - 1, capacity[kk - 1])];
          if (lower.cost < best.cost) best = lower;
        }
        t.forward[t.at(l, k, m)] = best;
      }
    }
  }
  const int top = levelCount - 1;
  const double optimum = t.forward[t.at(steps, top, capacity[static_cast<std::size_t>(top)])].cost;
  if (!(optimum < kInfinity))
    throw std::invalid_argument("K-level plan (hierarchical): no schedule for N = " + std::to_string(steps));
  KLevelPlan plan;
  plan.steps_ = steps;
  plan.capacity_ = capacity;
  plan.optimum_ = optimum;
  plan.hierarchical_ = std::move(tables);
  plan.finish(uf, write, read);
  return plan;
}

KLevelPlan::Decision KLevelPlan::forwardDecision(std::int64_t length) const {
  if (hierarchical_) {
    // The forward sweep stores on the level of its last store or a faster one (K - 1 at first).
    const int level = held_.empty() ? levelCount() - 1 : held_.back().level;
    const auto& e =
        hierarchical_->forward[hierarchical_->at(length, level, free_[static_cast<std::size_t>(level)])];
    return Decision{e.level, e.level, e.distance};
  }
  std::int64_t cell = 0;
  for (int k = 0; k < levelCount(); ++k) cell += free_[static_cast<std::size_t>(k)] * tables_->stride[k];
  const Tables::Entry& e = tables_->forward[tables_->at(length, cell)];
  return Decision{e.action, e.action, e.distance};
}

KLevelPlan::Decision KLevelPlan::backwardDecision(int level, std::int64_t length, bool moved) const {
  if (hierarchical_) {
    const auto& e =
        hierarchical_->backward[hierarchical_->at(length, level, free_[static_cast<std::size_t>(level)])];
    return Decision{e.action, e.level, e.distance};
  }
  std::int64_t cell = 0;
  for (int k = 0; k < levelCount(); ++k) cell += free_[static_cast<std::size_t>(k)] * tables_->stride[k];
  const Tables::Entry& e = (moved ? tables_->plain : tables_->backward)[tables_->at(length, level, cell)];
  return Decision{e.action, e.level, e.distance};
}

std::int64_t KLevelPlan::takeSlot(int level) {
  // The lowest free slot, so that the slots in use at the most are 0..peak-1.
  std::vector<char>& busy = busy_[static_cast<std::size_t>(level)];
  std::size_t slot = 0;
  while (busy[slot]) ++slot;
  busy[slot] = 1;
  --free_[static_cast<std::size_t>(level)];
  std::int64_t& peak = peak_[static_cast<std::size_t>(level)];
  peak = std::max(peak, static_cast<std::int64_t>(slot) + 1);
  return static_cast<std::int64_t>(slot);
}

void KLevelPlan::releaseSlot(const Held& held) {
  busy_[static_cast<std::size_t>(held.level)][static_cast<std::size_t>(held.slot)] = 0;
  ++free_[static_cast<std::size_t>(held.level)];
}

void KLevelPlan::rewind() {
  const std::size_t levels = capacity_.size();
  held_.clear();
  busy_.assign(levels, {});
  for (std::size_t k = 0; k < levels; ++k) busy_[k].assign(static_cast<std::size_t>(capacity_[k]), 0);
  free_ = capacity_;
  nextStore_ = 0;
}

KLevelPlan::Counts KLevelPlan::walk() {
  struct Counter {
    Counts& c;
    void store(int level, std::int64_t) { ++c.writes[static_cast<std::size_t>(level)]; }
    void load(int level, std::int64_t) { ++c.reads[static_cast<std::size_t>(level)]; }
    void advance(std::int64_t from, std::int64_t to) { c.recomputedSteps += to - from; }
  };
  Counts c;
  c.writes.assign(capacity_.size(), 0);
  c.reads.assign(capacity_.size(), 0);
  peak_.assign(capacity_.size(), 0);
  Counter counter{c};
  rewind();
  for (std::int64_t n = 0; n < steps_; ++n) {
    if ((n & 0xffff) == 0) pollInterrupt();
    recordForward(n, counter);
  }
  for (std::int64_t e = steps_ - 1; e >= 0; --e) {
    if ((e & 0xffff) == 0) pollInterrupt();
    restoreStep(e, counter);
  }
  rewind();
  return c;
}

}  // namespace hindsight
