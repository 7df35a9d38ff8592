// The checkpoint_schedules action stream (storage/checkpoint_actions.h): valid for every fixed-step
// strategy on a grid of N and budgets (a host that tracks which step each piece of data belongs to
// executes it), and it recomputes what the strategy's own prediction says.
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/cams_checkpointing.h>
#include <hindsight/storage/checkpoint_actions.h>
#include <hindsight/storage/checkpoint_stream.h>
#include <hindsight/storage/storage_factory.h>

#include "support/storage_fixtures.h"

#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace {

using testing::ScratchDirectory;

TEST(CheckpointActions, EveryFixedStepStrategyGivesAValidStreamWithItsPredictedRecomputation) {
  ScratchDirectory dir;
  const ScheduleCosts costs{1.0, 1.0, 0.5, 0.5};
  const std::vector<std::string> specs = {
      "full",
      "disk:dir=" + dir.path(),
      "binomial:checkpoints=1",
      "binomial:checkpoints=2",
      "binomial:checkpoints=5",
      "cams:checkpoints=1",
      "cams:checkpoints=3",
      "cams:checkpoints=8",
      "multilevel:ram=48,disk=1MiB,costs=1:1:0.5:0.5,dir=" + dir.path(),  // 3 RAM states, cheap disk
      "multilevel:ram=48,disk=64,costs=1:1:0:0,dir=" + dir.path(),        // 3 + 4 slots, free disk
      "multilevel:ram=96,disk=1MiB,costs=1:1:100:100,dir=" + dir.path(),  // dear disk: RAM only
  };
  for (const std::string& spec : specs) {
    for (int stages : {1, 4}) {
      for (std::int64_t steps : {1, 2, 3, 4, 7, 10, 31, 100, 257}) {
        SCOPED_TRACE(spec + ", N = " + std::to_string(steps) + ", stages " + std::to_string(stages));
        std::vector<CheckpointAction> actions;
        try {
          actions = checkpointSchedule(spec, steps, 16, stages, &costs);
        } catch (const std::invalid_argument& e) {
          // Only the plan's own refusals (too few slots for N steps).
          EXPECT_NE(std::string(e.what()).find("multilevel"), std::string::npos) << e.what();
          continue;
        }
        const CheckpointStreamCounts c = checkCheckpointStream(actions, steps);
        const SchedulePrediction p = predictSchedule(spec, steps, 16, stages, &costs);
        EXPECT_EQ(c.forwardSteps, steps);
        EXPECT_EQ(c.recomputedSteps, p.recomputedSteps);
        if (spec.rfind("cams", 0) == 0) {
          EXPECT_EQ(c.adjointReruns, p.adjointRecomputations);
        } else {
          EXPECT_EQ(c.adjointReruns, steps);
        }
        if (spec.rfind("multilevel", 0) == 0) EXPECT_EQ(c.diskIcsWrites, p.diskWrites);
        if (spec.rfind("binomial", 0) == 0) {
          // revolve over the C + 1 slots binomial holds: never more restart states at once.
          const std::int64_t checkpoints = std::stoll(spec.substr(spec.find('=') + 1));
          EXPECT_LE(c.peakRamCheckpoints, checkpoints + 1);
        }
        if (spec == "full") EXPECT_EQ(c.peakRamCheckpoints, steps - 1);  // x_{N-1} lives in WORK
      }
    }
  }
}

TEST(CheckpointActions, TextIsCheckpointSchedulesRepr) {
  const std::vector<CheckpointAction> actions =
      checkpointSchedule("binomial:checkpoints=1", 3, 16, 1, nullptr);
  std::string text;
  for (const CheckpointAction& a : actions) text += a.text() + "\n";
  // C + 1 = 2 slots over x_0, x_1 (x_2 is WORK when the forward run ends): nothing recomputed. The same
  // actions as checkpoint_schedules' MultistageCheckpointSchedule(3, 2, 0) (read from its multistage.py).
  EXPECT_EQ(text,
            "Forward(0, 1, True, False, StorageType.RAM)\n"
            "Forward(1, 2, True, False, StorageType.RAM)\n"
            "Forward(2, 3, False, True, StorageType.WORK)\n"
            "EndForward()\n"
            "Reverse(3, 2, True)\n"
            "Move(1, StorageType.RAM, StorageType.WORK)\n"
            "Forward(1, 2, False, True, StorageType.WORK)\n"
            "Reverse(2, 1, True)\n"
            "Move(0, StorageType.RAM, StorageType.WORK)\n"
            "Forward(0, 1, False, True, StorageType.WORK)\n"
            "Reverse(1, 0, True)\n"
            "EndReverse()\n");
}

