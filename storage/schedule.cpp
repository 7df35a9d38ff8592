#include <hindsight/storage/schedule.h>

#include <hindsight/engine/cams_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/interrupt.h>
#include <hindsight/engine/online_checkpointing.h>
#include <hindsight/engine/online_placement.h>
#include <hindsight/engine/recomputed_stages.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/storage/chunked_state_file.h>
#include <hindsight/storage/disk_storage.h>
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/storage_factory.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
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

// ---- ScheduleCosts ----

ScheduleCosts ScheduleCosts::parse(const std::string& text, const std::string& field) {
  const std::string expected = field + " = '" + text +
                               "' must be four numbers uf:ub:wd:rd in [0, 1e30] (seconds of a forward step, "
                               "an adjoint step, a disk write and a disk read of one state), uf > 0";
  double values[4];
  std::size_t position = 0;
  for (int i = 0; i < 4; ++i) {
    const std::size_t end = i < 3 ? text.find(':', position) : text.size();
    if (end == std::string::npos) throw std::invalid_argument(expected);
    const std::string part = text.substr(position, end - position);
    std::size_t used = 0;
    try {
      values[i] = std::stod(part, &used);
    } catch (const std::exception&) {
      throw std::invalid_argument(expected);
    }
    if (used != part.size() || !(values[i] >= 0.0 && values[i] <= kMaxScheduleCost))
      throw std::invalid_argument(expected);
    position = end + 1;
  }
  if (values[0] <= 0.0) throw std::invalid_argument(expected);
  return ScheduleCosts{values[0], values[1], values[2], values[3]};
}

std::string ScheduleCosts::text() const {
  // Shortest text that reads back to the same doubles (the spec round-trips).
  std::string out;
  for (double value : {forwardStep, adjointStep, diskWrite, diskRead}) {
    char buffer[32];
    const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
    if (!out.empty()) out += ':';
    out.append(buffer, result.ptr);
  }
  return out;
}

const char* levelName(StorageLevel level) { return level == StorageLevel::kRam ? "ram" : "disk"; }

// ---- TwoLevelPlan ----

