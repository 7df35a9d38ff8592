#include <hindsight/engine/binomial_checkpointing.h>

#include <algorithm>
#include <cstring>
#include <ostream>
#include <stdexcept>

namespace hindsight {
namespace revolve {
namespace {

__extension__ typedef __int128 SignedInt128;
constexpr UnsignedInt128 kSaturation = static_cast<UnsignedInt128>(1) << 64;

}  // namespace

UnsignedInt128 beta(std::int64_t c, std::int64_t r) {
  assert(c >= 0);
  if (r < 0) return 0;
  // C(c + r, k) with k = min(c, r): v_i = C(c + r - k + i, i) stays an integer after each division.
  const std::int64_t k = std::min(c, r);
  const UnsignedInt128 top =
      static_cast<UnsignedInt128>(c) + static_cast<UnsignedInt128>(r) - static_cast<UnsignedInt128>(k);
  UnsignedInt128 value = 1;
  for (std::int64_t i = 1; i <= k; ++i) {
    value = value * (top + static_cast<UnsignedInt128>(i)) / static_cast<UnsignedInt128>(i);
    // The remaining factors are >= 1, so a saturated value stays saturated.
    if (value >= kSaturation) return kSaturation;
  }
  return value;
}

std::int64_t repetitionNumber(std::int64_t steps, std::int64_t checkpoints) {
  assert(steps >= 1 && checkpoints >= 1);
  if (steps == 1) return 0;
  if (checkpoints == 1) return steps - 1;  // beta(1, r) = r + 1
  const auto target = static_cast<UnsignedInt128>(steps);
  // Exponential then binary search; beta(c, r) is increasing in r.
  std::int64_t high = 1;
  while (beta(checkpoints, high) < target) high *= 2;
  std::int64_t low = high / 2;  // beta(c, low) < target unless low == 0
  while (high - low > 1) {
    const std::int64_t middle = low + (high - low) / 2;
    if (beta(checkpoints, middle) >= target)
      high = middle;
    else
      low = middle;
  }
  return high;
}

UnsignedInt128 optimalForwardSteps(std::int64_t steps, std::int64_t checkpoints) {
  const std::int64_t r = repetitionNumber(steps, checkpoints);
  if (r == 0) return 0;
  // T = r N - beta(c + 1, r - 1), with beta(c + 1, r - 1) = C(c + r, c + 1) = beta(c, r - 1) (c + r) / (c +
  // 1) evaluated from beta(c, r - 1) < N, so nothing saturates (beta(2, N - 2) ~ N^2 / 2 for c = 1).
  const UnsignedInt128 previous = beta(checkpoints, r - 1);
  const UnsignedInt128 next =
      previous * static_cast<UnsignedInt128>(checkpoints + r) / static_cast<UnsignedInt128>(checkpoints + 1);
  return static_cast<UnsignedInt128>(r) * static_cast<UnsignedInt128>(steps) - next;
}

UnsignedInt128 optimalRecomputedSteps(std::int64_t steps, std::int64_t slots) {
  assert(steps >= 1 && slots >= 1);
  // T(N + 1, S) >= N for N >= 1 (the first sweep), so the difference is a count.
  return optimalForwardSteps(steps + 1, slots) - static_cast<UnsignedInt128>(steps);
}

UnsignedInt128 workingStateRecomputedSteps(std::int64_t steps, std::int64_t slots) {
  assert(steps >= 1 && slots >= 1);
  // T(N, S) >= N - 1 (the first sweep), so the difference is a count.
  return optimalForwardSteps(steps, slots) - static_cast<UnsignedInt128>(steps - 1);
}

std::int64_t binomialSplit(std::int64_t steps, std::int64_t slots) {
  assert(steps >= 2 && slots >= 2);
  const std::int64_t r = repetitionNumber(steps, slots);
  const auto l = static_cast<SignedInt128>(steps);
  const auto b = [](std::int64_t c, std::int64_t rr) { return static_cast<SignedInt128>(beta(c, rr)); };
  // beta(s - 1, r - 1) <= l - m <= beta(s - 1, r) and beta(s, r - 2) <= m <= beta(s, r - 1), 1 <= m < l.
  const SignedInt128 low = std::max({SignedInt128{1}, b(slots, r - 2), l - b(slots - 1, r)});
  const SignedInt128 high = std::min({l - 1, b(slots, r - 1), l - b(slots - 1, r - 1)});
  assert(low <= high);
  (void)low;
  return static_cast<std::int64_t>(high);
}

std::string toString(UnsignedInt128 value) {
  if (value == 0) return "0";
  std::string digits;
  while (value > 0) {
    digits.push_back(static_cast<char>('0' + static_cast<int>(value % 10)));
    value /= 10;
  }
  std::reverse(digits.begin(), digits.end());
  return digits;
}

// The checkpoints BinomialSchedule::reset(length, slots, true) pushes in the first sweep (x_0 not
// counted) and the position of the last one (0 when none). Once the rest fits the free slots
// (l <= free + 2, repetition number 1) every split is 1 and positions top + 1 .. length - 2 are all
// pushed: counted at once, so this takes O(pushes while r >= 2), not O(min(slots, length)).
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
    const std::int64_t target = sweep.top + binomialSplit(length - sweep.top, free + 1);
    if (target >= length - 1) break;
    ++sweep.pushes;
    sweep.top = target;
    --free;
  }
  return sweep;
}