// binomial's stream is revolve with C + 1 snapshots, as checkpoint_schedules' MultistageCheckpointSchedule
// counts it: x_{N-1}'s adjoint data comes from the forward run's last step (WORK), so N = 10, C = 2 takes
// 9 + 1 forward steps, 6 recomputed and 9 re-runs (25 in all, T(10, 3) + 10), and N = 1000, C = 2
// recomputes 11 156 = T(1000, 3) - 999 steps; never more than C + 1 restart states in RAM.
TEST(CheckpointActions, BinomialStreamIsRevolveWithOneSnapshotPerSlot) {
  for (const std::int64_t steps : {10, 1000, 4097}) {
    for (const std::int64_t c : {1, 2, 5, 20}) {
      const CheckpointStreamCounts counts = checkCheckpointStream(
          checkpointSchedule("binomial:checkpoints=" + std::to_string(c), steps, 16, 1, nullptr), steps);
      const std::int64_t snapshots = std::min(c + 1, steps);
      EXPECT_EQ(std::to_string(counts.recomputedSteps),
                revolve::toString(revolve::optimalForwardSteps(steps, snapshots) -
                                  static_cast<UnsignedInt128>(steps - 1)))
          << "N = " << steps << ", C = " << c;
      EXPECT_EQ(std::to_string(counts.forwardSteps + counts.recomputedSteps + counts.adjointReruns - 1),
                revolve::toString(revolve::optimalForwardSteps(steps, snapshots) +
                                  static_cast<UnsignedInt128>(steps)))
          << "N = " << steps << ", C = " << c;
      EXPECT_LE(counts.peakRamCheckpoints, c + 1);
    }
  }
  const std::vector<CheckpointAction> small =
      checkpointSchedule("binomial:checkpoints=2", 10, 16, 1, nullptr);
  const CheckpointStreamCounts counts = checkCheckpointStream(small, 10);
  EXPECT_EQ(counts.recomputedSteps, 6);
  EXPECT_EQ(counts.forwardSteps + counts.recomputedSteps + counts.adjointReruns - 1, 25);
  EXPECT_EQ(checkCheckpointStream(checkpointSchedule("binomial:checkpoints=2", 1000, 16, 1, nullptr), 1000)
                .recomputedSteps,
            11156);
}

// binomial's stream drives the run's own BinomialSchedule as the host consumes it: at N = 2^40 its first
// actions come without the plan being laid out, and it never holds more than the C + 1 slots.
TEST(CheckpointActions, BinomialStreamIsMadeAsItIsConsumed) {
  const std::int64_t steps = std::int64_t{1} << 40;
  const std::unique_ptr<CheckpointStream> stream =
      openCheckpointStream("binomial:checkpoints=20", steps, 16, 4, nullptr);
  EXPECT_EQ(stream->maxN(), steps);
  CheckpointAction a;
  std::int64_t at = 0;
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(stream->next(&a));
    ASSERT_EQ(a.kind, CheckpointAction::Kind::kForward) << a.text();
    EXPECT_EQ(a.n0, at);
    EXPECT_TRUE(a.writeIcs && a.storage == CheckpointStorage::kRam) << a.text();
    at = a.n1;
    EXPECT_EQ(stream->n(), at);
    EXPECT_LE(stream->heldCheckpoints(), 21);
  }
  EXPECT_LT(at, steps);
  EXPECT_EQ(stream->r(), 0);
  EXPECT_FALSE(stream->isExhausted());
}

// multilevel's stream drives its TwoLevelPlan as the host consumes it: at N = 10^8 (beyond the 2^24 a
// whole translation allowed) the leaves plan's first actions come without the plan being laid out, and the
// host never holds more than the plan's slots.
TEST(CheckpointActions, MultilevelStreamIsMadeAsItIsConsumed) {
  ScratchDirectory dir;
  const std::int64_t steps = 100'000'000;
  const std::string spec = "multilevel:ram=160,disk=1MiB,costs=1:1:0.5:0.5,dir=" + dir.path();
  const std::unique_ptr<CheckpointStream> stream = openCheckpointStream(spec, steps, 16, 4, nullptr);
  EXPECT_EQ(stream->maxN(), steps);
  CheckpointAction a;
  std::int64_t at = 0;
  for (int i = 0; i < 1000; ++i) {
    ASSERT_TRUE(stream->next(&a));
    ASSERT_EQ(a.kind, CheckpointAction::Kind::kForward) << a.text();
    EXPECT_EQ(a.n0, at);
    EXPECT_TRUE(a.writeIcs && a.storage == CheckpointStorage::kDisk) << a.text();  // the leaves' starts
    at = a.n1;
  }
  EXPECT_LE(stream->heldCheckpoints(), 1000);
  EXPECT_LT(at, steps);
  // schedule=stride has no plan of slots to stream.
  EXPECT_THROW(openCheckpointStream(spec + ",schedule=stride", 100, 16, 4, nullptr), std::invalid_argument);
}

