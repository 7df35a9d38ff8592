#include <hindsight/storage/schedule.h>

#include <hindsight/engine/interrupt.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/storage/storage_factory.h>

#include <algorithm>
#include <limits>
#include <optional>
#include <stdexcept>

namespace hindsight {

// ---- parsing ----

std::int64_t parseScheduleInteger(const std::string& text, const std::string& field, std::int64_t minimum,
                                  std::int64_t maximum) {
  const std::string message = field + " = '" + text + "' must be an integer in [" + std::to_string(minimum) +
                              ", " + std::to_string(maximum) +
                              "] (digits, or exact scientific notation as 1e9)";
  // mantissa digits [. digits] [e|E [+] digits], read exactly in 128 bits (no double rounding: 9.5e15
  // is 9500000000000000, 1e17 is not 1).
  __extension__ typedef __int128 Wide;
  const Wide limit = static_cast<Wide>(1) << 100;
  std::size_t i = 0;
  Wide mantissa = 0;
  int digits = 0, fraction = 0;
  const auto digit = [&](char c) { return c >= '0' && c <= '9'; };
  while (i < text.size() && digit(text[i])) {
    if (mantissa >= limit) throw std::invalid_argument(message);
    mantissa = mantissa * 10 + (text[i] - '0');
    ++digits;
    ++i;
  }
  if (i < text.size() && text[i] == '.') {
    ++i;
    while (i < text.size() && digit(text[i])) {
      if (mantissa >= limit) throw std::invalid_argument(message);
      mantissa = mantissa * 10 + (text[i] - '0');
      ++digits;
      ++fraction;
      ++i;
    }
  }
  if (digits == 0) throw std::invalid_argument(message);
  long exponent = 0;
  if (i < text.size() && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < text.size() && text[i] == '+') ++i;
    const std::size_t first = i;
    while (i < text.size() && digit(text[i])) {
      exponent = exponent * 10 + (text[i] - '0');
      if (exponent > 40) throw std::invalid_argument(message);
      ++i;
    }
    if (i == first) throw std::invalid_argument(message);
  }
  if (i != text.size()) throw std::invalid_argument(message);
  long shift = exponent - fraction;
  for (; shift < 0; ++shift) {
    if (mantissa % 10 != 0) throw std::invalid_argument(message);  // not an integer
    mantissa /= 10;
  }
  for (; shift > 0; --shift) {
    if (mantissa > static_cast<Wide>(maximum)) break;
    mantissa *= 10;
  }
  if (shift > 0 && mantissa != 0) throw std::invalid_argument(message);
  if (mantissa < static_cast<Wide>(minimum) || mantissa > static_cast<Wide>(maximum))
    throw std::invalid_argument(message);
  return static_cast<std::int64_t>(mantissa);
}

// ---- TwoLevelPlan ----

namespace {

std::int64_t revolveSteps(std::int64_t length, std::int64_t slots) {
  return static_cast<std::int64_t>(revolve::optimalForwardSteps(length, slots));
}

// Replaying x_{N-1} is evaluated while the first sweep has at most this many pushes to walk through;
// beyond, the working state is used (with that many slots one more slot changes little).
constexpr std::int64_t kMaxReplayWalk = 4096;
// Every length of the last leaf is tried up to this N.
constexpr std::int64_t kExhaustiveLastLeaf = 2048;

std::int64_t lastLeafSlots(std::int64_t length, std::int64_t ramSlots, bool replay) {
  return std::min(replay ? ramSlots : ramSlots - 1, std::max<std::int64_t>(1, length - 1));
}

// Recomputed steps of the last leaf (working state, or x_{N-1} replayed from the top checkpoint).
std::int64_t lastLeafRecomputed(std::int64_t length, std::int64_t ramSlots, bool replay) {
  if (length < 2) return 0;
  const std::int64_t slots = lastLeafSlots(length, ramSlots, replay);
  const std::int64_t sweep = revolveSteps(length, slots) - (length - 1);
  return replay ? sweep + (length - 1 - revolve::firstSweep(length, slots).top) : sweep;
}

bool replayAffordable(std::int64_t length, std::int64_t ramSlots) {
  return std::min(length, ramSlots) <= kMaxReplayWalk;
}

struct CountingVisitor {
  TwoLevelPlan::Counts& counts;
  void store(StorageLevel level, std::int64_t) {
    ++(level == StorageLevel::kRam ? counts.ramWrites : counts.diskWrites);
  }
  void load(StorageLevel level, std::int64_t) {
    ++(level == StorageLevel::kRam ? counts.ramReads : counts.diskReads);
  }
  void advance(std::int64_t from, std::int64_t to) { counts.recomputedSteps += to - from; }
};

}  // namespace