namespace {

std::int64_t revolveSteps(std::int64_t length, std::int64_t slots) {
  return static_cast<std::int64_t>(revolve::optimalForwardSteps(length, slots));
}

// The checkpoints BinomialSchedule::reset(length, slots, true) pushes in the first sweep (x_0 not
// counted) and the position of the last one (0 when none). Once the rest fits the free slots
// (l <= free + 2, repetition number 1) every split is 1 and positions top + 1 .. length - 2 are all
// pushed: counted at once, so this takes O(pushes while r >= 2), not O(min(slots, length)).
struct FirstSweep {
  std::int64_t pushes = 0;
  std::int64_t top = 0;
};
FirstSweep firstSweep(std::int64_t length, std::int64_t slots) {
  FirstSweep sweep;
  std::int64_t free = slots - 1;
  while (length - sweep.top >= 2 && free > 0) {
    if (length - sweep.top <= free + 2) {
      if (length - sweep.top >= 3) {
        sweep.pushes += length - sweep.top - 2;
        sweep.top = length - 2;
      }
      break;
    }
    const std::int64_t target = sweep.top + revolve::binomialSplit(length - sweep.top, free + 1);
    if (target >= length - 1) break;
    ++sweep.pushes;
    sweep.top = target;
    --free;
  }
  return sweep;
}
std::int64_t firstSweepPushes(std::int64_t length, std::int64_t slots) {
  return firstSweep(length, slots).pushes;
}

// Checkpoint writes of a whole BinomialSchedule run (reset(length, slots, true): x_0, the first sweep's
// and the backward sweep's stores; the working state not included), revolve::simulateSchedule's
// checkpointWrites in closed form. W(l, s), the stores at positions >= 1 while reversing l steps whose
// first state is held, with s slots (the first sweep stores exactly what the restore of l - 1 would),
// follows the schedule's split m = binomialSplit(l, s):
//     W(l, s) = [l - m >= 2] + W(l - m, s - 1) + W(m, s),   W(1, s) = W(l, 1) = 0,
// and W(l, s) = l - 2 when l <= s + 1 (r = 1: every position but the last is stored). On an exact
// binomial length, W(beta(s, r), s) = beta(s - 1, r) - 1 (W + 1 obeys Pascal's rule with ones on the
// border). With r the repetition number of l, binomialSplit takes m = beta(s, r - 1) (the left part
// exact) or m = l - beta(s - 1, r - 1) (the right part exact), so one part is closed form and the
// other continues with s - 1 or with a smaller r: O(s + r) iterations. The tests compare it with
// revolve::simulateSchedule.
std::int64_t revolveWrites(std::int64_t length, std::int64_t slots) {
  const auto exactWrites = [](std::int64_t s, std::int64_t r) {  // W(beta(s, r), s)
    return s <= 1 ? std::int64_t{0} : static_cast<std::int64_t>(revolve::beta(s - 1, r)) - 1;
  };
  std::int64_t writes = 1;  // x_0
  std::int64_t l = length, s = slots;
  while (l >= 2 && s >= 2) {
    const std::int64_t r = revolve::repetitionNumber(l, s);
    if (r <= 1) {
      writes += l - 2;
      break;
    }
    const std::int64_t m = revolve::binomialSplit(l, s);
    if (l - m >= 2) ++writes;
    if (static_cast<UnsignedInt128>(m) == revolve::beta(s, r - 1)) {
      writes += exactWrites(s, r - 1);
      l -= m;
      --s;
    } else {
      if (static_cast<UnsignedInt128>(l - m) != revolve::beta(s - 1, r - 1))
        throw std::logic_error("revolveWrites: binomialSplit left no part of binomial length");
      writes += exactWrites(s - 1, r - 1);
      l = m;
    }
  }
  return writes;
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
  return replay ? sweep + (length - 1 - firstSweep(length, slots).top) : sweep;
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
  plan.counts_ = plan.countBySimulation();
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
          DynamicTables::Entry best{l == 1 ? 0.0 : kInfinity, 0, l == 1 ? kDone : kNone};
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
  plan.counts_ = plan.countBySimulation();  // also the slots in use at the most (takeSlot)
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
  if (dynamicAffordable(steps, ramSlots, diskSlots)) optimal = dynamic(steps, ramSlots, diskSlots, costs);
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
  const std::int64_t pushes = last >= 2 ? firstSweepPushes(last, leafSlots(k - 1)) : 0;
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

TwoLevelPlan::Counts TwoLevelPlan::countBySimulation() {
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

namespace {

// Counts and bytes of a prediction are int64; every product and sum that could leave that range is
// computed in 128 bits and refused with a message naming the quantity instead of wrapping around.
constexpr std::int64_t kMaxCount = std::numeric_limits<std::int64_t>::max();
// online's placement (internal::CostPlacement::simulate) walks the forward sweep step by step.
constexpr std::int64_t kMaxOnlineSteps = std::int64_t{1} << 24;

std::int64_t checkedCount(UnsignedInt128 value, const std::string& what) {
  if (value > static_cast<UnsignedInt128>(kMaxCount)) {
    throw std::invalid_argument(
        what + " = " + revolve::toString(value) +
        " exceed the counters' range (2^63 - 1); lower --steps or raise the checkpoints");
  }
  return static_cast<std::int64_t>(value);
}

std::int64_t checkedProduct(std::int64_t a, std::int64_t b, const std::string& what) {
  assert(a >= 0 && b >= 0);
  return checkedCount(static_cast<UnsignedInt128>(a) * static_cast<UnsignedInt128>(b), what);
}

}  // namespace

SchedulePrediction predictSchedule(const std::string& specText, std::int64_t steps, std::int64_t stateBytes,
                                   int stages, const ScheduleCosts* costs) {
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
  const StorageSpec spec = StorageSpec::parse(specText);
  auto storage = createStorage(specText);  // validates names, keys and values as a run would
  const int n = static_cast<int>(stateBytes / 8);
  ScheduleCosts model = costs ? *costs : ScheduleCosts{};
  SchedulePrediction p;
  p.strategy = storage->spec();
  p.steps = steps;
  p.stages = stages;
  p.forwardSteps = steps;
  const std::string& name = spec.name();
  // full and disk with stages=1: every row the state and its step's S - 1 stage states (an explicit
  // Runge-Kutta method's Integrator::stepDataSize(); none for S = 1), and every adjoint step served.
  const bool stageRows =
      (name == "full" || name == "disk") && spec.integer("stages", 0, 0, 1) == 1 && stages > 1;
  const std::int64_t rowDoubles = stageRows ? std::int64_t{n} * stages : n;
  if (stageRows) p.stepDataStored = p.stepDataRestored = steps;
  if (rowDoubles > std::numeric_limits<int>::max()) {
    throw std::invalid_argument(
        name + ".stages = 1: a row of the state and its " + std::to_string(stages - 1) +
        " stage states has " + std::to_string(rowDoubles) +
        " doubles, more than a run allows (2^31 - 1); lower --state-bytes or --stages");
  }
  if (name == "full") {
    const std::int64_t budget = spec.bytes("budget", FullStorage::kDefaultBudget);
    if (steps > budget / (8 * rowDoubles)) {
      throw std::invalid_argument(
          "full: " + std::to_string(steps) + " states of " + formatBytes(stateBytes) +
          (stageRows ? " with their stage values (" + formatBytes(8 * rowDoubles) + " a step)"
                     : std::string()) +
          " exceed full.budget = " + formatBytes(budget));
    }
    p.plan = stageRows ? "every state and its step's stage values in RAM" : "every state in RAM";
    p.statesStored = steps;
    p.ramWrites = steps;
    p.ramReads = steps;
    p.peakRamBytes = steps * 8 * rowDoubles;  // <= full.budget (checked above)
  } else if (name == "disk") {
    // DiskStorage's own rule (DiskStorage::layoutFor): rows N + 1, chunk and buffer count from the budget.
    const auto& disk = dynamic_cast<DiskStorage&>(*storage);
    const DiskStorage::Layout layout =
        disk.layoutFor(rowDoubles, checkedCount(static_cast<UnsignedInt128>(steps) + 1, "rows"));
    if (layout.bufferBytes > disk.budgetBytes()) {
      throw std::invalid_argument("disk: one chunk buffer of " + formatBytes(layout.bufferBytes) +
                                  " exceeds disk.budget = " + formatBytes(disk.budgetBytes()));
    }
    p.plan = "every state on disk, " + std::to_string(layout.chunkStates) + " states per chunk";
    p.statesStored = steps;
    p.diskWrites = checkedCount(static_cast<UnsignedInt128>(steps) + 1, "disk writes");
    p.diskReads = steps;
    p.peakRamBytes = layout.bufferCount * layout.bufferBytes;
    p.peakDiskBytes = checkedProduct(p.diskWrites, 8 * rowDoubles, "disk bytes");
  } else if (name == "binomial") {
    // BinomialCheckpointing: revolve with S = min(C + 1, N) slots over the N + 1 positions 0..N, its first
    // sweep the forward sweep (engine/binomial_checkpointing.h).
    auto& binomial = dynamic_cast<BinomialCheckpointing&>(*storage);
    const std::int64_t slots = std::min(binomial.checkpoints() + 1, steps);
    const std::int64_t states = slots;
    // stages=1 (engine/recomputed_stages.h): two step records of an explicit Runge-Kutta method, S - 1
    // stage states each (Integrator::stepDataSize(); none for S = 1), charged like the states.
    const bool keepStages = spec.integer("stages", 0, 0, 1) == 1 && stages > 1;
    const std::int64_t recordBytes =
        keepStages ? checkedProduct(2 * (stages - 1), stateBytes, "--state-bytes") : 0;
    if (recordBytes > binomial.budgetBytes() ||
        states > (binomial.budgetBytes() - recordBytes) / stateBytes) {
      throw std::invalid_argument(
          "binomial.checkpoints = " + std::to_string(binomial.checkpoints()) + " needs " +
          std::to_string(states) + " states of " + formatBytes(stateBytes) +
          (keepStages ? " and two step records of " + formatBytes(recordBytes / 2) : "") +
          ", more than binomial.budget = " + formatBytes(binomial.budgetBytes()));
    }
    // The count first: beyond 2^63 it is refused before the O(slots + r) walks below.
    p.recomputedSteps = checkedCount(revolve::optimalRecomputedSteps(steps, slots), "recomputed steps");
    const std::int64_t firstPushes = firstSweepPushes(steps + 1, slots);
    const std::int64_t writes = revolveWrites(steps + 1, slots);
    p.plan = "revolve over " + std::to_string(slots) + " slots (positions 0..N, x_N never restored)" +
             (keepStages ? ", stages of the last recomputed step kept" : "");
    p.statesStored = 1 + firstPushes;
    p.ramReads = steps;
    p.ramWrites = writes;
    if (keepStages) {
      // RecomputedStages' rule: the adjoint step of e has its stages when e = N - 1 (the forward sweep's
      // last step, never recomputed) or when the restore of e + 1 recomputed (its last step is
      // e -> e + 1). The restores that recompute nothing are those of the checkpoint positions, each
      // stored once and loaded once directly: `writes` - 1 of them among x_1 .. x_{N-1}. A restore that
      // recomputes stores stage values after every advance (one more than its checkpoint stores); summed
      // over the backward sweep with the forward sweep's one record that is N minus the first sweep's
      // pushes.
      p.stepDataRestored = steps - writes + 1;
      p.stepDataStored = steps - firstPushes;
    }
    p.peakRamBytes = checkedProduct(states, stateBytes, "--state-bytes") + recordBytes;
  } else if (name == "online") {
    // OnlineCheckpointing for N fixed steps: its placement (internal::CostPlacement), then each interval
    // j reversed by BinomialSchedule with c - j slots; recomputed steps in closed form
    // (predictedForwardSteps, tested against runs), the rest by running the schedules without states.
    auto& online = dynamic_cast<OnlineCheckpointing&>(*storage);
    if (steps > kMaxOnlineSteps) {
      throw std::invalid_argument(
          "online is predicted up to --steps = " + std::to_string(kMaxOnlineSteps) +
          " (2^24; its placement is simulated step by step); --steps = " + std::to_string(steps));
    }
    const bool keepStages = online.keepsStages() && stages > 1;
    const std::int64_t recordBytes =
        keepStages ? checkedProduct(2 * (stages - 1), stateBytes, "online: bytes of two step records") : 0;
    const std::int64_t c = online.checkpointsFor(stateBytes, recordBytes);
    std::int64_t forwardStores = 0;
    const std::vector<std::int64_t> positions = internal::CostPlacement::simulate(steps, c, &forwardStores);
    p.plan = "online placement (" + std::to_string(positions.size()) + " held), revolve per interval, " +
             std::to_string(c) + " checkpoints + working state" +
             (keepStages ? ", stages of the last recomputed step kept" : "");
    p.recomputedSteps = checkedCount(
        OnlineCheckpointing::forwardStepsOf(positions, steps, c) - static_cast<UnsignedInt128>(steps - 1),
        "recomputed steps");
    p.statesStored = forwardStores + 1;  // and x_{N-1}, the working state
    p.ramReads = steps;
    // Slots are allocated on first use and kept: beyond c + 1 steps the forward sweep uses all c (it keeps
    // every candidate while d = 1), else the N - 1 positions 0..N-2, and intervals of one step store nothing.
    p.peakRamBytes =
        checkedCount(static_cast<UnsignedInt128>(std::min(c, std::max<std::int64_t>(steps - 1, 0)) + 1) *
                             static_cast<UnsignedInt128>(stateBytes) +
                         static_cast<UnsignedInt128>(recordBytes),
                     "peak RAM bytes");
    p.ramWrites = -1;
    if (keepStages && steps > TwoLevelPlan::kMaxSimulatedSteps) {
      throw std::invalid_argument("online.stages = 1 is predicted up to " +
                                  std::to_string(TwoLevelPlan::kMaxSimulatedSteps) +
                                  " steps (its served adjoint steps are counted by running the schedules); "
                                  "--steps = " +
                                  std::to_string(steps));
    }
    if (steps <= TwoLevelPlan::kMaxSimulatedSteps) {
      // The backward sweep as OnlineCheckpointing::doRestore runs it, with RecomputedStages' rule for
      // stages=1 (one-double "stage values": only which step they belong to matters).
      struct Simulation {
        internal::RecomputedStages stages;
        bool keep;
        std::int64_t offset = 0, stores = 0, stepDataStored = 0;
        void loadWorking() {}
        void load(std::int64_t) {}
        void store(std::int64_t) { ++stores; }
        void advance(std::int64_t from, std::int64_t to) {
          if (keep && to > from) {
            stages.pending(offset + to - 1);
            ++stepDataStored;
          }
        }
      } sim;
      sim.keep = keepStages;
      sim.stages.reset(keepStages ? 1 : 0);
      std::int64_t served = 0;
      Vector data = Vector::Zero(1);
      if (keepStages) sim.stages.recordLast(steps - 1, data);
      if (keepStages && sim.stages.restore(steps - 1, data)) ++served;  // x_{N-1}: the working state
      BinomialSchedule schedule;
      internal::OnlinePlacement::Interval interval{static_cast<std::int64_t>(positions.size()), steps, 0};
      for (std::int64_t e = steps - 2; e >= 0; --e) {
        if (e < interval.start) {
          // As OnlineCheckpointing::doRestore: interval j by revolve with c - j slots.
          interval = internal::OnlinePlacement::intervalOf(positions, steps, e, interval.index);
          schedule.reset(interval.length, c - interval.index, false);
          sim.offset = interval.start;
        }
        if (keepStages) sim.stages.beginRestore(e);
        schedule.restoreStep(e - interval.start, sim);
        if (keepStages && sim.stages.restore(e, data)) ++served;
      }
      p.ramWrites = forwardStores + sim.stores + 1;
      if (keepStages) {
        p.stepDataStored = sim.stepDataStored;
        p.stepDataRestored = served;
      }
    }
  } else if (name == "multilevel") {
    auto& multilevel = dynamic_cast<MultilevelStorage&>(*storage);
    if (multilevel.options().stride) {
      throw std::invalid_argument(
          "multilevel.schedule = stride is not predicted (its RAM blocks and scratch "
          "rounds depend on the run); use schedule=optimal");
    }
    const ScheduleCosts* planCosts = multilevel.options().costs ? &*multilevel.options().costs : costs;
    if (planCosts == nullptr) {
      throw std::invalid_argument(
          "multilevel plans by its costs: give --costs uf:ub:wd:rd or costs= in the spec");
    }
    model = *planCosts;  // the spec's own costs take precedence, as in a run
    const MultilevelStorage::Layout layout = multilevel.layoutFor(steps, n);
    // The run's own check (MultilevelStorage::beginPlan), in the flags' words: the plan's message would
    // name neither the levels nor the state size.
    if (layout.ramSlots < 1 || (steps >= 2 && layout.ramSlots + layout.diskSlots < 2)) {
      throw std::invalid_argument("multilevel.ram = " + formatBytes(multilevel.budgetBytes()) +
                                  " and multilevel.disk = " + formatBytes(multilevel.options().diskBytes) +
                                  " hold " + std::to_string(layout.ramSlots) + " and " +
                                  std::to_string(layout.diskSlots) + " states of --state-bytes = " +
                                  formatBytes(stateBytes) + " for --steps = " + std::to_string(steps) +
                                  "; RAM must hold one state and both levels two: raise ram or disk");
    }
    const TwoLevelPlan plan = TwoLevelPlan::choose(steps, layout.ramSlots, layout.diskSlots, *planCosts);
    p.plan = plan.describe();
    const TwoLevelPlan::Counts& c = plan.counts();
    p.recomputedSteps = c.recomputedSteps;
    p.statesStored = c.statesStored;
    p.ramWrites = c.ramWrites;
    p.ramReads = c.ramReads;
    p.diskWrites = c.diskWrites;
    p.diskReads = c.diskReads;
    if (p.ramWrites < 0 && steps <= TwoLevelPlan::kMaxSimulatedSteps) {
      TwoLevelPlan copy = plan;
      TwoLevelPlan::Counts simulated;
      CountingVisitor visitor{simulated};
      for (std::int64_t k = 0; k < steps; ++k) copy.recordForward(k, visitor);
      for (std::int64_t e = steps - 1; e >= 0; --e) copy.restoreStep(e, visitor);
      p.ramWrites = simulated.ramWrites;
      p.ramReads = simulated.ramReads;
    }
    p.peakRamBytes = checkedProduct(plan.ramSlotsUsed(), stateBytes, "peak RAM bytes");
    p.peakDiskBytes = checkedProduct(plan.diskSlotsUsed(), stateBytes, "peak disk bytes");
  } else if (name == "cams") {
    // The same model-free plan the strategy runs (engine/cams_checkpointing.h), with the step record of
    // an explicit Runge-Kutta method: the state and S - 1 stage states (rk4: 4 state units), as
    // CamsCheckpointing::doBegin sizes it for Integrator::stepDataSize() = (S - 1) n.
    const auto& strategy = dynamic_cast<CamsCheckpointing&>(*storage);
    const bool online = strategy.onlineRequested();
    if (online && steps > kMaxOnlineSteps) {
      throw std::invalid_argument(
          "cams with online=1 is predicted up to --steps = " + std::to_string(kMaxOnlineSteps) +
          " (2^24; its placement is simulated step by step); --steps = " + std::to_string(steps));
    }
    const std::int64_t units = strategy.usableUnits(stateBytes, online);
    const std::int64_t recordUnits = stages > 1 ? stages : std::numeric_limits<std::int32_t>::max();
    cams::PlanCounts c;
    if (online) {
      // Online placement, each interval reversed by the optimal plan.
      std::unique_ptr<cams::Plan> intervalPlan;
      c = cams::simulateOnline(steps, units, recordUnits, &intervalPlan);
      p.plan = "cams online: " + std::to_string(units) +
               " state units, online placement, intervals of at most " +
               std::to_string(intervalPlan ? intervalPlan->steps() : 0) + " steps reversed optimally";
      p.ramWrites = -1;  // thinning rewrites slots; the run does not count its copies either
      p.peakRamBytes = checkedProduct(units, stateBytes, "peak RAM bytes");
    } else {
      const cams::Plan plan(steps, units, recordUnits);
      c = cams::simulate(plan);
      p.plan = "cams: " + std::to_string(plan.memoryUnits()) + " state units, records of " +
               (stages > 1 ? std::to_string(recordUnits) : std::string("-")) + " units";
      p.ramWrites = c.statesStored + c.recordsStored;
      p.peakRamBytes = checkedProduct(std::min(units, plan.memoryUnits()), stateBytes, "peak RAM bytes");
    }
    p.plan += "; " + std::to_string(c.recordsStored) + " step records, " +
              std::to_string(c.adjointRecomputations) + " adjoint steps recompute their stages";
    p.recomputedSteps = c.recomputedSteps;
    p.adjointRecomputations = c.adjointRecomputations;
    p.stepDataStored = c.recordsStored;
    p.stepDataRestored = steps - c.adjointRecomputations;
    p.statesStored = c.forwardStores;  // the strategy counts the checkpoints of the forward sweep
    p.ramReads = steps;
  } else {
    throw std::invalid_argument("storage '" + name +
                                "' is not predicted: its counters depend on the run (adaptive doubling, "
                                "compression); predicted are full, disk, binomial, online, multilevel, cams");
  }
  // An adjoint step re-evaluates its S stages unless it has them stored (cams records, stages=1):
  // S rhs for every forward, recomputed and stage-recomputing adjoint step.
  const std::int64_t adjointRecomputations =
      name == "cams" ? p.adjointRecomputations : steps - p.stepDataRestored;
  p.rhsEvaluations =
      checkedCount(static_cast<UnsignedInt128>(stages) *
                       (static_cast<UnsignedInt128>(steps) + static_cast<UnsignedInt128>(p.recomputedSteps) +
                        static_cast<UnsignedInt128>(adjointRecomputations)),
                   "rhs evaluations");
  p.scheduleCost =
      static_cast<double>(p.recomputedSteps + (name == "cams" ? p.adjointRecomputations : 0)) *
          model.forwardStep +
      static_cast<double>(name == "disk" || name == "multilevel" ? p.diskWrites : 0) * model.diskWrite +
      static_cast<double>(name == "disk" || name == "multilevel" ? p.diskReads : 0) * model.diskRead;
  p.totalCost = static_cast<double>(steps) * (model.forwardStep + model.adjointStep) + p.scheduleCost;
  return p;
}

namespace {

struct PrintingVisitor {
  std::ostream& out;
  void store(StorageLevel level, std::int64_t slot) {
    out << "store " << levelName(level) << ' ' << slot << '\n';
  }
  void load(StorageLevel level, std::int64_t slot) {
    out << "load " << levelName(level) << ' ' << slot << '\n';
  }
  void advance(std::int64_t from, std::int64_t to) { out << "advance " << from << ' ' << to << '\n'; }
  // BinomialSchedule's own visitor interface (binomial strategy).
  void loadWorking() { out << "load ram working\n"; }
  void load(std::int64_t slot) { load(StorageLevel::kRam, slot); }
  void store(std::int64_t slot) { store(StorageLevel::kRam, slot); }
};

}  // namespace

void writeScheduleActions(const std::string& specText, std::int64_t steps, std::int64_t stateBytes,
                          int stages, const ScheduleCosts* costs, std::ostream& out) {
  predictSchedule(specText, steps, stateBytes, stages, costs);  // validates spec, sizes and budgets
  if (steps > TwoLevelPlan::kMaxSimulatedSteps) {
    throw std::invalid_argument("--actions lists every action, for --steps up to " +
                                std::to_string(TwoLevelPlan::kMaxSimulatedSteps) +
                                " (2^24); --steps = " + std::to_string(steps));
  }
  const std::string name = StorageSpec::parse(specText).name();
  PrintingVisitor visitor{out};
  if (name == "full" || name == "disk") {
    const char* level = name == "full" ? "ram" : "disk";
    for (std::int64_t k = 0; k < steps; ++k) out << "record " << k << "\nstore " << level << ' ' << k << '\n';
    for (std::int64_t e = steps - 1; e >= 0; --e)
      out << "restore " << e << "\nload " << level << ' ' << e << '\n';
    return;
  }
  if (name == "binomial") {
    auto storage = createStorage(specText);
    const auto& binomial = dynamic_cast<BinomialCheckpointing&>(*storage);
    const std::int64_t slots = std::min(binomial.checkpoints() + 1, steps);
    BinomialSchedule schedule;
    schedule.reset(steps + 1, slots, true);
    for (std::int64_t k = 0; k < steps; ++k) {
      out << "record " << k << '\n';
      const std::int64_t slot = k == 0 ? 0 : schedule.recordForward(k);
      if (slot >= 0) visitor.store(slot);
    }
    struct Skip {
      void loadWorking() {}
      void load(std::int64_t) {}
      void store(std::int64_t) {}
      void advance(std::int64_t, std::int64_t) {}
    } skip;
    schedule.restoreStep(steps, skip);  // x_N: the schedule's end position, never restored
    for (std::int64_t e = steps - 1; e >= 0; --e) {
      out << "restore " << e << '\n';
      schedule.restoreStep(e, visitor);
    }
    return;
  }
  if (name == "online") {
    throw std::invalid_argument(
        "--actions prints offline plans; online thins its checkpoints during the forward "
        "sweep (print its counts without --actions)");
  }
  if (name == "cams") {
    // Step records of `stages` state units (the state and S - 1 stage states), as predictSchedule counts
    // them; none for one stage.
    auto storage = createStorage(specText);
    if (dynamic_cast<CamsCheckpointing&>(*storage).onlineRequested()) {
      throw std::invalid_argument(
          "--actions prints offline plans; cams with online=1 thins its checkpoints "
          "during the forward sweep (print its counts without --actions)");
    }
    const std::int64_t units = dynamic_cast<CamsCheckpointing&>(*storage).usableUnits(stateBytes, false);
    std::vector<cams::Action> actions;
    const std::int64_t recordUnits = stages > 1 ? stages : std::numeric_limits<std::int32_t>::max();
    cams::simulate(cams::Plan(steps, units, recordUnits), &actions);
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
    return;
  }
  // multilevel (predictSchedule has rejected everything else)
  auto storage = createStorage(specText);
  auto& multilevel = dynamic_cast<MultilevelStorage&>(*storage);
  const ScheduleCosts* planCosts = multilevel.options().costs ? &*multilevel.options().costs : costs;
  const MultilevelStorage::Layout layout = multilevel.layoutFor(steps, static_cast<int>(stateBytes / 8));
  TwoLevelPlan plan = TwoLevelPlan::choose(steps, layout.ramSlots, layout.diskSlots, *planCosts);
  for (std::int64_t k = 0; k < steps; ++k) {
    out << "record " << k << '\n';
    plan.recordForward(k, visitor);
  }
  for (std::int64_t e = steps - 1; e >= 0; --e) {
    out << "restore " << e << '\n';
    plan.restoreStep(e, visitor);
  }
}

}  // namespace hindsight