// full and disk without N: the forward run goes on step by step until the host calls finalize(n); the
// stream is then the contract's for N = n. Other strategies need N.
TEST(CheckpointActions, FullAndDiskStreamsWithoutNEndWhereTheHostFinalizes) {
  for (const std::string spec : {"full", "disk:dir=unused"}) {
    for (std::int64_t steps : {1, 2, 9}) {
      const std::unique_ptr<CheckpointStream> stream =
          openCheckpointStream(spec, kUnknownSteps, 16, 4, nullptr);
      EXPECT_EQ(stream->maxN(), -1);
      std::vector<CheckpointAction> actions;
      CheckpointAction a;
      while (stream->next(&a)) {
        actions.push_back(a);
        if (a.kind == CheckpointAction::Kind::kForward && stream->maxN() < 0 && a.n1 == steps)
          stream->finalize(steps);
      }
      EXPECT_EQ(stream->maxN(), steps);
      const CheckpointStreamCounts c = checkCheckpointStream(actions, steps);
      EXPECT_EQ(c.recomputedSteps, 0) << spec;
      EXPECT_EQ(c.adjointReruns, steps) << spec;
      if (steps >= 2) EXPECT_THROW(stream->finalize(steps), std::logic_error);  // the forward is at 1
    }
  }
  const std::unique_ptr<CheckpointStream> full = openCheckpointStream("full", kUnknownSteps, 16, 4, nullptr);
  EXPECT_THROW(full->finalize(1), std::logic_error);  // the forward is at step 0
  EXPECT_THROW(openCheckpointStream("binomial:checkpoints=3", kUnknownSteps, 16, 4, nullptr),
               std::invalid_argument);
}

// online without N keeps states as checkpoints (RestartData::kState): the host finalizes at N inside a
// Forward (its prefix is the same for every N, so N = 1..300 finalizes at every step of every Forward up
// there), the relaxed contract holds, at most c + 1 checkpoints are held, and the stream recomputes what
// online's prediction for N + 1 steps counts (the host's WORK holds x_N as an engine run of N + 1 steps
// holds its working state).
CheckpointStreamCounts runOnlineWithoutN(const std::string& spec, std::int64_t checkpoints,
                                         std::int64_t steps, std::vector<CheckpointAction>* actions,
                                         std::int64_t maxForward = 0) {
  const std::unique_ptr<CheckpointStream> stream =
      maxForward > 0 ? openOnlineStateStream(kUnknownSteps, checkpoints, maxForward)
                     : openCheckpointStream(spec, kUnknownSteps, 16, 4, nullptr);
  EXPECT_EQ(stream->restartData(), RestartData::kState);
  CheckpointStreamChecker checker(steps, RestartData::kState);
  CheckpointAction a;
  std::int64_t mostHeld = 0;
  while (stream->next(&a)) {
    if (a.kind == CheckpointAction::Kind::kForward && stream->maxN() < 0 && a.n1 >= steps) {
      a.n1 = steps;  // the host stops there
      stream->finalize(steps);
      EXPECT_EQ(stream->n(), steps);
    }
    checker.take(a);
    if (actions != nullptr) actions->push_back(a);
    mostHeld = std::max(mostHeld, stream->heldCheckpoints());
  }
  EXPECT_LE(mostHeld, checkpoints + 1);
  EXPECT_EQ(stream->heldCheckpoints(), 0);
  return checker.finish();
}

