// Every row of the registry (storage/storage_factory.h, storageStrategies()) is either predicted -- and
// then its prediction equals a real run counter by counter on a grid of N, budgets and state sizes (2
// doubles and 8200 > 8191 doubles, where disk's chunk rule changes) -- or has no prediction and is
// refused with its row's reason. The test iterates the rows: a new predicting row fails it until its
// specs are in the grid below, a new row without a prediction is asked with its documented example.
#include <hindsight/problems/classic/heat_equation.h>
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_factory.h>
#include "support/storage_fixtures.h"

#include <algorithm>
#include <functional>
#include <map>

namespace hindsight {
namespace {

using testing::bitwiseEqual;
using testing::ScratchDirectory;

// Specs per strategy as functions of the bytes S of one state (budgets in states) and a scratch directory.
using SpecList = std::function<std::vector<std::string>(std::int64_t S, const std::string& dir)>;

const std::map<std::string, SpecList>& predictedStrategies() {
  static const std::map<std::string, SpecList> grid = {
      {"full",
       [](std::int64_t, const std::string&) {
         return std::vector<std::string>{"full", "full:stages=1"};
       }},
      {"disk",
       [](std::int64_t, const std::string& dir) {
         return std::vector<std::string>{"disk:dir=" + dir, "disk:dir=" + dir + ",stages=1",
                                         "disk:dir=" + dir + ",chunk=3"};
       }},
      {"binomial",
       [](std::int64_t, const std::string&) {
         return std::vector<std::string>{"binomial:checkpoints=1", "binomial:checkpoints=3",
                                         "binomial:checkpoints=50", "binomial:checkpoints=2,stages=1"};
       }},
      {"online",
       [](std::int64_t, const std::string&) {
         return std::vector<std::string>{"online:checkpoints=2", "online:checkpoints=5",
                                         "online:checkpoints=3,stages=1"};
       }},
      {"cams",
       [](std::int64_t S, const std::string&) {
         return std::vector<std::string>{"cams:checkpoints=1", "cams:checkpoints=6",
                                         "cams:budget=" + std::to_string(13 * S),
                                         "cams:checkpoints=4,online=1"};
       }},
      {"multilevel",
       [](std::int64_t S, const std::string& dir) {
         const auto states = [S](int k) { return std::to_string(k * S); };
         return std::vector<std::string>{
             "multilevel:ram=" + states(3) + ",disk=" + states(40) + ",costs=1:1:0.5:0.5,dir=" + dir,
             "multilevel:ram=" + states(2) + ",disk=" + states(3) + ",costs=1:1:0:0,dir=" + dir,
             "multilevel:ram=" + states(4) + ",disk=" + states(40) + ",costs=1:1:100:100,dir=" + dir,
             // the stride: kept states in RAM and on disk, RAM alone (the I/O buffers do not fit)
             "multilevel:ram=" + states(20) + ",disk=" + states(10) + ",schedule=stride,dir=" + dir,
             "multilevel:ram=" + states(4) + ",disk=" + states(40) + ",schedule=stride,dir=" + dir,
             // one RAM state: every plan lives on the disk level
             "multilevel:ram=" + states(1) + ",disk=" + states(5) + ",costs=1:1:0.5:0.5,dir=" + dir};
       }},
  };
  return grid;
}

TEST(PredictionGrid, EveryRowIsPredictedOnTheGridOrRefusedWithItsReason) {
  for (const StorageStrategyRow& row : storageStrategies()) {
    if (row.name() == "mixed") {
      // A plan for action streams (storage/mixed_plan.h): predicted, and its prediction counts its stream
      // (tests/storage/mixed_plan_test.cpp); a run is refused, naming the engine's equivalent.
      EXPECT_NE(row.predict, nullptr);
      const HeatEquation problem(2, 2);
      IntegratorOptions options;
      options.method = "rk4";
      options.step = 0.1;
      options.t1 = 1.0;
      auto storage = createStorage(row.doc.example);
      try {
        computeGradient(problem, problem.nominalParameters(), options, *storage);
        ADD_FAILURE() << "mixed ran";
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("cams:checkpoints=C"), std::string::npos) << e.what();
      }
      continue;
    }
    if (row.predict != nullptr) {
      EXPECT_EQ(predictedStrategies().count(row.name()), 1u)
          << row.name() << " is predicted: give it specs in the grid of this test";
      continue;
    }
    EXPECT_EQ(predictedStrategies().count(row.name()), 0u) << row.name();
    EXPECT_FALSE(row.notPredicted.empty()) << row.name() << ": say why it is not predicted";
    try {
      predictSchedule(row.doc.example, 10, 16, 4, nullptr);  // a valid spec: refused for being unpredictable
      ADD_FAILURE() << row.name() << " is predicted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("is not predicted: " + row.notPredicted), std::string::npos)
          << e.what();
    }
  }
  for (const auto& [name, specs] : predictedStrategies()) {
    const StorageStrategyRow* row = findStorageStrategy(storageStrategies(), name);
    ASSERT_NE(row, nullptr) << name;
    EXPECT_NE(row->predict, nullptr) << name;
  }
}

TEST(PredictionGrid, PredictionEqualsTheRunForEveryStrategyNAndStateSize) {
  ScratchDirectory dir;
  // Each spec of the grid is predicted (not refused) somewhere on it, and the stride keeps states on disk
  // somewhere, so no row is covered by refusals alone.
  std::map<std::string, int> predictedRuns;
  bool strideOnDisk = false;
  for (int gridPoints : {2, 8200}) {
    const HeatEquation problem(gridPoints, 2);
    const Vector p = problem.nominalParameters();
    const std::int64_t stateBytes = 8 * std::int64_t{gridPoints};
    for (std::int64_t steps : {1, 2, 7, 40}) {
      IntegratorOptions options;
      options.method = "rk4";
      options.step = 5e-6;  // explicit rk4 is stable on the 8200-point grid below ~5.8e-6
      options.t1 = options.step * static_cast<double>(steps);
      const GradientResult reference = testing::fullReference(problem, p, options);
      ASSERT_EQ(reference.summary.steps, steps);
      for (const StorageStrategyRow& row : storageStrategies()) {
        if (row.predict == nullptr || predictedStrategies().count(row.name()) == 0) continue;
        const std::string& name = row.name();
        const std::vector<std::string> specs = predictedStrategies().at(name)(stateBytes, dir.path());
        for (std::size_t index = 0; index < specs.size(); ++index) {
          const std::string& spec = specs[index];
          SCOPED_TRACE(spec + ", N = " + std::to_string(steps) + ", " + std::to_string(gridPoints) +
                       " doubles");
          SchedulePrediction predicted;
          try {
            predicted = predictSchedule(spec, steps, stateBytes, 4, nullptr);
          } catch (const std::invalid_argument& e) {
            // The plan's refusal must be the run's too (e.g. two RAM slots and no disk room for N steps).
            auto storage = createStorage(spec);
            EXPECT_ANY_THROW(computeGradient(problem, p, options, *storage))
                << "predicted refusal: " << e.what();
            continue;
          }
          ++predictedRuns[name + " #" + std::to_string(index)];
          auto storage = createStorage(spec);
          storage->setVerifyRestores(true);
          const GradientResult run = computeGradient(problem, p, options, *storage);
          EXPECT_TRUE(bitwiseEqual(run, reference));
          const StorageCounters& c = storage->counters();
          EXPECT_EQ(predicted.recomputedSteps, run.summary.recomputedSteps) << predicted.plan;
          EXPECT_EQ(predicted.rhsEvaluations, run.summary.rhsEvaluations) << predicted.plan;
          EXPECT_EQ(predicted.statesStored, c.statesStored) << predicted.plan;
          EXPECT_EQ(predicted.peakRamBytes, c.peakBytesInMemory) << predicted.plan;
          EXPECT_EQ(predicted.stepDataStored, c.stepDataStored) << predicted.plan;
          EXPECT_EQ(predicted.stepDataRestored, c.stepDataRestored) << predicted.plan;
          if (name == "disk") EXPECT_EQ(predicted.peakDiskBytes, c.uncompressedBytes) << predicted.plan;
          if (const auto* multilevel = dynamic_cast<const MultilevelStorage*>(storage.get())) {
            EXPECT_EQ(predicted.diskWrites, multilevel->diskWrites()) << predicted.plan;
            EXPECT_EQ(predicted.diskReads, multilevel->diskReads()) << predicted.plan;
            if (!multilevel->usesPlan()) {
              EXPECT_EQ(predicted.peakDiskBytes, c.uncompressedBytes) << predicted.plan;
              strideOnDisk = strideOnDisk || multilevel->statesOnDisk() > 0;
            }
          }
        }
      }
    }
  }
  for (const auto& [name, specs] : predictedStrategies()) {
    for (std::size_t index = 0; index < specs(16, "d").size(); ++index)
      EXPECT_GT(predictedRuns[name + " #" + std::to_string(index)], 0) << name << " spec " << index;
  }
  EXPECT_TRUE(strideOnDisk);
}

}  // namespace
}  // namespace hindsight
