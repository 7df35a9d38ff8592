#include <hindsight/engine/online_checkpointing.h>

#include <hindsight/engine/interrupt.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace hindsight {

OnlineCheckpointing::OnlineCheckpointing(std::int64_t checkpoints, std::int64_t budgetBytes, bool stages)
    : TrajectoryStorage(budgetBytes), requestedCheckpoints_(checkpoints), stages_(stages) {
  if (checkpoints < 0 || checkpoints > BinomialCheckpointing::kMaxCheckpoints) {
    throw std::invalid_argument("online.checkpoints = " + std::to_string(checkpoints) +
                                " must be an integer in [1, " +
                                std::to_string(BinomialCheckpointing::kMaxCheckpoints) + "]");
  }
}

std::unique_ptr<TrajectoryStorage> OnlineCheckpointing::create(const StorageSpec& spec) {
  const std::int64_t checkpoints = spec.integer("checkpoints", 0, 1, BinomialCheckpointing::kMaxCheckpoints);
  return std::make_unique<OnlineCheckpointing>(checkpoints, spec.bytes("budget", kDefaultBudget),
                                               spec.integer("stages", 0, 0, 1) == 1);
}

std::string OnlineCheckpointing::spec() const {
  std::string text = "online:";
  if (requestedCheckpoints_ > 0) {
    text += "checkpoints=" + std::to_string(requestedCheckpoints_);
    if (budgetBytes() != kDefaultBudget) text += ",budget=" + std::to_string(budgetBytes());
  } else {
    text += "budget=" + std::to_string(budgetBytes());
  }
  if (stages_) text += ",stages=1";
  return text;
}

UnsignedInt128 OnlineCheckpointing::predictedForwardSteps(std::int64_t steps, std::int64_t c,
                                                          bool workingStateHoldsLast) {
  if (steps <= 1) return 0;
  const std::vector<std::int64_t> positions =
      workingStateHoldsLast ? internal::TwoHorizonPlacement::simulate(steps, c, nullptr, nullptr)
                            : internal::CostPlacement::simulate(steps, c, nullptr);
  return forwardStepsOf(positions, steps, c);
}

UnsignedInt128 OnlineCheckpointing::forwardStepsOf(const std::vector<std::int64_t>& positions,
                                                   std::int64_t steps, std::int64_t c) {
  UnsignedInt128 total = static_cast<UnsignedInt128>(steps - 1);
  const auto held = static_cast<std::int64_t>(positions.size());
  for (std::int64_t j = 0; j < held; ++j) {
    const std::int64_t end = j + 1 < held ? positions[static_cast<std::size_t>(j + 1)] : steps - 1;
    // (an interval may be empty: with the caller's working state the last position can be N - 1)
    total += static_cast<UnsignedInt128>(
        internal::intervalForwardSteps(end - positions[static_cast<std::size_t>(j)], c + 1 - j));
  }
  return total;
}

void OnlineCheckpointing::releaseAll() {
  if (heldBytes_ > 0) releaseBytes(heldBytes_);
  heldBytes_ = 0;
  slots_.clear();
  workingCopy_.reset();
  workingValid_ = false;
  recomputedStages_.reset(0);
}

double* OnlineCheckpointing::slot(std::int64_t index) {
  // Without the caller's working state, slot c is the strategy's own copy of x_{N-1}: free for the
  // backward sweep once x_{N-1} is consumed. With it, slots 0..c all hold checkpoints.
  if (!working_ && index == activeCheckpoints_) {
    assert(!workingValid_ && workingCopy_);
    return workingCopy_.get();
  }
  assert(index <= activeCheckpoints_);
  while (static_cast<std::int64_t>(slots_.size()) <= index) slots_.emplace_back();
  auto& memory = slots_[static_cast<std::size_t>(index)];
  if (!memory) {
    holdBytes(stateBytes());
    heldBytes_ += stateBytes();
    memory.reset(new double[static_cast<std::size_t>(info().stateSize)]);
  }
  return memory.get();
}