TEST(CheckpointActions, OnlineStreamWithoutNRecomputesThePredictionOfOneStepMore) {
  std::mt19937_64 rng(11);
  std::vector<std::pair<std::int64_t, std::int64_t>> cases;
  for (const std::int64_t c : {1, 2, 3, 5, 10})
    for (std::int64_t steps = 1; steps <= 300; ++steps) cases.emplace_back(c, steps);
  for (int trial = 0; trial < 40; ++trial)
    cases.emplace_back(std::uniform_int_distribution<std::int64_t>(1, 40)(rng),
                       std::uniform_int_distribution<std::int64_t>(1, 5000)(rng));
  bool intervalRuleBroken = false;
  for (const auto& [c, steps] : cases) {
    SCOPED_TRACE("c = " + std::to_string(c) + ", N = " + std::to_string(steps));
    std::vector<CheckpointAction> actions;
    const std::string spec = "online:checkpoints=" + std::to_string(c);
    const CheckpointStreamCounts counts = runOnlineWithoutN(spec, c, steps, &actions);
    const SchedulePrediction p = predictSchedule(spec, steps + 1, 16, 4, nullptr);
    EXPECT_EQ(counts.recomputedSteps, p.recomputedSteps);
    EXPECT_EQ(counts.forwardSteps, steps);
    EXPECT_EQ(counts.adjointReruns, steps);  // x_N's step is re-run from x_{N-1} like every other
    EXPECT_LE(counts.peakRamCheckpoints, c + 1);
    // checkpoint_schedules' own rule 1 refuses these streams once a checkpoint is dropped.
    try {
      checkCheckpointStream(actions, steps);
    } catch (const std::logic_error&) {
      intervalRuleBroken = true;
    }
  }
  EXPECT_TRUE(intervalRuleBroken);
  // Forwards cut short of the next store (the cap, 2^20 steps in the stream a host opens) start from a
  // state that is not stored: the same placement and count.
  for (const std::int64_t c : {1, 2, 5})
    for (std::int64_t steps = 1; steps <= 120; ++steps)
      for (const std::int64_t cap : {1, 2, 3}) {
        SCOPED_TRACE("c = " + std::to_string(c) + ", N = " + std::to_string(steps) + ", cap " +
                     std::to_string(cap));
        std::vector<CheckpointAction> actions;
        const CheckpointStreamCounts counts = runOnlineWithoutN("", c, steps, &actions, cap);
        EXPECT_EQ(counts.recomputedSteps,
                  predictSchedule("online:checkpoints=" + std::to_string(c), steps + 1, 16, 4, nullptr)
                      .recomputedSteps);
        for (const CheckpointAction& a : actions) {
          if (a.kind == CheckpointAction::Kind::kEndForward) break;
          if (a.kind == CheckpointAction::Kind::kForward) EXPECT_LE(a.n1 - a.n0, cap) << a.text();
        }
      }
}

// online with N known: the stream of a run of N steps (the records 1 .. N - 1 offered, x_{N-1} the
// working state), so it recomputes exactly online's prediction for N, holds at most c + 1 states and keeps
// the relaxed contract; forwards cut short by a cap give the same count.
TEST(CheckpointActions, OnlineStreamWithNRecomputesItsPrediction) {
  std::mt19937_64 rng(13);
  std::vector<std::array<std::int64_t, 3>> cases;  // c, N, cap (0: the stream a host opens)
  for (const std::int64_t c : {1, 2, 3, 5, 10})
    for (std::int64_t steps = 1; steps <= 200; ++steps) cases.push_back({c, steps, 0});
  for (int trial = 0; trial < 40; ++trial)
    cases.push_back({std::uniform_int_distribution<std::int64_t>(1, 40)(rng),
                     std::uniform_int_distribution<std::int64_t>(1, 5000)(rng),
                     std::uniform_int_distribution<std::int64_t>(0, 3)(rng)});
  for (const auto& [c, steps, cap] : cases) {
    SCOPED_TRACE("c = " + std::to_string(c) + ", N = " + std::to_string(steps) + ", cap " +
                 std::to_string(cap));
    const std::string spec = "online:checkpoints=" + std::to_string(c);
    const std::unique_ptr<CheckpointStream> stream =
        cap > 0 ? openOnlineStateStream(steps, c, cap) : openCheckpointStream(spec, steps, 16, 4, nullptr);
    EXPECT_EQ(stream->restartData(), RestartData::kState);
    CheckpointStreamChecker checker(steps, RestartData::kState);
    CheckpointAction a;
    std::int64_t mostHeld = 0;
    while (stream->next(&a)) {
      if (cap > 0 && a.kind == CheckpointAction::Kind::kForward && stream->r() == 0)
        EXPECT_LE(a.n1 - a.n0, cap) << a.text();
      checker.take(a);
      mostHeld = std::max(mostHeld, stream->heldCheckpoints());
    }
    const CheckpointStreamCounts counts = checker.finish();
    EXPECT_EQ(counts.recomputedSteps, predictSchedule(spec, steps, 16, 4, nullptr).recomputedSteps);
    EXPECT_EQ(counts.forwardSteps, steps);
    EXPECT_LE(mostHeld, c + 1);
    EXPECT_EQ(stream->heldCheckpoints(), 0);
    // For a host of checkpoint_schedules' contract: the placement walked first, only the checkpoints held at
    // the end written; checkpoint_schedules' strict rule 1 holds and the count is the same.
    const std::unique_ptr<CheckpointStream> strict =
        openCheckpointStream(spec, steps, 16, 4, nullptr, RestartData::kInterval);
    EXPECT_EQ(strict->restartData(), RestartData::kInterval);
    std::vector<CheckpointAction> actions;
    while (strict->next(&a)) actions.push_back(a);
    const CheckpointStreamCounts strictCounts = checkCheckpointStream(actions, steps);
    EXPECT_EQ(strictCounts.recomputedSteps, counts.recomputedSteps);
    EXPECT_LE(strictCounts.peakRamCheckpoints, c + 1);
  }
}

