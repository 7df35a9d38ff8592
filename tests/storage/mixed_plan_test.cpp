// `mixed` (storage/mixed_plan.h): the plan's table against a reference written here from Maddison's
// recurrence (a memoized recursion over every first decision), checkpoint_schedules' figures, and its
// action stream: valid under the contract, as many Forward steps as the plan says, at most C units held.
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/storage/checkpoint_actions.h>
#include <hindsight/storage/checkpoint_stream.h>
#include <hindsight/storage/mixed_plan.h>
#include <hindsight/storage/schedule.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <utility>

namespace hindsight {
namespace {

// m(n, s): the least Forward steps reversing n steps from the state at hand with s units, each unit a
// state (restartable) or one step's adjoint data; every first decision tried.
std::int64_t referenceCost(std::int64_t n, std::int64_t s,
                           std::map<std::pair<std::int64_t, std::int64_t>, std::int64_t>& memo) {
  if (n == 1) return 1;    // advance with the adjoint data to WORK, reverse
  s = std::min(s, n - 1);  // more units than steps to store buy nothing
  const auto key = std::make_pair(n, s);
  if (const auto it = memo.find(key); it != memo.end()) return it->second;
  // The first step's adjoint data in a unit: one step, then the rest with a unit less.
  // (With one unit, only when one step is left after it.)
  std::int64_t best = s >= 2 || n == 2 ? 1 + referenceCost(n - 1, s - 1, memo) : std::int64_t{1} << 62;
  // The state in a unit, advanced i steps: the right part with s - 1 units, then the left from the state.
  if (s >= 1) {
    for (std::int64_t i = 2; i < n; ++i) {
      if (s == 1 && n - i > 1) continue;  // the right part needs a unit unless it is one step
      const std::int64_t right = n - i == 1 ? 1 : referenceCost(n - i, s - 1, memo);
      best = std::min(best, i + referenceCost(i, s, memo) + right);
    }
  }
  memo[key] = best;
  return best;
}

std::int64_t forwardStepsOf(const std::vector<CheckpointAction>& actions) {
  std::int64_t steps = 0;
  for (const CheckpointAction& a : actions)
    if (a.kind == CheckpointAction::Kind::kForward) steps += a.n1 - a.n0;
  return steps;
}

TEST(MixedPlan, TableEqualsTheRecurrenceForEveryFirstDecision) {
  std::map<std::pair<std::int64_t, std::int64_t>, std::int64_t> memo;
  const std::int64_t N = 90;
  for (std::int64_t units = 1; units <= 14; ++units) {
    const mixed::Plan plan(N, units);
    for (std::int64_t n = 2; n <= N; ++n) {
      for (std::int64_t s = 1; s <= std::min(units, n - 1); ++s) {
        ASSERT_EQ(plan.cost(n, s), referenceCost(n, s, memo)) << "n = " << n << ", s = " << s;
      }
    }
  }
  // The closed forms: n steps with n - 1 units store every step's adjoint data; one unit replays.
  const mixed::Plan plan(40, 39);
  for (std::int64_t n = 1; n <= 40; ++n) EXPECT_EQ(plan.cost(n, n - 1 > 0 ? n - 1 : 1), n);
  for (std::int64_t n = 2; n <= 40; ++n) EXPECT_EQ(plan.cost(n, 1), n * (n + 1) / 2 - 1);
}

TEST(MixedPlan, CheckpointSchedulesFiguresAgainstRevolve) {
  // checkpoint_schedules' recurrence (mixed.py, optimal_steps_mixed) at N = 1000 with 11 units and
  // N = 10^4 with 51: 3 730 and 28 850 Forward steps; revolve's stream with as many snapshots (binomial's
  // with C - 1 checkpoints: T(N, C) + N) 4 545 and 38 569.
  const mixed::Plan small(1000, 11), large(10000, 51);
  EXPECT_EQ(small.cost(1000, 11), 3730);
  EXPECT_EQ(large.cost(10000, 51), 28850);
  EXPECT_EQ(static_cast<std::int64_t>(revolve::optimalForwardSteps(1000, 11)) + 1000, 4545);
  EXPECT_EQ(static_cast<std::int64_t>(revolve::optimalForwardSteps(10000, 51)) + 10000, 38569);
  EXPECT_EQ(forwardStepsOf(checkpointSchedule("binomial:checkpoints=10", 1000, 8, 1, nullptr)), 4545);
  const std::vector<CheckpointAction> stream =
      checkpointSchedule("mixed:checkpoints=11", 1000, 8, 1, nullptr);
  EXPECT_EQ(forwardStepsOf(stream), 3730);
}

TEST(MixedPlan, StreamKeepsTheContractAndCostsWhatThePlanSays) {
  for (std::int64_t units : {1, 2, 3, 5, 11}) {
    for (std::int64_t steps = 1; steps <= 60; ++steps) {
      SCOPED_TRACE("C = " + std::to_string(units) + ", N = " + std::to_string(steps));
      const mixed::Plan plan(steps, units);
      const std::vector<CheckpointAction> actions = mixed::actions(plan);
      const CheckpointStreamCounts counts = checkCheckpointStream(actions, steps);  // throws on a breach
      const std::int64_t cost = plan.cost(steps, std::max<std::int64_t>(1, std::min(units, steps - 1)));
      EXPECT_EQ(forwardStepsOf(actions), cost);
      EXPECT_EQ(counts.forwardSteps + counts.recomputedSteps + counts.adjointReruns - 1, cost);
      // Units held at once: restart states and adjoint data in RAM.
      std::int64_t held = 0, peak = 0;
      for (const CheckpointAction& a : actions) {
        if (a.kind == CheckpointAction::Kind::kForward && a.storage == CheckpointStorage::kRam) ++held;
        if (a.kind == CheckpointAction::Kind::kMove) --held;
        peak = std::max(peak, held);
      }
      EXPECT_LE(peak, units);
      // The prediction counts the same stream.
      const SchedulePrediction p =
          predictSchedule("mixed:checkpoints=" + std::to_string(units), steps, 16, 1, nullptr);
      EXPECT_EQ(p.recomputedSteps, counts.recomputedSteps);
      EXPECT_EQ(p.stepDataRestored, steps - counts.adjointReruns);
      EXPECT_EQ(p.peakRamBytes, 16 * peak);
      EXPECT_EQ(p.rhsEvaluations, cost + 1);  // one rhs per Forward step, the forward's last counted twice
    }
  }
}

TEST(MixedPlan, StreamStateAndRefusals) {
  auto stream = openCheckpointStream("mixed:checkpoints=4", 30, 8, 1, nullptr);
  CheckpointAction action;
  std::int64_t actions = 0;
  while (stream->next(&action)) ++actions;
  EXPECT_TRUE(stream->isExhausted());
  EXPECT_EQ(stream->r(), 30);
  EXPECT_GT(actions, 30);
  EXPECT_THROW(openCheckpointStream("mixed", 30, 8, 1, nullptr), std::invalid_argument);
  EXPECT_THROW(openCheckpointStream("mixed:checkpoints=0", 30, 8, 1, nullptr), std::invalid_argument);
  try {
    predictSchedule("mixed:checkpoints=2", 200000, 8, 1, nullptr);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("2^32"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hindsight