// Checkpoint writes of a whole BinomialSchedule run (reset(length, slots, true): x_0, the first sweep's
// and the backward sweep's stores; the working state not included), simulateSchedule's
// checkpointWrites in closed form. W(l, s), the stores at positions >= 1 while reversing l steps whose
// first state is held, with s slots (the first sweep stores exactly what the restore of l - 1 would),
// follows the schedule's split m = binomialSplit(l, s):
//     W(l, s) = [l - m >= 2] + W(l - m, s - 1) + W(m, s),   W(1, s) = W(l, 1) = 0,
// and W(l, s) = l - 2 when l <= s + 1 (r = 1: every position but the last is stored). On an exact
// binomial length, W(beta(s, r), s) = beta(s - 1, r) - 1 (W + 1 obeys Pascal's rule with ones on the
// border). With r the repetition number of l, binomialSplit takes m = beta(s, r - 1) (the left part
// exact) or m = l - beta(s - 1, r - 1) (the right part exact), so one part is closed form and the
// other continues with s - 1 or with a smaller r: O(s + r) iterations. The tests compare it with
// simulateSchedule.
std::int64_t checkpointWrites(std::int64_t length, std::int64_t slots) {
  const auto exactWrites = [](std::int64_t s, std::int64_t r) {  // W(beta(s, r), s)
    return s <= 1 ? std::int64_t{0} : static_cast<std::int64_t>(beta(s - 1, r)) - 1;
  };
  std::int64_t writes = 1;  // x_0
  std::int64_t l = length, s = slots;
  while (l >= 2 && s >= 2) {
    const std::int64_t r = repetitionNumber(l, s);
    if (r <= 1) {
      writes += l - 2;
      break;
    }
    const std::int64_t m = binomialSplit(l, s);
    if (l - m >= 2) ++writes;
    if (static_cast<UnsignedInt128>(m) == beta(s, r - 1)) {
      writes += exactWrites(s, r - 1);
      l -= m;
      --s;
    } else {
      if (static_cast<UnsignedInt128>(l - m) != beta(s - 1, r - 1))
        throw std::logic_error("checkpointWrites: binomialSplit left no part of binomial length");
      writes += exactWrites(s - 1, r - 1);
      l = m;
    }
  }
  return writes;
}

namespace {

struct CountingVisitor {
  ScheduleCounts& counts;
  BinomialSchedule& schedule;
  void loadWorking() { ++counts.workingStateLoads; }
  void load(std::int64_t) {}
  void advance(std::int64_t from, std::int64_t to) {
    counts.recomputedSteps += static_cast<UnsignedInt128>(to - from);
  }
  void store(std::int64_t) {
    ++counts.checkpointWrites;
    counts.maxCheckpointsHeld = std::max(counts.maxCheckpointsHeld, schedule.held());
  }
};

}  // namespace

ScheduleCounts simulateSchedule(std::int64_t steps, std::int64_t checkpoints) {
  if (steps < 1 || checkpoints < 1) {
    throw std::invalid_argument("simulateSchedule: steps = " + std::to_string(steps) +
                                " and checkpoints = " + std::to_string(checkpoints) + " must be >= 1");
  }
  ScheduleCounts counts;
  BinomialSchedule schedule;
  schedule.reset(steps, checkpoints, true);
  counts.checkpointWrites = 1;
  counts.maxCheckpointsHeld = 1;
  counts.firstSweepSteps = steps - 1;
  for (std::int64_t n = 1; n < steps; ++n) {
    if (schedule.recordForward(n) >= 0) {
      ++counts.checkpointWrites;
      counts.maxCheckpointsHeld = std::max(counts.maxCheckpointsHeld, schedule.held());
    }
  }
  CountingVisitor visitor{counts, schedule};
  for (std::int64_t e = steps - 1; e >= 0; --e) schedule.restoreStep(e, visitor);
  return counts;
}

}  // namespace revolve