TwoLevelPlan TwoLevelPlan::leaves(std::int64_t steps, std::int64_t ramSlots, std::int64_t leafCount,
                                  std::int64_t lastLength, bool replayLast) {
  if (steps < 1 || ramSlots < 2 || leafCount < 1 || leafCount > steps || lastLength < 1 ||
      steps - lastLength < leafCount - 1 || (leafCount == 1 && lastLength != steps)) {
    throw std::invalid_argument(
        "two-level plan 'leaves' needs N >= 1, ram slots >= 2, 1 <= K <= N and a last "
        "leaf of 1..N-K+1 steps (N = " +
        std::to_string(steps) + ", ram slots = " + std::to_string(ramSlots) +
        ", K = " + std::to_string(leafCount) + ", last = " + std::to_string(lastLength) + ")");
  }
  TwoLevelPlan plan;
  plan.kind_ = Kind::kLeaves;
  plan.steps_ = steps;
  plan.ramSlots_ = ramSlots;
  plan.leafCount_ = leafCount;
  plan.lastLength_ = lastLength;
  plan.replayLast_ = replayLast && lastLength >= 2;
  std::int64_t ram =
      lastLeafSlots(lastLength, ramSlots, plan.replayLast_) + (lastLength >= 2 && !plan.replayLast_ ? 1 : 0);
  if (leafCount > 1) ram = std::max(ram, std::min(ramSlots, plan.leafLength(0)));
  plan.ramSlotsUsed_ = ram;
  plan.diskSlotsUsed_ = leafCount - 1;
  plan.counts_ = plan.countLeaves();
  return plan;
}

TwoLevelPlan TwoLevelPlan::allSlots(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                                    bool replayLast) {
  if (steps < 1 || ramSlots < 1 || diskSlots < 0 || (steps >= 2 && ramSlots + diskSlots < 2)) {
    throw std::invalid_argument(
        "two-level plan 'allSlots' needs N >= 1, ram slots >= 1 and, for N >= 2, two "
        "slots in all (N = " +
        std::to_string(steps) + ", ram slots = " + std::to_string(ramSlots) +
        ", disk slots = " + std::to_string(diskSlots) + ")");
  }
  TwoLevelPlan plan;
  plan.kind_ = Kind::kAllSlots;
  plan.steps_ = steps;
  plan.ramSlots_ = ramSlots;
  plan.replayLast_ = replayLast && steps >= 2;
  if (steps == 1) {
    plan.revolveSlots_ = 1;
    plan.diskSlotsUsed_ = 0;
    plan.ramSlotsUsed_ = 1;
  } else {
    const std::int64_t ramCheckpoints = plan.replayLast_ ? ramSlots : ramSlots - 1;
    plan.diskSlotsUsed_ = std::min(diskSlots, std::max<std::int64_t>(0, (steps - 1) - ramCheckpoints));
    plan.revolveSlots_ = std::min(ramCheckpoints + plan.diskSlotsUsed_, steps - 1);
    plan.ramSlotsUsed_ = plan.revolveSlots_ - plan.diskSlotsUsed_ + (plan.replayLast_ ? 0 : 1);
  }
  plan.counts_ = plan.walk();
  return plan;
}