// cams without N keeps states as checkpoints, placed by its online placement as the host goes and thinned
// by releases; finalized at n it is a cams run of n + 1 steps in the online mode after the forward run (the
// host's WORK holds x_n as that run's working state does): it recomputes what cams' online prediction for
// n + 1 steps counts, holds at most M - 1 checkpoints while the forward run goes, keeps the relaxed
// contract and ends holding none. Forwards cut short by a cap give the same count.
TEST(CheckpointActions, CamsStreamWithoutNRecomputesThePredictionOfOneStepMore) {
  std::mt19937_64 rng(17);
  std::vector<std::array<std::int64_t, 4>> cases;  // M, stages, N, cap (0: the stream a host opens)
  for (const std::int64_t units : {2, 3, 4, 6, 11})
    for (const std::int64_t stages : {1, 4})
      for (std::int64_t steps = 1; steps <= 150; ++steps) cases.push_back({units, stages, steps, 0});
  for (int trial = 0; trial < 40; ++trial)
    cases.push_back({std::uniform_int_distribution<std::int64_t>(2, 40)(rng),
                     std::uniform_int_distribution<std::int64_t>(1, 4)(rng),
                     std::uniform_int_distribution<std::int64_t>(1, 5000)(rng),
                     std::uniform_int_distribution<std::int64_t>(0, 3)(rng)});
  bool released = false;
  for (const auto& [units, stages, steps, cap] : cases) {
    SCOPED_TRACE("M = " + std::to_string(units) + ", stages " + std::to_string(stages) +
                 ", N = " + std::to_string(steps) + ", cap " + std::to_string(cap));
    const std::string spec = "cams:checkpoints=" + std::to_string(units - 1) + ",online=1";
    const int s = static_cast<int>(stages);
    const std::unique_ptr<CheckpointStream> stream =
        cap > 0 ? openCamsOnlineStateStream(units, CamsCheckpointing::recordUnitsOfStages(s), cap)
                : openCheckpointStream(spec, kUnknownSteps, 16, s, nullptr);
    ASSERT_EQ(stream->restartData(), RestartData::kState);
    CheckpointStreamChecker checker(steps, RestartData::kState);
    CheckpointAction a;
    std::int64_t mostHeldForward = 0;
    while (stream->next(&a)) {
      if (a.kind == CheckpointAction::Kind::kForward && stream->maxN() < 0) {
        if (cap > 0) EXPECT_LE(a.n1 - a.n0, cap) << a.text();
        if (a.n1 >= steps) {
          a.n1 = steps;  // the host stops there
          stream->finalize(steps);
          EXPECT_EQ(stream->n(), steps);
        }
      }
      released = released || (a.kind == CheckpointAction::Kind::kMove && a.to == CheckpointStorage::kNone);
      checker.take(a);
      if (stream->maxN() < 0) mostHeldForward = std::max(mostHeldForward, stream->heldCheckpoints());
    }
    const CheckpointStreamCounts counts = checker.finish();
    const SchedulePrediction p = predictSchedule(spec, steps + 1, 16, s, nullptr);
    EXPECT_EQ(counts.recomputedSteps, p.recomputedSteps);
    EXPECT_EQ(counts.forwardSteps, steps);
    EXPECT_LE(mostHeldForward, units - 1);
    EXPECT_EQ(stream->heldCheckpoints(), 0);
  }
  EXPECT_TRUE(released);
  // Without online=1 the same stream (a cams run with an unknown step count is in the online mode).
  const std::unique_ptr<CheckpointStream> plain =
      openCheckpointStream("cams:checkpoints=3", kUnknownSteps, 16, 4, nullptr);
  EXPECT_EQ(plain->restartData(), RestartData::kState);
  // A spacing beyond what the interval plan reverses is refused before anything is released: one
  // checkpoint and the working state (M = 2) double the spacing at every thinning.
  const std::unique_ptr<CheckpointStream> far = openCamsOnlineStateStream(2, 2, std::int64_t{1} << 20);
  CheckpointAction a;
  std::int64_t reached = 0;
  try {
    while (far->next(&a)) reached = std::max(reached, a.n1);
    ADD_FAILURE() << "no refusal";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("give N"), std::string::npos) << e.what();
  }
  EXPECT_GE(reached, cams::onlineIntervalPlanSteps(cams::kMaxIntervalPlanSteps, 2, 2));
}

