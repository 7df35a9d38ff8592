// Every strategy of the factory is either predicted -- and then its prediction equals a real run counter
// by counter on a grid of N, budgets and state sizes (2 doubles and 8200 > 8191 doubles, where disk's
// chunk rule changes) -- or refused by the prediction with a message that it is not predicted. A new
// strategy fails this test until it is put in one of the two lists.
#include <hindsight/problems/classic/heat_equation.h>
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_docs.h>
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
             "multilevel:ram=" + states(4) + ",disk=" + states(40) + ",costs=1:1:100:100,dir=" + dir};
       }},
  };
  return grid;
}

// Counters that depend on the run (adaptive doubling, compression, interpolation error).
const std::vector<std::string> kNotPredicted = {"lossy", "hermite", "packed"};

TEST(PredictionGrid, EveryStrategyIsPredictedOrRefusedByName) {
  for (const std::string& name : storageStrategyNames()) {
    const bool predicted = predictedStrategies().count(name) != 0;
    const bool refused = std::find(kNotPredicted.begin(), kNotPredicted.end(), name) != kNotPredicted.end();
    EXPECT_TRUE(predicted != refused)
        << name << ": put it in the grid of predicted strategies or in kNotPredicted";
    if (refused) {
      const StorageStrategyDoc* doc = findStorageStrategyDoc(name);
      ASSERT_NE(doc, nullptr) << name;
      try {
        predictSchedule(doc->example, 10, 16, 4, nullptr);  // a valid spec: refused for being unpredictable
        ADD_FAILURE() << name << " is predicted now: move it into the grid";
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("not predicted"), std::string::npos) << e.what();
      }
    }
  }
}

TEST(PredictionGrid, PredictionEqualsTheRunForEveryStrategyNAndStateSize) {
  ScratchDirectory dir;
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
      for (const auto& [name, specs] : predictedStrategies()) {
        for (const std::string& spec : specs(stateBytes, dir.path())) {
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
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace hindsight