// ---- BinomialSchedule ----

void BinomialSchedule::reset(std::int64_t length, std::int64_t slots, bool workingStateHoldsLast) {
  assert(length >= 1 && slots >= 1);
  length_ = length;
  slots_ = slots;
  workingValid_ = workingStateHoldsLast && length >= 2;
  stack_.clear();
  stack_.reserve(static_cast<std::size_t>(std::min<std::int64_t>(slots, length)));
  stack_.push_back(0);
  nextForward_ = workingStateHoldsLast ? nextForwardTarget() : -1;
}

std::int64_t BinomialSchedule::nextForwardTarget() const {
  const std::int64_t top = stack_.back();
  const std::int64_t steps = length_ - top;
  const std::int64_t freeSlots = slots_ - static_cast<std::int64_t>(stack_.size());
  if (steps < 2 || freeSlots == 0) return -1;
  const std::int64_t target = top + revolve::binomialSplit(steps, freeSlots + 1);
  // The state at length - 1 is the working state; a checkpoint there would be redundant.
  return target < length_ - 1 ? target : -1;
}

std::int64_t BinomialSchedule::recordForward(std::int64_t n) {
  assert(n >= 1 && n < length_);
  if (n != nextForward_) return -1;
  stack_.push_back(n);
  nextForward_ = nextForwardTarget();
  return static_cast<std::int64_t>(stack_.size()) - 1;
}

// ---- BinomialCheckpointing ----

BinomialCheckpointing::BinomialCheckpointing(std::int64_t checkpoints, std::int64_t budgetBytes, bool stages)
    : TrajectoryStorage(budgetBytes), checkpoints_(checkpoints), stages_(stages) {
  if (checkpoints < 1 || checkpoints > kMaxCheckpoints) {
    throw std::invalid_argument("binomial.checkpoints = " + std::to_string(checkpoints) +
                                " must be an integer in [1, " + std::to_string(kMaxCheckpoints) + "]");
  }
}

std::int64_t BinomialCheckpointing::slotsFor(std::int64_t steps, std::int64_t checkpoints,
                                             bool workingStateHoldsLast) {
  // One slot per position that can be a checkpoint: 0..N-1, or 0..N-2 when the caller's working state
  // holds x_{N-1} (N = 1 keeps x_0 in its slot all the same).
  const std::int64_t positions = workingStateHoldsLast ? std::max<std::int64_t>(steps - 1, 1) : steps;
  return std::min(checkpoints + 1, positions);
}

std::unique_ptr<TrajectoryStorage> BinomialCheckpointing::create(const StorageSpec& spec) {
  if (!spec.has("checkpoints")) {
    throw std::invalid_argument("binomial.checkpoints is required: an integer in [1, " +
                                std::to_string(kMaxCheckpoints) + "], e.g. binomial:checkpoints=20");
  }
  return std::make_unique<BinomialCheckpointing>(spec.integer("checkpoints", 1, 1, kMaxCheckpoints),
                                                 spec.bytes("budget", kDefaultBudget),
                                                 spec.integer("stages", 0, 0, 1) == 1);
}

std::string BinomialCheckpointing::spec() const {
  std::string text = "binomial:checkpoints=" + std::to_string(checkpoints_);
  if (budgetBytes() != kDefaultBudget) text += ",budget=" + std::to_string(budgetBytes());
  if (stages_) text += ",stages=1";
  return text;
}

void BinomialCheckpointing::releaseAll() {
  if (heldBytes_ > 0) releaseBytes(heldBytes_);
  heldBytes_ = 0;
  slots_.reset();
  recomputedStages_.reset(0);
  slotCount_ = 0;
}