TEST(CheckpointActions, OnlineStreamWithoutNRefusesAWrongFinalize) {
  const std::unique_ptr<CheckpointStream> stream =
      openCheckpointStream("online:checkpoints=2", kUnknownSteps, 16, 4, nullptr);
  CheckpointAction a;
  // Up to a Forward of more than one step.
  do {
    ASSERT_TRUE(stream->next(&a));
  } while (a.kind != CheckpointAction::Kind::kForward || a.n1 - a.n0 < 2);
  EXPECT_THROW(stream->finalize(a.n0), std::logic_error);      // behind the Forward
  EXPECT_THROW(stream->finalize(a.n1 + 1), std::logic_error);  // ahead of it
  EXPECT_THROW(stream->finalize(0), std::logic_error);
  stream->finalize(a.n0 + 1);
  EXPECT_EQ(stream->maxN(), a.n0 + 1);
  EXPECT_EQ(stream->n(), a.n0 + 1);
  EXPECT_THROW(stream->finalize(a.n0 + 1), std::logic_error);  // twice
  // Families without a stream for an unknown N, and online's stages=1.
  EXPECT_THROW(openCheckpointStream("multilevel:ram=3,disk=10", kUnknownSteps, 16, 4, nullptr),
               std::invalid_argument);
  EXPECT_THROW(openCheckpointStream("mixed:checkpoints=3", kUnknownSteps, 16, 4, nullptr),
               std::invalid_argument);
  EXPECT_THROW(openCheckpointStream("online:checkpoints=3,stages=1", kUnknownSteps, 16, 4, nullptr),
               std::invalid_argument);
  EXPECT_THROW(openCheckpointStream("online:checkpoints=0", kUnknownSteps, 16, 4, nullptr),
               std::invalid_argument);
  // A budget of three states: two checkpoints and the working state, as in a run.
  const CheckpointStreamCounts budget = runOnlineWithoutN("online:budget=48", 2, 100, nullptr);
  EXPECT_EQ(budget.recomputedSteps,
            predictSchedule("online:checkpoints=2", 101, 16, 4, nullptr).recomputedSteps);
}

// cams' stream drives its plan's executor as the host consumes it and counts each checkpoint's reads when
// it is stored (cams::Executor::lastStoredUse); the whole plan translated at once, with a first pass that
// counts the reads, is the reference: the same actions, one for one, on random plans with and without
// records, and a valid stream with the prediction's recomputation.
TEST(CheckpointActions, CamsStreamIsTheWholePlansTranslationActionForAction) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    const std::int64_t steps = std::uniform_int_distribution<std::int64_t>(1, trial < 150 ? 50 : 800)(rng);
    const std::int64_t checkpoints = std::uniform_int_distribution<std::int64_t>(1, 40)(rng);
    const int stages = std::uniform_int_distribution<int>(1, 6)(rng);
    const std::string spec = "cams:checkpoints=" + std::to_string(checkpoints);
    SCOPED_TRACE(spec + ", N = " + std::to_string(steps) + ", stages " + std::to_string(stages));
    const std::vector<CheckpointAction> eager = translateCheckpointPlan(spec, steps, 16, stages, nullptr);
    const std::unique_ptr<CheckpointStream> stream = openCheckpointStream(spec, steps, 16, stages, nullptr);
    CheckpointStreamChecker checker(steps);
    CheckpointAction a;
    std::size_t i = 0;
    for (; stream->next(&a); ++i) {
      ASSERT_LT(i, eager.size()) << a.text();
      ASSERT_EQ(a.text(), eager[i].text()) << "action " << i;
      checker.take(a);
    }
    EXPECT_EQ(i, eager.size());
    const CheckpointStreamCounts c = checker.finish();
    const SchedulePrediction p = predictSchedule(spec, steps, 16, stages, nullptr);
    EXPECT_EQ(c.recomputedSteps, p.recomputedSteps);
    EXPECT_EQ(c.adjointReruns, p.adjointRecomputations);
  }
  // Beyond the plan's tables the stream is refused before its first action, naming the limit.
  try {
    openCheckpointStream("cams:checkpoints=100", 1'000'000, 16, 4, nullptr);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("12500000 table entries; add online=1"), std::string::npos)
        << e.what();
  }
}