// ---- the dynamic programme (kDynamic) ----
//
// For a segment of l states x_p..x_e (l = e - p + 1) whose first state is a checkpoint at level L, with
// m RAM and d disk slots free besides it:
//   F_L(l, m, d)  = r_L + G_L(l, m, d)        (load x_p: r_RAM = 0, r_disk = rd),
//   G_L(1, m, d)  = 0                          (x_e = x_p is at hand; its slot is freed),
//   G_L(l, m, d)  = min of                     (x_p at hand, l >= 2)
//     (l - 1) uf + F_L(l - 1, m, d)                                   advance to x_e, consume it;
//     j uf + G_RAM(l - j, m - 1, d) + F_L(j, m, d),     1 <= j <= l-2   store x_{p+j} in RAM;
//     j uf + wd + G_disk(l - j, m, d - 1) + F_L(j, m, d), 1 <= j <= l-2 store it on disk;
//     G_RAM(l, m - 1, d + 1)            (L = disk: keep x_p in RAM instead, its disk slot freed)
//     wd + G_disk(l, m + 1, d - 1)      (L = RAM: move x_p to disk, its RAM slot freed).
// The forward sweep at x_p (nothing stored from p on, advancing free), m and d slots free:
//   H(l, m, d) = min over L of w_L + min( F_L(l, m', d'),  min_{1<=j<=l-1} H(l - j, m', d') + F_L(j, m', d')
//   )
// with w_RAM = 0, w_disk = wd and (m', d') the slots left after storing x_p at L; F_L(l, ...) there
// stores nothing more in the forward sweep (the later states are replayed from x_p). The game's cost
// is H(N, R, D). Moving a checkpoint there and back is never cheaper, so applying the two moves to the
// values without moves is exact. O(N^2 R D) time, O(N R D) memory.
struct TwoLevelPlan::DynamicTables {
  std::int64_t steps = 0, ram = 0, disk = 0;
  struct Entry {
    double cost;
    std::int32_t distance;
    std::int8_t action;
  };
  std::vector<Entry> backward[2];  // G_L, L = 0 RAM, 1 disk
  std::vector<Entry> forward;      // H; action = level index
  std::size_t index(std::int64_t l, std::int64_t m, std::int64_t d) const {
    return static_cast<std::size_t>((l * (ram + 1) + m) * (disk + 1) + d);
  }
};

bool TwoLevelPlan::dynamicAffordable(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots) {
  if (steps < 1 || ramSlots < 0 || diskSlots < 0) return false;
  const auto n = static_cast<UnsignedInt128>(steps);
  const auto r = static_cast<UnsignedInt128>(std::min(ramSlots, steps) + 1);
  const auto d = static_cast<UnsignedInt128>(std::min(diskSlots, steps) + 1);
  return n * n * r * d <= static_cast<UnsignedInt128>(kMaxDynamicWork);
}