void BinomialCheckpointing::doBegin() {
  // The base class has reset the counters, so whatever a previous run held is no longer charged.
  heldBytes_ = 0;
  releaseAll();
  const std::int64_t steps = info().stepCount;
  if (steps < 1) {
    throw std::invalid_argument(
        "binomial checkpointing needs the number of steps in advance (TrajectoryInfo.stepCount = " +
        std::to_string(steps) +
        ", adaptive steps); use 'online:budget=BYTES' or 'online:checkpoints=C' for adaptive steps");
  }
  // C + 1 slots (the checkpoints and what revolve calls the working state), at most one per position that
  // can be a checkpoint. With the caller's working state holding x_{N-1}: revolve over the positions
  // 0..N-1 with C + 1 slots; without it, revolve over N + 1 positions (see the header).
  working_ = info().workingStateHoldsLast;
  slotCount_ = slotsFor(steps, checkpoints_, working_);
  const std::int64_t states = slotCount_;
  const std::int64_t recordBytes = info().stepDataSize > 0 ? 2 * stepDataBytes() : 0;  // recomputedStages_
  if (recordBytes > budgetBytes() || states > (budgetBytes() - recordBytes) / stateBytes()) {
    throw std::invalid_argument("binomial.checkpoints = " + std::to_string(checkpoints_) + " needs " +
                                std::to_string(states) + " states of " + formatBytes(stateBytes()) +
                                " (the checkpoints and one more slot), more than binomial.budget = " +
                                formatBytes(budgetBytes()) + "; lower the checkpoints or raise the budget");
  }
  const auto n = static_cast<std::size_t>(info().stateSize);
  holdBytes(states * stateBytes() + recordBytes);
  heldBytes_ = states * stateBytes() + recordBytes;
  recomputedStages_.reset(info().stepDataSize);
  slots_.reset(new double[static_cast<std::size_t>(slotCount_) * n]);
  schedule_.reset(planLength(steps, working_), slotCount_, true);
}

namespace {

// binomial's plan, one code for the run (doRecord, doRestore), the prediction's counting run (countPlan)
// and the action stream (writeActions): revolve with the slots, its first sweep the forward sweep, over
// the positions 0..N-1 when the caller's working state holds x_{N-1} (the schedule's loadWorking() is
// then the first restore itself), else over 0..N, where the restore of x_{N-1} first passes x_N, the
// schedule's end position, which is never restored.
std::int64_t planRecordSlot(BinomialSchedule& schedule, std::int64_t step) {
  return step == 0 ? 0 : schedule.recordForward(step);
}
template <typename Visitor>
void planRestore(BinomialSchedule& schedule, std::int64_t steps, bool working, std::int64_t step,
                 Visitor& visitor) {
  if (!working && step == steps - 1) {
    struct Skip {
      void loadWorking() {}
      void load(std::int64_t) {}
      void store(std::int64_t) {}
      void advance(std::int64_t, std::int64_t) {}
    } skip;
    schedule.restoreStep(step + 1, skip);  // x_N: loads the working state, nothing else
  }
  schedule.restoreStep(step, visitor);
}

}  // namespace

void BinomialCheckpointing::doRecord(std::int64_t step, double, ConstVectorRef z, ConstVectorRef) {
  const auto n = static_cast<std::size_t>(info().stateSize);
  const std::int64_t slot = planRecordSlot(schedule_, step);
  if (slot >= 0) {
    std::memcpy(slots_.get() + static_cast<std::size_t>(slot) * n, z.data(), n * sizeof(double));
    ++mutableCounters().statesStored;
  }
}

void BinomialCheckpointing::doFinish(double, ConstVectorRef, ConstVectorRef) {}

void BinomialCheckpointing::doRecordStepData(std::int64_t step, ConstVectorRef data) {
  // Only the last forward step's stages are kept: no restore recomputes the step x_{N-1} -> x_N (x_N is
  // revolve's current state, never asked for), so nothing else would give them.
  if (!recomputedStages_.active() || step != info().stepCount - 1) return;
  recomputedStages_.recordLast(step, data);
  ++mutableCounters().stepDataStored;
}

bool BinomialCheckpointing::doRestoreStepData(std::int64_t step, VectorRef data) {
  const bool restored = recomputedStages_.restore(step, data);
  if (step == 0) releaseAll();  // (restore(0) keeps the records for this call)
  return restored;
}