std::int64_t OnlineCheckpointing::checkpointsFor(std::int64_t stateBytes, std::int64_t recordBytes) const {
  const std::int64_t fitting = (budgetBytes() - recordBytes) / stateBytes - 1;
  const std::int64_t c = requestedCheckpoints_ > 0 ? requestedCheckpoints_ : fitting;
  if (c < 1 || c > fitting) {
    throw std::invalid_argument(
        "online checkpointing needs " +
        (requestedCheckpoints_ > 0 ? "online.checkpoints = " + std::to_string(requestedCheckpoints_)
                                   : std::string("at least one checkpoint")) +
        " plus one working state of " + formatBytes(stateBytes) +
        (recordBytes > 0 ? " and two step records of " + formatBytes(recordBytes / 2) : std::string()) +
        " within online.budget = " + formatBytes(budgetBytes()) + "; raise the budget" +
        (requestedCheckpoints_ > 0 ? " or lower the checkpoints" : ""));
  }
  return std::min(c, BinomialCheckpointing::kMaxCheckpoints);
}

void OnlineCheckpointing::doBegin() {
  heldBytes_ = 0;  // the base class has released what a previous run held
  releaseAll();
  const std::int64_t recordBytes = info().stepDataSize > 0 ? 2 * stepDataBytes() : 0;  // recomputedStages_
  activeCheckpoints_ = checkpointsFor(stateBytes(), recordBytes);
  working_ = info().workingStateHoldsLast;
  // With the caller's working state the c + 1 slots all hold checkpoints (TwoHorizonPlacement); without
  // it one of them is the strategy's own copy of the last recorded state (CostPlacement).
  slots_.reserve(static_cast<std::size_t>(std::min<std::int64_t>(activeCheckpoints_ + 1, 1 << 16)));
  holdBytes(recordBytes);
  heldBytes_ += recordBytes;
  if (working_) {
    twoHorizon_.reset(activeCheckpoints_);
  } else {
    placement_.reset(activeCheckpoints_);
    holdBytes(stateBytes());
    heldBytes_ += stateBytes();
    workingCopy_.reset(new double[static_cast<std::size_t>(info().stateSize)]);
  }
  recomputedStages_.reset(info().stepDataSize);
}

void OnlineCheckpointing::doRecord(std::int64_t step, double, ConstVectorRef z, ConstVectorRef) {
  if (working_) {
    // x_k is stored at once or not: the caller's working state will hold x_{N-1} whatever N is.
    const std::int64_t dropped =
        step == 0 ? internal::TwoHorizonPlacement::kAppended : twoHorizon_.offer(step);
    if (dropped != internal::TwoHorizonPlacement::kSkipped)
      keep(dropped, static_cast<std::int64_t>(twoHorizon_.positions().size()), z.data());
    return;
  }
  // The strategy's copy holds the last recorded state; it becomes a checkpoint candidate only when the
  // next record shows that it was not the last one (so N <= c + 1 states fit without thinning).
  if (workingValid_) commitWorkingState(step);
  std::memcpy(workingCopy_.get(), z.data(), static_cast<std::size_t>(info().stateSize) * sizeof(double));
  workingValid_ = true;
}

void OnlineCheckpointing::commitWorkingState(std::int64_t step) {
  const std::int64_t dropped = placement_.offer(step);
  if (dropped == internal::CostPlacement::kSkipped) return;
  keep(dropped, static_cast<std::int64_t>(placement_.positions().size()), workingCopy_.get());
}

void OnlineCheckpointing::keep(std::int64_t dropped, std::int64_t held, const double* state) {
  if (dropped >= 0) {
    // Slot i holds positions()[i]: the dropped checkpoint's memory moves to the end (pointers only).
    std::rotate(slots_.begin() + dropped, slots_.begin() + dropped + 1, slots_.begin() + held);
  }
  std::memcpy(slot(held - 1), state, static_cast<std::size_t>(info().stateSize) * sizeof(double));
  ++mutableCounters().statesStored;
}