TwoLevelPlan TwoLevelPlan::dynamic(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                                   const ScheduleCosts& costs) {
  if (!dynamicAffordable(steps, ramSlots, diskSlots)) {
    throw std::invalid_argument("two-level plan 'dynamic': N = " + std::to_string(steps) + " with " +
                                std::to_string(ramSlots) + " RAM and " + std::to_string(diskSlots) +
                                " disk slots exceeds its work limit N^2 (R + 1)(D + 1) <= 2^28");
  }
  if (steps >= 2 && (ramSlots < 1 || ramSlots + diskSlots < 2)) {
    throw std::invalid_argument("two-level plan 'dynamic': " + std::to_string(ramSlots) + " RAM and " +
                                std::to_string(diskSlots) + " disk slots cannot reverse N >= 2 steps");
  }
  auto tables = std::make_shared<DynamicTables>();
  DynamicTables& t = *tables;
  t.steps = steps;
  t.ram = std::min(ramSlots, steps);  // more slots than states are never used
  t.disk = std::min(diskSlots, steps);
  const std::size_t size = t.index(steps + 1, 0, 0);
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  for (auto& table : t.backward) table.assign(size, DynamicTables::Entry{kInfinity, 0, kDone});
  t.forward.assign(size, DynamicTables::Entry{kInfinity, 0, 0});
  const double uf = costs.forwardStep, wd = costs.diskWrite, rd = costs.diskRead;
  const double read[2] = {0.0, rd}, write[2] = {0.0, wd};
  const auto loaded = [&](int level, std::int64_t l, std::int64_t m, std::int64_t d) {  // F_L
    return read[level] + t.backward[level][t.index(l, m, d)].cost;
  };
  std::vector<DynamicTables::Entry> plain[2];  // G_L at one l before the moves
  for (auto& row : plain) row.resize(static_cast<std::size_t>((t.ram + 1) * (t.disk + 1)));
  const auto cell = [&](std::int64_t m, std::int64_t d) {
    return static_cast<std::size_t>(m * (t.disk + 1) + d);
  };
  for (std::int64_t l = 1; l <= steps; ++l) {
    pollInterrupt();
    for (std::int64_t m = 0; m <= t.ram; ++m) {
      for (std::int64_t d = 0; d <= t.disk; ++d) {
        for (int level = 0; level < 2; ++level) {
          DynamicTables::Entry best{l == 1 ? 0.0 : kInfinity, 0,
                                    static_cast<std::int8_t>(l == 1 ? kDone : kNone)};
          if (l >= 2) {
            best.cost = static_cast<double>(l - 1) * uf + loaded(level, l - 1, m, d);
            for (std::int64_t j = 1; j <= l - 2; ++j) {
              const double lower = static_cast<double>(j) * uf + loaded(level, j, m, d);
              if (m >= 1) {
                const double cost = lower + t.backward[0][t.index(l - j, m - 1, d)].cost;
                if (cost < best.cost) best = {cost, static_cast<std::int32_t>(j), kStoreRam};
              }
              if (d >= 1) {
                const double cost = lower + wd + t.backward[1][t.index(l - j, m, d - 1)].cost;
                if (cost < best.cost) best = {cost, static_cast<std::int32_t>(j), kStoreDisk};
              }
            }
          }
          plain[level][cell(m, d)] = best;
        }
      }
    }
    for (std::int64_t m = 0; m <= t.ram; ++m) {
      for (std::int64_t d = 0; d <= t.disk; ++d) {
        DynamicTables::Entry ram = plain[0][cell(m, d)], disk = plain[1][cell(m, d)];
        if (l >= 2 && d >= 1 && m + 1 <= t.ram && wd + plain[1][cell(m + 1, d - 1)].cost < ram.cost)
          ram = {wd + plain[1][cell(m + 1, d - 1)].cost, 0, kMove};
        if (l >= 2 && m >= 1 && d + 1 <= t.disk && plain[0][cell(m - 1, d + 1)].cost < disk.cost)
          disk = {plain[0][cell(m - 1, d + 1)].cost, 0, kMove};
        t.backward[0][t.index(l, m, d)] = ram;
        t.backward[1][t.index(l, m, d)] = disk;
      }
    }
    for (std::int64_t m = 0; m <= t.ram; ++m) {
      for (std::int64_t d = 0; d <= t.disk; ++d) {
        DynamicTables::Entry best{kInfinity, 0, 0};
        for (int level = 0; level < 2; ++level) {
          const std::int64_t m2 = level == 0 ? m - 1 : m, d2 = level == 1 ? d - 1 : d;
          if (m2 < 0 || d2 < 0) continue;
          double cost = write[level] + loaded(level, l, m2, d2);
          if (cost < best.cost) best = {cost, 0, static_cast<std::int8_t>(level)};
          for (std::int64_t j = 1; j <= l - 1; ++j) {
            cost = write[level] + t.forward[t.index(l - j, m2, d2)].cost + loaded(level, j, m2, d2);
            if (cost < best.cost)
              best = {cost, static_cast<std::int32_t>(j), static_cast<std::int8_t>(level)};
          }
        }
        t.forward[t.index(l, m, d)] = best;
      }
    }
  }
  if (!(t.forward[t.index(steps, t.ram, t.disk)].cost < kInfinity)) {
    throw std::invalid_argument("two-level plan 'dynamic': no schedule for N = " + std::to_string(steps));
  }
  TwoLevelPlan plan;
  plan.kind_ = Kind::kDynamic;
  plan.steps_ = steps;
  plan.ramSlots_ = t.ram;
  plan.dynamic_ = std::move(tables);
  plan.counts_ = plan.walk();  // also the slots in use at the most (takeSlot)
  plan.ramSlotsUsed_ = plan.peakRam_;
  plan.diskSlotsUsed_ = plan.peakDisk_;
  return plan;
}

TwoLevelPlan::Decision TwoLevelPlan::forwardDecision(std::int64_t length) const {
  const DynamicTables::Entry& e = dynamic_->forward[dynamic_->index(length, freeRam_, freeDisk_)];
  return Decision{e.action, e.distance};
}

TwoLevelPlan::Decision TwoLevelPlan::backwardDecision(StorageLevel level, std::int64_t length) const {
  const DynamicTables::Entry& e =
      dynamic_->backward[level == StorageLevel::kRam ? 0 : 1][dynamic_->index(length, freeRam_, freeDisk_)];
  return Decision{e.action, e.distance};
}

