// The checkpoint_schedules action stream (storage/checkpoint_actions.h): valid for every fixed-step
// strategy on a grid of N and budgets (a host that tracks which step each piece of data belongs to
// executes it), and it recomputes what the strategy's own prediction says.
#include <hindsight/storage/checkpoint_actions.h>
#include <hindsight/storage/storage_factory.h>

#include "support/storage_fixtures.h"

#include <gtest/gtest.h>

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
  // revolve with x_0 as the one checkpoint: x_2's adjoint data from the forward run, x_1 from x_0 again.
  EXPECT_EQ(text,
            "Forward(0, 2, True, False, StorageType.RAM)\n"
            "Forward(2, 3, False, True, StorageType.WORK)\n"
            "EndForward()\n"
            "Reverse(3, 2, True)\n"
            "Copy(0, StorageType.RAM, StorageType.WORK)\n"
            "Forward(0, 1, False, False, StorageType.WORK)\n"
            "Forward(1, 2, False, True, StorageType.WORK)\n"
            "Reverse(2, 1, True)\n"
            "Move(0, StorageType.RAM, StorageType.WORK)\n"
            "Forward(0, 1, False, True, StorageType.WORK)\n"
            "Reverse(1, 0, True)\n"
            "EndReverse()\n");
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

TEST(CheckpointActions, RefusesWhatHasNoFixedPlanNamingIt) {
  const auto message = [](const std::string& spec) {
    try {
      checkpointSchedule(spec, 10, 16, 4, nullptr);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("online:checkpoints=3").find("online"), std::string::npos);
  EXPECT_NE(message("cams:checkpoints=3,online=1").find("online"), std::string::npos);
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