void BinomialCheckpointing::doRestore(std::int64_t step, VectorRef z) {
  struct Visitor {
    BinomialCheckpointing& self;
    VectorRef z;
    std::size_t n;
    void loadWorking() {}  // x_{N-1}, which z holds already (TrajectoryInfo.workingStateHoldsLast)
    void load(std::int64_t slot) {
      std::memcpy(z.data(), self.slots_.get() + static_cast<std::size_t>(slot) * n, n * sizeof(double));
    }
    void store(std::int64_t slot) {
      std::memcpy(self.slots_.get() + static_cast<std::size_t>(slot) * n, z.data(), n * sizeof(double));
    }
    void advance(std::int64_t from, std::int64_t to) {
      for (std::int64_t k = from; k < to; ++k) self.recompute(k, z);
      if (self.recomputedStages_.active() && to > from) {
        self.recomputedStepData(self.recomputedStages_.pending(to - 1));
        ++self.mutableCounters().stepDataStored;
      }
    }
  } visitor{*this, z, static_cast<std::size_t>(info().stateSize)};
  recomputedStages_.beginRestore(step);
  planRestore(schedule_, info().stepCount, working_, step, visitor);
  if (step == 0 && !recomputedStages_.active()) releaseAll();  // else restoreStepData(0) follows
}

BinomialCheckpointing::PlanCounts BinomialCheckpointing::countPlan(std::int64_t steps, std::int64_t slots,
                                                                   bool keepStages, bool working) {
  // The strategy's own plan (planRecordSlot, planRestore) with a visitor that counts instead of copying
  // states and stepping, and RecomputedStages' rule for stages=1 on one-double "stage values" (only which
  // step they belong to matters), in the order of a run: records 0..N-1 (the stages of the last step
  // recorded, as doRecordStepData), then for e = N-1..0 the restore of e and its step data.
  struct Counting {
    internal::RecomputedStages stages;
    bool keep = false;
    UnsignedInt128 recomputed = 0;
    std::int64_t stores = 0, stepDataStored = 0;
    void loadWorking() {}
    void load(std::int64_t) {}
    void store(std::int64_t) { ++stores; }
    void advance(std::int64_t from, std::int64_t to) {
      recomputed += static_cast<UnsignedInt128>(to - from);
      if (keep && to > from) {
        stages.pending(to - 1);
        ++stepDataStored;
      }
    }
  } counting;
  counting.keep = keepStages;
  counting.stages.reset(keepStages ? 1 : 0);
  Vector data = Vector::Zero(1);
  BinomialSchedule schedule;
  schedule.reset(planLength(steps, working), slots, true);
  PlanCounts counts;
  for (std::int64_t step = 0; step < steps; ++step) {
    if (planRecordSlot(schedule, step) >= 0) ++counts.statesStored;
  }
  if (keepStages) {
    counting.stages.recordLast(steps - 1, data);
    ++counting.stepDataStored;
  }
  for (std::int64_t e = steps - 1; e >= 0; --e) {
    if (keepStages) counting.stages.beginRestore(e);
    planRestore(schedule, steps, working, e, counting);
    if (keepStages && counting.stages.restore(e, data)) ++counts.stepDataRestored;
  }
  counts.recomputedSteps = counting.recomputed;
  counts.ramWrites = counts.statesStored + counting.stores;
  counts.stepDataStored = counting.stepDataStored;
  return counts;
}

BinomialCheckpointing::PlanCounts BinomialCheckpointing::closedFormCounts(std::int64_t steps,
                                                                          std::int64_t slots, bool keepStages,
                                                                          bool working) {
  // revolve's formulas (the header) over L = planLength positions: T(L, S) - (L - 1) recomputed steps
  // (T(N, S) - (N - 1) with the working state, R(N, S) = T(N + 1, S) - N without), the first sweep's
  // pushes and the checkpoint writes of the whole schedule. With stages=1 (RecomputedStages' rule): the
  // adjoint step of e has its stages when e = N - 1 (the forward sweep's last step, never recomputed)
  // or when the restore of e + 1 recomputed (its last step is e -> e + 1). The restores that recompute
  // nothing are those of the checkpoint positions, each stored once and loaded once directly (`writes`
  // of them, x_0 included), and with the working state the restore of x_{N-1}. A restore that
  // recomputes stores stage values after every advance (one more than its checkpoint stores); summed
  // over the backward sweep, with the forward sweep's one record.
  PlanCounts counts;
  const std::int64_t length = planLength(steps, working);
  counts.recomputedSteps =
      revolve::optimalForwardSteps(length, slots) - static_cast<UnsignedInt128>(length - 1);
  const std::int64_t firstPushes = revolve::firstSweep(length, slots).pushes;
  const std::int64_t writes = revolve::checkpointWrites(length, slots);
  counts.statesStored = 1 + firstPushes;
  counts.ramWrites = writes;
  if (keepStages) {
    // Restores that advance: all N but the direct ones (x_0's among them, so each advancing restore is
    // of some e + 1 >= 1 and gives the stages of step e).
    const std::int64_t advancing = steps - writes - (working && steps >= 2 ? 1 : 0);
    counts.stepDataRestored = 1 + advancing;
    counts.stepDataStored = 1 + advancing + (writes - 1 - firstPushes);
  }
  return counts;
}

