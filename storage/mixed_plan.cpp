#include <hindsight/storage/mixed_plan.h>

#include <hindsight/engine/storage_spec.h>

#include <algorithm>
#include <cassert>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

namespace hindsight {

namespace mixed {

Plan::Plan(std::int64_t steps, std::int64_t units) : steps_(steps), units_(std::min(units, steps - 1)) {
  if (steps < 1) throw std::invalid_argument("mixed: steps = " + std::to_string(steps) + " must be >= 1");
  if (steps >= 2 && units < 1) {
    throw std::invalid_argument("mixed.checkpoints = " + std::to_string(units) + " must be in [1, " +
                                std::to_string(MixedPlanStorage::kMaxCheckpoints) + "]");
  }
  const auto n = static_cast<double>(steps);
  if (n * n * static_cast<double>(std::max<std::int64_t>(units_ - 1, 0)) / 2 >
      static_cast<double>(kMaxWork)) {
    throw std::invalid_argument(
        "mixed: the plan's table costs about N^2 (C - 1) / 2 operations, at most " +
        std::to_string(kMaxWork) + " (2^32, a few seconds); N = " + std::to_string(steps) +
        " with C = " + std::to_string(units_) + " units is beyond: use fewer steps or units, or binomial");
  }
  if (static_cast<double>(steps + 1) * static_cast<double>(std::max<std::int64_t>(units_, 1)) >
      static_cast<double>(kMaxCells)) {
    throw std::invalid_argument("mixed: the plan's table has N C cells, at most " +
                                std::to_string(kMaxCells) + " (2^24); N = " + std::to_string(steps) +
                                " with C = " + std::to_string(units_) +
                                " units is beyond: use fewer steps or units, or binomial");
  }
  const std::size_t cells =
      static_cast<std::size_t>(std::max<std::int64_t>(units_, 0)) * static_cast<std::size_t>(steps + 1);
  cost_.assign(cells, 0);
  split_.assign(cells, 0);
  for (std::int64_t s = 1; s <= units_; ++s) {
    std::int64_t* const col = cost_.data() + cell(0, s);
    std::int32_t* const split = split_.data() + cell(0, s);
    const std::int64_t* const prev = s >= 2 ? cost_.data() + cell(0, s - 1) : nullptr;
    for (std::int64_t k = 1; k <= steps; ++k) {
      if (k <= s + 1) {  // every step's adjoint data stored (one step: kept in WORK)
        col[k] = k;
        split[k] = k == 1 ? 0 : 1;
      } else if (s == 1) {  // the state stored, every step replayed from it
        col[k] = k * (k + 1) / 2 - 1;
        split[k] = static_cast<std::int32_t>(k - 1);
      } else {
        // The least i + m(i, s) + m(k - i, s - 1) over 2 <= i < k, then the largest i reaching it.
        std::int64_t best = std::numeric_limits<std::int64_t>::max();
        for (std::int64_t i = 2; i < k; ++i) best = std::min(best, i + col[i] + prev[k - i]);
        std::int64_t at = k - 1;
        while (at + col[at] + prev[k - at] != best) --at;
        if (1 + prev[k - 1] < best) {
          col[k] = 1 + prev[k - 1];
          split[k] = 1;
        } else {
          col[k] = best;
          split[k] = static_cast<std::int32_t>(at);
        }
      }
    }
  }
}

std::size_t Plan::cell(std::int64_t n, std::int64_t s) const {
  return static_cast<std::size_t>(s - 1) * static_cast<std::size_t>(steps_ + 1) + static_cast<std::size_t>(n);
}

std::int64_t Plan::cost(std::int64_t n, std::int64_t s) const {
  assert(n >= 1 && n <= steps_ && (n == 1 || s >= 1));
  if (n == 1) return 1;
  return cost_[cell(n, std::min({s, n - 1, units_}))];
}

Plan::Step Plan::step(std::int64_t n, std::int64_t s) const {
  assert(n >= 1 && n <= steps_ && (n == 1 || s >= 1));
  if (n == 1) return Step{Kind::kForwardReverse, 1};
  const std::int32_t split = split_[cell(n, std::min({s, n - 1, units_}))];
  return split == 1 ? Step{Kind::kAdjointData, 1} : Step{Kind::kState, split};
}

void forEachAction(const Plan& plan, const std::function<void(const CheckpointAction&)>& out) {
  using Kind = CheckpointAction::Kind;
  const std::int64_t steps = plan.steps(), units = plan.units();
  const auto forward = [&out](std::int64_t n0, std::int64_t n1, bool ics, bool adjDeps,
                              CheckpointStorage where) {
    out(CheckpointAction::forward(n0, n1, ics, adjDeps, where));
  };
  // The units held, in the order they were written: each is the first decision of a subproblem still
  // open, so the latest is the one the adjoint reaches next (a stack).
  struct Held {
    Plan::Kind kind;
    std::int64_t step;
  };
  std::vector<Held> held;
  std::int64_t n = 0, reversed = 0;
  for (;;) {
    // Advance to the adjoint, storing as the plan says for the steps left from here.
    while (n < steps - reversed) {
      const bool reuse = !held.empty() && held.back().step == n && held.back().kind == Plan::Kind::kState;
      const std::int64_t free = units - static_cast<std::int64_t>(held.size()) + (reuse ? 1 : 0);
      const Plan::Step first = plan.step(steps - reversed - n, free);
      switch (first.kind) {
        case Plan::Kind::kForwardReverse:
          forward(n, n + 1, false, true, CheckpointStorage::kWork);
          ++n;
          break;
        case Plan::Kind::kAdjointData:
          assert(!reuse);
          forward(n, n + 1, false, true, CheckpointStorage::kRam);
          held.push_back(Held{Plan::Kind::kAdjointData, n});
          ++n;
          break;
        case Plan::Kind::kState:
          if (reuse) {
            forward(n, n + first.advance, false, false, CheckpointStorage::kWork);
          } else {
            forward(n, n + first.advance, true, false, CheckpointStorage::kRam);
            held.push_back(Held{Plan::Kind::kState, n});
          }
          n += first.advance;
          break;
      }
      assert(static_cast<std::int64_t>(held.size()) <= units);
    }
    if (reversed == 0) out(CheckpointAction::marker(Kind::kEndForward));
    out(CheckpointAction::reverseStep(steps - reversed - 1));
    ++reversed;
    if (reversed == steps) break;
    // The latest unit: adjoint data of the step now reversed (used once, released), or a state from which
    // the steps up to the adjoint are replayed (kept while the plan stores it again first).
    assert(!held.empty());
    const Held top = held.back();
    const std::int64_t free = units - static_cast<std::int64_t>(held.size()) + 1;
    const bool keep =
        top.kind == Plan::Kind::kState && plan.step(steps - reversed - top.step, free).kind == top.kind;
    if (!keep) held.pop_back();
    out(CheckpointAction::toWork(top.step, CheckpointStorage::kRam, !keep));
    n = top.kind == Plan::Kind::kState ? top.step : top.step + 1;
  }
  assert(held.empty());
  out(CheckpointAction::marker(Kind::kEndReverse));
}

std::vector<CheckpointAction> actions(const Plan& plan) {
  std::vector<CheckpointAction> out;
  forEachAction(plan, [&out](const CheckpointAction& a) { out.push_back(a); });
  return out;
}

}  // namespace mixed

std::unique_ptr<TrajectoryStorage> MixedPlanStorage::create(const StorageSpec& spec) {
  if (!spec.has("checkpoints")) {
    throw std::invalid_argument("mixed needs checkpoints=C, the units in [1, " +
                                std::to_string(kMaxCheckpoints) + "] (e.g. mixed:checkpoints=11)");
  }
  return std::make_unique<MixedPlanStorage>(spec.integer("checkpoints", 0, 1, kMaxCheckpoints));
}

std::string MixedPlanStorage::spec() const { return "mixed:checkpoints=" + std::to_string(checkpoints_); }

void MixedPlanStorage::doBegin() {
  throw std::invalid_argument(
      "storage mixed is a plan for action streams and predictions (hindsight schedule, "
      "hindsight.checkpoint_schedule): its units hold a state or one step's adjoint data of a state's size, "
      "while a record of the engine is the state plus the step's stage values; use cams:checkpoints=C, the "
      "engine's equivalent (records sized by the integrator's stage data)");
}

void MixedPlanStorage::predict(const TrajectoryStorage& storage, const StorageSpec&,
                               const PredictionRequest& request, SchedulePrediction& p) {
  const auto& self = static_cast<const MixedPlanStorage&>(storage);
  const mixed::Plan plan(request.steps, self.checkpoints());
  // The stream checked and counted as it is made (N up to 2^24 would be gigabytes of actions).
  CheckpointStreamChecker checker(request.steps);
  std::int64_t records = 0, loads = 0, heldUnits = 0, peakUnits = 0;
  mixed::forEachAction(plan, [&](const CheckpointAction& a) {
    checker.take(a);
    if (a.kind == CheckpointAction::Kind::kForward && a.storage == CheckpointStorage::kRam) {
      records += a.writeAdjDeps ? 1 : 0;
      peakUnits = std::max(peakUnits, ++heldUnits);
    } else if (a.kind == CheckpointAction::Kind::kCopy || a.kind == CheckpointAction::Kind::kMove) {
      ++loads;
      heldUnits -= a.kind == CheckpointAction::Kind::kMove ? 1 : 0;
    }
  });
  const CheckpointStreamCounts counts = checker.finish();
  p.plan = "mixed: " + std::to_string(plan.units()) +
           " units of a state or one step's adjoint data (checkpoint_schedules' Mixed, Maddison 2023); " +
           std::to_string(plan.cost(request.steps, plan.units())) + " forward steps in its stream";
  p.recomputedSteps = counts.recomputedSteps;
  p.stepDataStored = records;
  p.stepDataRestored = request.steps - counts.adjointReruns;
  // As cams counts its records (engine/storage_registry.h): ub is the adjoint step given its adjoint data,
  // and the steps reversed without a record re-run their step first.
  p.adjointRecomputations = counts.adjointReruns;
  p.statesStored = counts.ramIcsWrites;
  p.ramWrites = counts.ramIcsWrites + records;
  p.ramReads = loads;
  p.peakRamBytes = peakUnits * request.stateBytes;
}

}  // namespace hindsight