std::int64_t TwoLevelPlan::takeSlot(StorageLevel level) {
  // The lowest free slot, so that the slots in use at the most are 0..peak-1.
  std::vector<char>& busy = level == StorageLevel::kRam ? ramBusy_ : diskBusy_;
  std::size_t slot = 0;
  while (busy[slot]) ++slot;
  busy[slot] = 1;
  --(level == StorageLevel::kRam ? freeRam_ : freeDisk_);
  std::int64_t& peak = level == StorageLevel::kRam ? peakRam_ : peakDisk_;
  peak = std::max(peak, static_cast<std::int64_t>(slot) + 1);
  return static_cast<std::int64_t>(slot);
}

void TwoLevelPlan::releaseSlot(const Held& held) {
  (held.level == StorageLevel::kRam ? ramBusy_ : diskBusy_)[static_cast<std::size_t>(held.slot)] = 0;
  ++(held.level == StorageLevel::kRam ? freeRam_ : freeDisk_);
}

TwoLevelPlan TwoLevelPlan::choose(std::int64_t steps, std::int64_t ramSlots, std::int64_t diskSlots,
                                  const ScheduleCosts& costs) {
  if (steps < 1)
    throw std::invalid_argument("two-level plan: N = " + std::to_string(steps) + " must be >= 1");
  if (steps >= 2 && (ramSlots < 1 || ramSlots + diskSlots < 2)) {
    throw std::invalid_argument("two-level plan: " + std::to_string(ramSlots) + " RAM and " +
                                std::to_string(diskSlots) +
                                " disk slots cannot reverse N >= 2 steps; RAM must hold one state and both "
                                "levels two");
  }
  // leaves(K) in closed form for every K (O(min(N, disk slots + 1)) evaluations of revolve's T).
  const double write = costs.diskWrite + costs.diskRead;
  double bestCost = std::numeric_limits<double>::infinity();
  std::int64_t bestLeaves = 0;
  std::int64_t bestLast = steps;
  bool bestReplay = false;
  if (ramSlots >= 2) {
    // K - 1 balanced leaves over N - L steps and a last leaf of L steps (cheaper per step: the forward
    // sweep is its first sweep). For a given L, cost(K) is linear in K wherever
    // base = floor((N - L) / (K - 1)) is constant (the lengths and hence their revolve counts are fixed,
    // only the number of long leaves moves), so the ends of those O(sqrt N) intervals are the only
    // candidates. L runs over all of 1..N for N <= kExhaustiveLastLeaf, else over the breakpoints of
    // the last leaf's revolve count (and the balanced plans, where L = floor(N / K), are added).
    const auto lastCost = [&](std::int64_t length, bool* replay) {
      const std::int64_t working = lastLeafRecomputed(length, ramSlots, false);
      const std::int64_t replayed =
          replayAffordable(length, ramSlots) ? lastLeafRecomputed(length, ramSlots, true) : working;
      *replay = replayed < working;
      return std::min(working, replayed);
    };
    const auto evaluate = [&](std::int64_t k, std::int64_t last, double lastRecomputed, bool replay) {
      double recomputed = lastRecomputed;
      if (k > 1) {
        const std::int64_t rest = steps - last;
        const std::int64_t base = rest / (k - 1), extra = rest % (k - 1);
        recomputed += static_cast<double>(k - 1 - extra) *
                      static_cast<double>(revolveSteps(base, std::min(ramSlots, base)));
        if (extra > 0)
          recomputed += static_cast<double>(extra) *
                        static_cast<double>(revolveSteps(base + 1, std::min(ramSlots, base + 1)));
      }
      const double cost = recomputed * costs.forwardStep + static_cast<double>(k - 1) * write;
      if (cost < bestCost) {
        bestCost = cost;
        bestLeaves = k;
        bestLast = last;
        bestReplay = replay;
      }
    };
    const std::int64_t maxLeaves = std::min(steps, diskSlots + 1);
    std::vector<std::int64_t> lasts;
    if (steps <= kExhaustiveLastLeaf) {
      for (std::int64_t l = 1; l <= steps; ++l) lasts.push_back(l);
    } else {
      // The balanced plans: K leaves of floor(N / K) or one more step, the last one the shortest.
      for (std::int64_t k = 1; k <= maxLeaves;) {
        pollInterrupt();
        const std::int64_t end = std::min(maxLeaves, steps / (steps / k));
        for (std::int64_t kk : {k, end}) {
          bool replay = false;
          const std::int64_t last = steps / kk;
          evaluate(kk, last, static_cast<double>(lastCost(last, &replay)), replay);
        }
        k = end + 1;
      }
      for (std::int64_t r = 1; r <= 8; ++r) {
        for (std::int64_t s : {ramSlots - 1, ramSlots}) {
          const auto b = revolve::beta(s, r);
          if (b > static_cast<UnsignedInt128>(steps)) continue;
          for (std::int64_t d = -1; d <= 1; ++d) lasts.push_back(static_cast<std::int64_t>(b) + d);
        }
      }
      std::sort(lasts.begin(), lasts.end());
      lasts.erase(std::unique(lasts.begin(), lasts.end()), lasts.end());
    }
    for (std::int64_t last : lasts) {
      pollInterrupt();  // O(sqrt N) evaluations each, up to 2048 lengths
      if (last < 1 || last > steps) continue;
      bool replay = false;
      const double lastRecomputed = static_cast<double>(lastCost(last, &replay));
      if (last == steps) {
        evaluate(1, last, lastRecomputed, replay);
        continue;
      }
      const std::int64_t rest = steps - last;
      const std::int64_t maxOthers = std::min(rest, maxLeaves - 1);
      for (std::int64_t k = 1; k <= maxOthers;) {  // k = number of other leaves
        const std::int64_t end = std::min(maxOthers, rest / (rest / k));
        evaluate(k + 1, last, lastRecomputed, replay);
        if (end != k) evaluate(end + 1, last, lastRecomputed, replay);
        k = end + 1;
      }
    }
  }
  // The dynamic programme is the optimum over stack schedules, which include both families; it is
  // compared with them anyway (ties keep the family, whose counts are also in closed form).
  std::optional<TwoLevelPlan> optimal;
  if (dynamicAffordable(steps, ramSlots, diskSlots)) {
    optimal = dynamic(steps, ramSlots, diskSlots, costs);
  } else {
    const UnsignedInt128 cells =
        static_cast<UnsignedInt128>(steps) *
        static_cast<UnsignedInt128>(std::min(ramSlots, steps) + std::min(diskSlots, steps) + 2);
    if (ramSlots >= 1 && cells <= static_cast<UnsignedInt128>(kMaxHierarchicalCells)) {
      TwoLevelPlan plan;
      plan.kind_ = Kind::kHierarchical;
      plan.steps_ = steps;
      plan.ramSlots_ = std::min(ramSlots, steps);
      plan.hierarchical_ = KLevelPlan::hierarchical(
          steps, ramSlots, {StorageLevelCosts{diskSlots, costs.diskWrite, costs.diskRead}}, costs.forwardStep,
          kHierarchicalWindow);
      plan.ramSlotsUsed_ = plan.hierarchical_->slotsUsed()[0];
      plan.diskSlotsUsed_ = plan.hierarchical_->slotsUsed()[1];
      plan.counts_ = plan.walk();
      optimal = std::move(plan);
    }
  }
  const auto better = [&](TwoLevelPlan plan) {
    if (optimal && optimal->counts().cost(costs) < plan.counts().cost(costs)) return std::move(*optimal);
    return plan;
  };
  if (steps <= kMaxSimulatedSteps && (diskSlots > 0 || ramSlots < 2)) {
    TwoLevelPlan all = allSlots(steps, ramSlots, diskSlots, false);
    if (steps >= 2 && replayAffordable(steps, ramSlots + diskSlots)) {
      TwoLevelPlan replayed = allSlots(steps, ramSlots, diskSlots, true);
      if (replayed.counts().cost(costs) < all.counts().cost(costs)) all = std::move(replayed);
    }
    if (all.counts().cost(costs) < bestCost) return better(std::move(all));
  }
  if (bestLeaves == 0 && optimal) return std::move(*optimal);
  if (bestLeaves == 0) {
    throw std::invalid_argument("two-level plan: with one RAM slot and N = " + std::to_string(steps) +
                                " > 2^24 steps no plan is counted; give RAM at least two states");
  }
  return better(leaves(steps, ramSlots, bestLeaves, bestLast, bestReplay));
}