void BinomialCheckpointing::predict(const TrajectoryStorage& storage, const StorageSpec&,
                                    const PredictionRequest& request, SchedulePrediction& p) {
  // A run of computeGradient, whose working state holds x_{N-1}: revolve with S = slotsFor(N, C, true)
  // slots over the positions 0..N-1, its first sweep the forward sweep (engine/binomial_checkpointing.h).
  const auto& binomial = dynamic_cast<const BinomialCheckpointing&>(storage);
  const std::int64_t steps = request.steps, stateBytes = request.stateBytes;
  const int stages = request.stages;
  const std::int64_t slots = slotsFor(steps, binomial.checkpoints(), true);
  const std::int64_t states = slots;
  // stages=1 (engine/recomputed_stages.h): two step records of an explicit Runge-Kutta method, S - 1
  // stage states and S rhs data each (Integrator::stepDataSize(); none for S = 1), charged like the states.
  const bool keepStages = binomial.stages_ && prediction::hasStageValues(stages);
  const std::int64_t recordBytes =
      keepStages
          ? prediction::checkedProduct(2, prediction::stepRecordBytes(request, "binomial"), "--state-bytes")
          : 0;
  if (recordBytes > binomial.budgetBytes() || states > (binomial.budgetBytes() - recordBytes) / stateBytes) {
    throw std::invalid_argument(
        "binomial.checkpoints = " + std::to_string(binomial.checkpoints()) + " needs " +
        std::to_string(states) + " states of " + formatBytes(stateBytes) +
        (keepStages ? " and two step records of " + formatBytes(recordBytes / 2) : "") +
        ", more than binomial.budget = " + formatBytes(binomial.budgetBytes()));
  }
  // The count first: beyond 2^63 it is refused before the plan is run or walked.
  prediction::checkedCount(revolve::workingStateRecomputedSteps(steps, slots), "recomputed steps");
  // The strategy's own plan run with a counting visitor up to 2^24 steps; beyond, revolve's closed forms,
  // equal to it (tests/storage/binomial_checkpointing_test.cpp compares the two).
  const PlanCounts counts = steps <= prediction::kMaxWalkedSteps
                                ? countPlan(steps, slots, keepStages, true)
                                : closedFormCounts(steps, slots, keepStages, true);
  p.recomputedSteps = prediction::checkedCount(counts.recomputedSteps, "recomputed steps");
  p.plan = "revolve over " + std::to_string(slots) + " slots (positions 0..N-1, x_{N-1} the working state)" +
           (keepStages ? ", stages of the last recomputed step kept" : "");
  p.statesStored = counts.statesStored;
  p.ramReads = steps;
  p.ramWrites = counts.ramWrites;
  if (keepStages) {
    p.stepDataRestored = counts.stepDataRestored;
    p.stepDataStored = counts.stepDataStored;
  }
  p.peakRamBytes = prediction::checkedProduct(states, stateBytes, "--state-bytes") + recordBytes;
}

void BinomialCheckpointing::writeActions(const TrajectoryStorage& storage, const StorageSpec&,
                                         const PredictionRequest& request, std::ostream& out) {
  // The schedule doBegin, doRecord and doRestore run in computeGradient (the working state holds x_{N-1}).
  const auto& binomial = dynamic_cast<const BinomialCheckpointing&>(storage);
  const std::int64_t steps = request.steps;
  const std::int64_t slots = slotsFor(steps, binomial.checkpoints(), true);
  prediction::ActionWriter writer{out};
  BinomialSchedule schedule;
  schedule.reset(planLength(steps, true), slots, true);
  for (std::int64_t k = 0; k < steps; ++k) {
    out << "record " << k << '\n';
    const std::int64_t slot = planRecordSlot(schedule, k);
    if (slot >= 0) writer.store(slot);
  }
  for (std::int64_t e = steps - 1; e >= 0; --e) {
    out << "restore " << e << '\n';
    planRestore(schedule, steps, true, e, writer);
  }
}

}  // namespace hindsight