void OnlineCheckpointing::doFinish(double, ConstVectorRef, ConstVectorRef) {
  // Without the caller's working state x_{N-1} is kept in the strategy's copy (binomial counts it alike).
  if (!working_) ++mutableCounters().statesStored;
  // Interval j is reversed with min(c + 1 - j, its length) slots at the most: reserved now, so that the
  // backward sweep allocates nothing (the slots are allocated once c + 1 positions are held, c with the
  // strategy's copy, and shorter placements have intervals of one step, which store nothing).
  const std::vector<std::int64_t>& positions = working_ ? twoHorizon_.positions() : placement_.positions();
  std::int64_t deepest = 1;
  for (std::size_t j = 0; j < positions.size(); ++j) {
    const std::int64_t end = j + 1 < positions.size() ? positions[j + 1] : stepCount() - 1;
    deepest = std::max(deepest,
                       std::min(activeCheckpoints_ + 1 - static_cast<std::int64_t>(j), end - positions[j]));
  }
  reversal_.reserve(deepest);
  reversal_.reset(&positions, stepCount(), activeCheckpoints_);  // N - 1: the working state
}

void OnlineCheckpointing::doRecordStepData(std::int64_t step, ConstVectorRef data) {
  // N is unknown while recording: every step's stages replace the last ones, so the final step's
  // (its state is restored from the working state, without recomputation) are held at the end.
  if (!recomputedStages_.active()) return;
  recomputedStages_.recordLast(step, data);
}

bool OnlineCheckpointing::doRestoreStepData(std::int64_t step, VectorRef data) {
  const bool restored = recomputedStages_.restore(step, data);
  if (step == 0) releaseAll();  // (restore(0) keeps the records for this call)
  return restored;
}

void OnlineCheckpointing::doRestore(std::int64_t step, VectorRef z) {
  const auto bytes = static_cast<std::size_t>(info().stateSize) * sizeof(double);
  if (step == stepCount() - 1) {
    // x_{N-1}: z holds it already (the caller's working state), or the strategy's copy does.
    if (!working_) {
      std::memcpy(z.data(), workingCopy_.get(), bytes);
      workingValid_ = false;  // its memory is now slot c of the intervals' reversal (slot())
    }
    if (step == 0 && !recomputedStages_.active()) releaseAll();  // else restoreStepData(0) follows
    return;
  }
  const internal::OnlinePlacement::Interval& interval = reversal_.enter(step);
  struct Visitor {
    OnlineCheckpointing& self;
    VectorRef z;
    std::size_t bytes;
    std::int64_t offset;
    std::int64_t slotOffset;
    void loadWorking() { assert(false); }
    void load(std::int64_t slot) { std::memcpy(z.data(), self.slot(slot + slotOffset), bytes); }
    void store(std::int64_t slot) { std::memcpy(self.slot(slot + slotOffset), z.data(), bytes); }
    void advance(std::int64_t from, std::int64_t to) {
      for (std::int64_t k = from; k < to; ++k) self.recompute(offset + k, z);
      if (self.recomputedStages_.active() && to > from) {
        self.recomputedStepData(self.recomputedStages_.pending(offset + to - 1));
        ++self.mutableCounters().stepDataStored;
      }
    }
  } visitor{*this, z, bytes, interval.start, interval.index};
  recomputedStages_.beginRestore(step);
  reversal_.restoreStep(step, visitor);
  if (step == 0 && !recomputedStages_.active()) releaseAll();  // else restoreStepData(0) follows
}