std::string TwoLevelPlan::describe() const {
  if (kind_ == Kind::kHierarchical) {
    return "hierarchical two-level stack schedule (H-Revolve's structure with moves): up to " +
           std::to_string(ramSlotsUsed_) + " RAM and " + std::to_string(diskSlotsUsed_) +
           " disk states, slots reused";
  }
  if (kind_ == Kind::kDynamic) {
    return "optimal two-level stack schedule (dynamic programme): up to " + std::to_string(ramSlotsUsed_) +
           " RAM and " + std::to_string(diskSlotsUsed_) + " disk states, slots reused";
  }
  const std::string last = replayLast_ ? ", last state replayed" : ", working state";
  if (kind_ == Kind::kAllSlots) {
    return "revolve over all slots: " + std::to_string(revolveSlots_) + " checkpoints (the bottom " +
           std::to_string(diskSlotsUsed_) + " on disk)" + last;
  }
  if (leafCount_ == 1) return "revolve in RAM: " + std::to_string(ramSlotsUsed_) + " states" + last;
  const std::int64_t rest = steps_ - lastLength_;
  const std::int64_t base = rest / (leafCount_ - 1);
  return "leaves: " + std::to_string(leafCount_ - 1) + " of " + std::to_string(base) +
         (rest % (leafCount_ - 1) ? "-" + std::to_string(base + 1) : std::string()) +
         " steps starting on disk, a last one of " + std::to_string(lastLength_) + "; revolve over " +
         std::to_string(ramSlotsUsed_) + " RAM states in each" + last;
}