// cams:...,online=1 with N known: the forward run writes the checkpoints the placement holds at its end and
// the intervals are reversed by the interval plan, as a run with online=1 reverses them: a valid stream
// recomputing what the prediction (cams::simulateOnline) says, on random N and budgets with and without
// records; an interval beyond the plan (revolve's) is refused before the first action.
TEST(CheckpointActions, CamsOnlineStreamRecomputesWhatTheOnlineModePredicts) {
  std::mt19937_64 rng(9);
  for (int trial = 0; trial < 120; ++trial) {
    const std::int64_t steps = std::uniform_int_distribution<std::int64_t>(1, trial < 80 ? 60 : 3000)(rng);
    const std::int64_t checkpoints = std::uniform_int_distribution<std::int64_t>(1, 30)(rng);
    const int stages = std::uniform_int_distribution<int>(1, 5)(rng);
    const std::string spec = "cams:checkpoints=" + std::to_string(checkpoints) + ",online=1";
    SCOPED_TRACE(spec + ", N = " + std::to_string(steps) + ", stages " + std::to_string(stages));
    const CheckpointStreamCounts c =
        checkCheckpointStream(checkpointSchedule(spec, steps, 16, stages, nullptr), steps);
    const SchedulePrediction p = predictSchedule(spec, steps, 16, stages, nullptr);
    EXPECT_EQ(c.forwardSteps, steps);
    EXPECT_EQ(c.recomputedSteps, p.recomputedSteps);
    EXPECT_EQ(c.adjointReruns, p.adjointRecomputations);
    EXPECT_LE(c.peakRamCheckpoints, checkpoints + 1);
  }
  // 10^5 steps with one checkpoint: an interval of about 10^5 steps, beyond the 2^15 its plan reverses.
  try {
    openCheckpointStream("cams:checkpoints=1,online=1", 100'000, 16, 4, nullptr);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("revolve"), std::string::npos) << e.what();
  }
}

// Every family's whole stream, as it is consumed, pinned by a hash of its actions' text (FNV-1a, 64 bits)
// and their count: a change of the code that drives the streams must leave every action sequence as it
// was. The hashes were recorded from the streams as they were before their drivers were shared; a
// deliberate change of a plan records them again (the failure prints the new value).
TEST(CheckpointActions, EveryFamilysStreamIsTheRecordedSequence) {
  ScratchDirectory dir;
  const ScheduleCosts costs{1.0, 1.0, 0.5, 0.5};
  struct Case {
    std::string spec;
    std::int64_t steps;
    int stages;
    std::string hash;
  };
  const std::vector<Case> cases = {
      {"full", 1, 1, "5384ec9951d523fc 4"},
      {"full", 37, 4, "5f4beefa213c0561 148"},
      {"disk:dir=" + dir.path(), 37, 4, "d7d8cfc18e4079b 148"},
      {"binomial:checkpoints=1", 10, 1, "b6a3f496167ed59a 40"},
      {"binomial:checkpoints=3", 257, 4, "776121e37347b7df 1028"},
      {"binomial:checkpoints=20", 1000, 4, "69e615001a5b9c67 4000"},
      {"multilevel:ram=48,disk=1MiB,costs=1:1:0.5:0.5,dir=" + dir.path(), 100, 4, "b8e80601c461a03c 425"},
      {"multilevel:ram=48,disk=64,costs=1:1:0:0,dir=" + dir.path(), 31, 1, "f433e028ffc2a779 126"},
      {"multilevel:ram=96,disk=1MiB,costs=1:1:100:100,dir=" + dir.path(), 100, 4, "70ec292b7e884f4b 402"},
      {"multilevel:ram=160,disk=1MiB,costs=1:1:0.5:0.5,dir=" + dir.path(), 2000, 4, "be2c78c3527384e9 8181"},
      {"cams:checkpoints=1", 10, 1, "36bf7cd50c59321a 42"},
      {"cams:checkpoints=3", 100, 4, "a28403aabfe87ba1 401"},
      {"cams:checkpoints=8", 257, 6, "a5100c207db3e7de 1010"},
      {"cams:checkpoints=3,online=1", 60, 4, "5a574b1b5d088d89 239"},
      {"cams:checkpoints=10,online=1", 3000, 5, "d1c6427b81a1abf7 11643"},
      {"mixed:checkpoints=4", 30, 1, "5ab17cc44f7acd8c 101"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.spec + ", N = " + std::to_string(c.steps) + ", stages " + std::to_string(c.stages));
    const std::unique_ptr<CheckpointStream> stream =
        openCheckpointStream(c.spec, c.steps, 16, c.stages, &costs);
    std::uint64_t hash = 14695981039346656037ULL;
    std::size_t count = 0;
    CheckpointAction a;
    while (stream->next(&a)) {
      for (const char ch : a.text() + "\n") {
        hash ^= static_cast<unsigned char>(ch);
        hash *= 1099511628211ULL;
      }
      ++count;
    }
    std::ostringstream hex;
    hex << std::hex << hash << " " << std::dec << count;
    EXPECT_EQ(hex.str(), c.hash);
  }
}

// The stream's state is checkpoint_schedules' n (where the forward is) and r (adjoint steps taken).
TEST(CheckpointActions, StreamStateFollowsTheActions) {
  for (const std::string spec : {"binomial:checkpoints=3", "cams:checkpoints=3", "full"}) {
    const std::unique_ptr<CheckpointStream> stream = openCheckpointStream(spec, 40, 16, 4, nullptr);
    CheckpointAction a;
    std::int64_t reversed = 0;
    while (stream->next(&a)) {
      if (a.kind == CheckpointAction::Kind::kForward) EXPECT_EQ(stream->n(), a.n1) << spec;
      if (a.kind == CheckpointAction::Kind::kReverse) reversed += a.n1 - a.n0;
      EXPECT_EQ(stream->r(), reversed) << spec;
    }
    EXPECT_TRUE(stream->isExhausted());
    EXPECT_EQ(stream->r(), 40);
    EXPECT_FALSE(stream->next(&a));
  }
}

TEST(CheckpointActions, TheCheckerRejectsAnInvalidStream) {
  std::vector<CheckpointAction> actions = checkpointSchedule("binomial:checkpoints=2", 10, 16, 1, nullptr);
  ASSERT_NO_THROW(checkCheckpointStream(actions, 10));
  for (std::size_t drop = 0; drop < actions.size(); ++drop) {
    std::vector<CheckpointAction> broken = actions;
    broken.erase(broken.begin() + static_cast<std::ptrdiff_t>(drop));
    EXPECT_THROW(checkCheckpointStream(broken, 10), std::logic_error) << "without " << actions[drop].text();
  }
}

// What a checkpoint_schedules host cannot run: a copy out of WORK, adjoint data read from RAM, restart
// data reused beyond the steps its Forward ran.
TEST(CheckpointActions, TheCheckerHoldsCheckpointSchedulesContract) {
  const auto forward = [](std::int64_t n0, std::int64_t n1, bool ics, bool adj, CheckpointStorage s) {
    CheckpointAction a;
    a.kind = CheckpointAction::Kind::kForward;
    a.n0 = n0;
    a.n1 = n1;
    a.writeIcs = ics;
    a.writeAdjDeps = adj;
    a.storage = s;
    return a;
  };
  const auto copy = [](std::int64_t n, CheckpointStorage from, CheckpointStorage to) {
    CheckpointAction a;
    a.kind = CheckpointAction::Kind::kCopy;
    a.n0 = a.n1 = n;
    a.from = from;
    a.to = to;
    return a;
  };
  CheckpointAction endForward, reverse;
  endForward.kind = CheckpointAction::Kind::kEndForward;
  reverse.kind = CheckpointAction::Kind::kReverse;
  reverse.n1 = 2;
  reverse.n0 = 1;
  reverse.clearAdjDeps = true;
  using S = CheckpointStorage;
  EXPECT_THROW(checkCheckpointStream({forward(0, 1, false, false, S::kWork), copy(1, S::kWork, S::kRam)}, 2),
               std::logic_error);
  EXPECT_THROW(checkCheckpointStream({forward(0, 1, false, false, S::kWork),
                                      forward(1, 2, false, true, S::kRam), endForward, reverse},
                                     2),
               std::logic_error);
  EXPECT_THROW(
      checkCheckpointStream({forward(0, 1, true, false, S::kRam), forward(1, 2, false, false, S::kWork),
                             endForward, copy(0, S::kRam, S::kWork)},
                            2),
      std::logic_error);
}

TEST(CheckpointActions, RefusesWhatHasNoFixedPlanNamingIt) {
  const auto message = [](const std::string& spec) {
    try {
      checkpointSchedule(spec, 10, 16, 4, nullptr);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("online:checkpoints=3"), "no error");  // its stream of state checkpoints
  EXPECT_NE(message("binomial:checkpoints=3,stages=1").find("binomial.stages = 1"), std::string::npos);
  EXPECT_NE(message("lossy").find("lossy"), std::string::npos);
  EXPECT_NE(message("binomial:checkpoints=0").find("checkpoints"), std::string::npos);
  // The stride, with RAM enough for the optimal plan's measured costs (it took the plan's path, without
  // a cost model, and crashed).
  EXPECT_NE(message("multilevel:ram=1MiB,disk=1MiB,schedule=stride").find("stride"), std::string::npos);
}

// Each predicted strategy writes its own plan from its registry row, or its row says why it has none:
// the stream is not chosen by the strategy's name anywhere.
TEST(CheckpointActions, EveryPredictedRowWritesItsPlanOrSaysWhyNot) {
  for (const StorageStrategyRow& row : storageStrategies()) {
    if (row.predict == nullptr) continue;
    EXPECT_TRUE(row.actions != nullptr || !row.noActions.empty()) << row.name();
    if (row.actions == nullptr) {
      try {
        std::ostringstream out;
        writeScheduleActions(row.doc.example, 10, 16, 1, nullptr, out);
        ADD_FAILURE() << row.name() << ": no error";
      } catch (const std::invalid_argument& e) {
        EXPECT_EQ(std::string(e.what()), row.noActions);
      }
    }
  }
}

}  // namespace
}  // namespace hindsight