void OnlineCheckpointing::predict(const TrajectoryStorage& storage, const StorageSpec&,
                                  const PredictionRequest& request, SchedulePrediction& p) {
  // OnlineCheckpointing for N fixed steps in a run of computeGradient (the caller's working state holds
  // x_{N-1}): its placement (internal::TwoHorizonPlacement), then each interval j reversed by
  // BinomialSchedule with c + 1 - j slots; recomputed steps in closed form
  // (predictedForwardSteps, tested against runs), the rest by running the schedules without states.
  const auto& online = dynamic_cast<const OnlineCheckpointing&>(storage);
  const std::int64_t steps = request.steps, stateBytes = request.stateBytes;
  const int stages = request.stages;

  if (steps > prediction::kMaxWalkedSteps) {
    throw std::invalid_argument(
        "online is predicted up to --steps = " + std::to_string(prediction::kMaxWalkedSteps) +
        " (2^24; its placement is simulated step by step); --steps = " + std::to_string(steps));
  }
  const bool keepStages = online.keepsStages() && stages > 1;
  // Two step records (engine/recomputed_stages.h): S - 1 stage states and S rhs data each.
  const std::int64_t recordBytes =
      keepStages ? prediction::checkedProduct(2, prediction::stepRecordBytes(request, "online"),
                                              "online: bytes of two step records")
                 : 0;
  const std::int64_t c = online.checkpointsFor(stateBytes, recordBytes);
  std::int64_t forwardStores = 0, peakSlots = 0;
  const std::vector<std::int64_t> positions =
      internal::TwoHorizonPlacement::simulate(steps, c, &forwardStores, &peakSlots);
  p.plan = "online placement (" + std::to_string(positions.size()) + " held), revolve per interval, " +
           std::to_string(c + 1) + " slots (x_{N-1} the working state)" +
           (keepStages ? ", stages of the last recomputed step kept" : "");
  p.recomputedSteps = prediction::checkedCount(
      OnlineCheckpointing::forwardStepsOf(positions, steps, c) - static_cast<UnsignedInt128>(steps - 1),
      "recomputed steps");
  if (steps >= 2) {
    // The ratio the guarantee is stated in (docs/guides/storage_strategies.md, "online"), computed for this
    // N: against binomial with the same slots, the optimum had N been known.
    const UnsignedInt128 optimum = internal::binomialAtSameMemory(steps, c);
    const long double twice = 2.0L * static_cast<long double>(steps);
    char ratio[32];
    std::snprintf(
        ratio, sizeof ratio, "%.4Lf",
        (twice + static_cast<long double>(p.recomputedSteps)) / (twice + static_cast<long double>(optimum)));
    p.plan += "; binomial with N known recomputes " + revolve::toString(optimum) +
              ", work ratio (2N + recomputed) / (2N + binomial's) = " + ratio;
  }
  p.statesStored = forwardStores;  // x_0 included; x_{N-1} is the caller's working state
  p.ramReads = steps;
  // Slots are allocated on first use and kept; the backward sweep uses no slot the forward sweep left
  // unused (it fills all c + 1 before N exceeds c + 1, and intervals of one step store nothing).
  p.peakRamBytes = prediction::checkedCount(
      static_cast<UnsignedInt128>(peakSlots) * static_cast<UnsignedInt128>(stateBytes) +
          static_cast<UnsignedInt128>(recordBytes),
      "peak RAM bytes");
  p.ramWrites = -1;
  if (keepStages && steps > prediction::kMaxWalkedSteps) {
    throw std::invalid_argument("online.stages = 1 is predicted up to " +
                                std::to_string(prediction::kMaxWalkedSteps) +
                                " steps (its served adjoint steps are counted by running the schedules); "
                                "--steps = " +
                                std::to_string(steps));
  }
  if (steps <= prediction::kMaxWalkedSteps) {
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
    internal::OnlineReversal reversal;  // the strategy's own backward sweep, with a counting visitor
    reversal.reset(&positions, steps, c);
    for (std::int64_t e = steps - 2; e >= 0; --e) {
      if ((e & 0xffff) == 0) pollInterrupt();  // up to 2^24 steps (engine/interrupt.h)
      sim.offset = reversal.enter(e).start;
      if (keepStages) sim.stages.beginRestore(e);
      reversal.restoreStep(e, sim);
      if (keepStages && sim.stages.restore(e, data)) ++served;
    }
    p.ramWrites = forwardStores + sim.stores;
    if (keepStages) {
      p.stepDataStored = sim.stepDataStored;
      p.stepDataRestored = served;
    }
  }
}

}  // namespace hindsight