// Leaves 0..K-2 split N - L steps evenly (the first ones one step longer); leaf K-1 has L steps.
std::int64_t TwoLevelPlan::leafStart(std::int64_t leaf) const {
  if (leaf == leafCount_ - 1) return steps_ - lastLength_;
  const std::int64_t rest = steps_ - lastLength_;
  const std::int64_t base = rest / (leafCount_ - 1), extra = rest % (leafCount_ - 1);
  return leaf * base + std::min(leaf, extra);
}

std::int64_t TwoLevelPlan::leafLength(std::int64_t leaf) const {
  if (leaf == leafCount_ - 1) return lastLength_;
  const std::int64_t rest = steps_ - lastLength_;
  return rest / (leafCount_ - 1) + (leaf < rest % (leafCount_ - 1) ? 1 : 0);
}

std::int64_t TwoLevelPlan::leafOf(std::int64_t n) const {
  const std::int64_t rest = steps_ - lastLength_;
  if (n >= rest) return leafCount_ - 1;
  const std::int64_t base = rest / (leafCount_ - 1), extra = rest % (leafCount_ - 1);
  const std::int64_t longPart = extra * (base + 1);
  return n < longPart ? n / (base + 1) : extra + (n - longPart) / base;
}

std::int64_t TwoLevelPlan::leafSlots(std::int64_t leaf) const {
  const std::int64_t length = leafLength(leaf);
  return leaf == leafCount_ - 1 ? lastLeafSlots(length, ramSlots_, replayLast_) : std::min(ramSlots_, length);
}

TwoLevelPlan::Counts TwoLevelPlan::countLeaves() const {
  Counts c;
  const std::int64_t k = leafCount_;
  const std::int64_t last = lastLength_;
  c.recomputedSteps = lastLeafRecomputed(last, ramSlots_, replayLast_);
  if (k > 1) {
    const std::int64_t rest = steps_ - last;
    const std::int64_t base = rest / (k - 1), extra = rest % (k - 1);
    c.recomputedSteps += (k - 1 - extra) * revolveSteps(base, std::min(ramSlots_, base));
    if (extra > 0) c.recomputedSteps += extra * revolveSteps(base + 1, std::min(ramSlots_, base + 1));
  }
  const std::int64_t pushes = last >= 2 ? revolve::firstSweep(last, leafSlots(k - 1)).pushes : 0;
  c.diskWrites = k - 1;
  c.diskReads = k - 1;
  c.statesStored = (k - 1) + 1 + pushes + (last >= 2 && !replayLast_ ? 1 : 0);
  // RAM traffic: every restore loads one state (the working state counts as a RAM read), the leaves'
  // first states are copied into RAM slot 0; revolve's stores in the backward sweep are counted by
  // running the schedule when N is small enough (they cost nothing in the model).
  c.ramReads = steps_;
  c.ramWrites = -1;
  return c;
}

TwoLevelPlan::Counts TwoLevelPlan::walk() {
  Counts c;
  CountingVisitor visitor{c};
  rewind();
  // Up to 2^24 steps: the interrupt is polled every 2^16 of them (engine/interrupt.h).
  for (std::int64_t n = 0; n < steps_; ++n) {
    if ((n & 0xffff) == 0) pollInterrupt();
    recordForward(n, visitor);
  }
  c.statesStored = c.ramWrites + c.diskWrites;
  for (std::int64_t e = steps_ - 1; e >= 0; --e) {
    if ((e & 0xffff) == 0) pollInterrupt();
    restoreStep(e, visitor);
  }
  rewind();
  return c;
}

void TwoLevelPlan::rewind() {
  currentLeaf_ = -1;
  if (kind_ == Kind::kHierarchical) hierarchical_->rewind();
  if (kind_ == Kind::kDynamic) {
    held_.clear();
    held_.reserve(static_cast<std::size_t>(dynamic_->ram + dynamic_->disk + 1));
    ramBusy_.assign(static_cast<std::size_t>(dynamic_->ram), 0);
    diskBusy_.assign(static_cast<std::size_t>(dynamic_->disk), 0);
    freeRam_ = dynamic_->ram;
    freeDisk_ = dynamic_->disk;
    nextStore_ = 0;
  }
}

// ---- predictions ----

SchedulePrediction predictSchedule(const std::string& specText, std::int64_t steps, std::int64_t stateBytes,
                                   int stages, const ScheduleCosts* costs, std::int64_t stageBytes) {
  if (steps < 1 || steps > kMaxScheduleSteps) {
    throw std::invalid_argument("--steps = " + std::to_string(steps) + " must be an integer in [1, " +
                                std::to_string(kMaxScheduleSteps) + "]");
  }
  if (stateBytes < 8 || stateBytes % 8 != 0 || stateBytes > kMaxScheduleStateBytes) {
    throw std::invalid_argument("--state-bytes = " + std::to_string(stateBytes) +
                                " must be a multiple of 8 in [8, " + std::to_string(kMaxScheduleStateBytes) +
                                "] (8 bytes per state entry, at most 2^31 - 1 entries as a run allows)");
  }
  if (stages < 1 || stages > kMaxScheduleStages) {
    throw std::invalid_argument("--stages = " + std::to_string(stages) + " must be an integer in [1, " +
                                std::to_string(kMaxScheduleStages) + "]");
  }
  if (stageBytes < 0 || stageBytes % 8 != 0 || stageBytes > kMaxScheduleStateBytes) {
    throw std::invalid_argument("--stage-bytes = " + std::to_string(stageBytes) +
                                " must be a multiple of 8 in [0, " + std::to_string(kMaxScheduleStateBytes) +
                                "] (8 bytes per double of rhs data a stage keeps)");
  }
  // Each strategy's own prediction, from its row (engine/storage_registry.h).
  return predictFromRows(storageStrategies(), specText,
                         PredictionRequest{steps, stateBytes, stages, costs, stageBytes});
}

void writeScheduleActions(const std::string& specText, std::int64_t steps, std::int64_t stateBytes,
                          int stages, const ScheduleCosts* costs, std::ostream& out,
                          std::int64_t stageBytes) {
  predictSchedule(specText, steps, stateBytes, stages, costs,
                  stageBytes);  // validates spec, sizes and budgets
  if (steps > TwoLevelPlan::kMaxSimulatedSteps) {
    throw std::invalid_argument("--actions lists every action, for --steps up to " +
                                std::to_string(TwoLevelPlan::kMaxSimulatedSteps) +
                                " (2^24); --steps = " + std::to_string(steps));
  }
  // Each strategy's own plan, from its row (engine/storage_registry.h); predictSchedule has refused the
  // rows without a prediction.
  const std::vector<StorageStrategyRow>& rows = storageStrategies();
  const StorageSpec spec = StorageSpec::parse(specText);
  const StorageStrategyRow& row = *findStorageStrategy(rows, spec.name());
  if (row.actions == nullptr) throw std::invalid_argument(row.noActions);
  const std::unique_ptr<TrajectoryStorage> storage = createFromRows(rows, specText);
  row.actions(*storage, spec, PredictionRequest{steps, stateBytes, stages, costs, stageBytes}, out);
}

}  // namespace hindsight
