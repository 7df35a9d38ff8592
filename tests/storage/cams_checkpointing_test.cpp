// The cams plan (engine/cams_checkpointing.h): its optimum against brute-force enumeration of every
// schedule for tiny N, the fast split search against the exhaustive one, revolve when records do not
// fit, "store everything" with an unlimited budget, the executor's counts against the plan's value, and
// the strategy's counters in a real run against the plan.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/cams_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/interrupt.h>
#include <hindsight/engine/online_checkpointing.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_factory.h>

#include "support/same_bits.h"

#include <gtest/gtest.h>

#include <map>
#include <random>

namespace hindsight {
namespace {

using testing::sameBits;

constexpr int kNoRecords = 1000000;

// The real runs below: the pendulum with rk4 and N = 1000 fixed steps.
Vector runParameters() { return Eigen::Vector4d(1.5, 0.8, 0.3, 1.2); }
IntegratorOptions thousandRk4Steps() {
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = 4.0;
  options.step = 4e-3;
  return options;
}

// Planning a long trajectory takes seconds to minutes: it polls the interrupt (engine/interrupt.h) so
// that Ctrl-C in Python does not wait for it; a plan built after the interrupt is complete.
struct PlanningInterrupted {};
int planningPolls = 0;
void throwOnThirdPoll() {
  if (++planningPolls >= 3) throw PlanningInterrupted{};
}

TEST(CamsPlan, PlanningPollsTheInterrupt) {
  planningPolls = 0;
  setInterruptPoll(&throwOnThirdPoll);
  EXPECT_THROW(cams::Plan(20000, 20, 2), PlanningInterrupted);
  setInterruptPoll(nullptr);
  EXPECT_EQ(planningPolls, 3);
  const cams::Plan plan(20000, 20, 2);
  EXPECT_EQ(plan.steps(), 20000);
  EXPECT_EQ(planningPolls, 3);  // nothing installed: nothing called
}

// cams:checkpoints=C holds C + 1 states; beyond the default budget (4 GiB) the run is refused at
// begin(), before the plan (minutes for long runs) and before any allocation -- as binomial is.
class NoRecomputer final : public StepRecomputer {
 public:
  void advance(std::int64_t, VectorRef) override { ADD_FAILURE() << "no recomputation expected"; }
};

TEST(CamsCheckpointing, CheckpointsBeyondTheBudgetAreRefusedBeforePlanning) {
  TrajectoryInfo info;
  info.problemName = "large";
  info.stateSize = 1 << 28;  // 2 GiB states: 3 of them are 6 GiB
  info.t1 = 1.0;
  info.stepCount = 100000;
  NoRecomputer recomputer;
  CamsCheckpointing cams(2, CamsCheckpointing::kDefaultBudget, false);
  try {
    cams.begin(info, recomputer);
    ADD_FAILURE() << "cams:checkpoints=2 with 2 GiB states was accepted";
  } catch (const std::invalid_argument& e) {
    // usableUnits refuses it before any planning (which may take minutes) or allocation.
    EXPECT_NE(std::string(e.what()).find("cams.checkpoints = 2 needs 3 states of 2.0 GiB"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(cams.counters().peakBytesInMemory, 0);
}

TEST(CamsPlan, OptimumEqualsBruteForceEnumerationOfAllSchedules) {
  for (std::int64_t w : std::initializer_list<std::int64_t>{1, 2, 3, 4, kNoRecords}) {
    for (std::int64_t n = 1; n <= 6; ++n) {
      for (std::int64_t m = 1; m <= 6; ++m) {
        const cams::Plan plan(n, m, w);
        EXPECT_EQ(plan.optimalStepEvaluations(), cams::bruteForceStepEvaluations(n, m, w))
            << "N = " << n << ", M = " << m << ", w = " << w;
      }
    }
  }
}

TEST(CamsPlan, FastSplitSearchEqualsExhaustiveSearch) {
  for (std::int64_t w : std::initializer_list<std::int64_t>{1, 2, 3, 4, 7, kNoRecords}) {
    for (std::int64_t m : std::initializer_list<std::int64_t>{1, 2, 3, 5, 8, 13, 30}) {
      const std::int64_t n = 150;
      // Plan(n, ...) builds every interval length l <= n, so comparing E(l, m) for every l checks the tables.
      for (std::int64_t l = 1; l <= n; l += (l < 40 ? 1 : 7)) {
        EXPECT_EQ(cams::Plan(l, m, w).optimalStepEvaluations(),
                  cams::Plan::exhaustive(l, m, w).optimalStepEvaluations())
            << "N = " << l << ", M = " << m << ", w = " << w;
      }
    }
  }
}

// The split search brackets h's minimum from the previous length's split and compares bounds without
// dividing: on random plans the result is still the exhaustive search's optimum, and the executor
// attains it.
TEST(CamsPlan, FastSplitSearchEqualsExhaustiveSearchOnRandomPlans) {
  std::mt19937_64 rng(17);
  for (int trial = 0; trial < 40; ++trial) {
    const std::int64_t n = std::uniform_int_distribution<std::int64_t>(2, 500)(rng);
    const std::int64_t m = std::uniform_int_distribution<std::int64_t>(1, 40)(rng);
    const std::int64_t w = std::initializer_list<std::int64_t>{1, 2, 3, 4, 6, kNoRecords}.begin()[trial % 6];
    const cams::Plan fast(n, m, w);
    EXPECT_EQ(fast.optimalStepEvaluations(), cams::Plan::exhaustive(n, m, w).optimalStepEvaluations())
        << "N = " << n << ", M = " << m << ", w = " << w;
    EXPECT_EQ(cams::simulate(fast).stepEvaluations(), fast.optimalStepEvaluations());
  }
}

TEST(CamsPlan, WithoutRecordsItIsBinomialOverTheSameSlots) {
  // binomial:checkpoints=C holds C + 1 states and reverses by revolve over all of them (positions 0..N,
  // engine/binomial_checkpointing.h), the optimum of the game of charged states; its cost in steps is
  // N + recomputed + N (every adjoint step recomputes its stages). The plan over the same C + 1 units
  // without records plays the same game, so the two are equal.
  for (std::int64_t c : std::initializer_list<std::int64_t>{1, 2, 3, 5, 10, 20}) {
    for (std::int64_t n : std::initializer_list<std::int64_t>{1, 2, 3, 7, 50, 200, 1000}) {
      const std::int64_t binomial =
          n + static_cast<std::int64_t>(revolve::optimalRecomputedSteps(n, std::min(c + 1, n))) + n;
      EXPECT_EQ(cams::Plan(n, c + 1, kNoRecords).optimalStepEvaluations(), binomial)
          << "N = " << n << ", C = " << c;
    }
  }
}

TEST(CamsPlan, UnlimitedBudgetStoresEveryStepsRecordAndRecomputesNothing) {
  for (std::int64_t n : std::initializer_list<std::int64_t>{1, 2, 10, 100}) {
    for (std::int64_t w : std::initializer_list<std::int64_t>{1, 4}) {
      const cams::Plan plan(n, (n + 1) * w, w);
      EXPECT_EQ(plan.optimalStepEvaluations(), n) << n;  // the forward sweep only
      const cams::PlanCounts counts = cams::simulate(plan);
      EXPECT_EQ(counts.recomputedSteps, 0);
      EXPECT_EQ(counts.adjointRecomputations, 0);
      EXPECT_EQ(counts.recordsStored, n);
    }
  }
}

TEST(CamsPlan, ExecutorAttainsThePlansOptimumWithinItsMemory) {
  for (std::int64_t w : std::initializer_list<std::int64_t>{1, 2, 4, kNoRecords}) {
    for (std::int64_t m : std::initializer_list<std::int64_t>{1, 2, 3, 6, 11, 51}) {
      for (std::int64_t n : std::initializer_list<std::int64_t>{1, 2, 3, 5, 17, 100, 1000}) {
        const cams::Plan plan(n, m, w);
        const cams::PlanCounts counts = cams::simulate(plan);
        EXPECT_EQ(counts.stepEvaluations(), plan.optimalStepEvaluations()) << n << " " << m << " " << w;
        EXPECT_LE(counts.peakUnits, m);
      }
    }
  }
}

TEST(CamsPlan, RecordsLowerTheCostBelowRevolveAtTheSameBytes) {
  // rk4: a record is 4 states. 3000 steps, the budgets of binomial:checkpoints=10 and 50.
  for (std::int64_t c : std::initializer_list<std::int64_t>{10, 50}) {
    const std::int64_t n = 3000;
    const std::int64_t revolveCost =
        n + static_cast<std::int64_t>(revolve::optimalRecomputedSteps(n, c + 1)) + n;
    const cams::Plan plan(n, c + 1, 4);
    EXPECT_LT(plan.optimalStepEvaluations(), revolveCost) << c;
    EXPECT_EQ(cams::simulate(plan).stepEvaluations(), plan.optimalStepEvaluations());
  }
}

TEST(CamsPlan, ActionStreamReplaysTheCounts) {
  const cams::Plan plan(40, 5, 2);
  std::vector<cams::Action> actions;
  const cams::PlanCounts counts = cams::simulate(plan, &actions);
  std::int64_t advanced = 0, delivered = 0, next = 39;
  for (const auto& a : actions) {
    if (a.kind == cams::Action::Kind::Advance) advanced += a.to - a.from;
    if (a.kind == cams::Action::Kind::Deliver) {
      EXPECT_EQ(a.from, next--);
      ++delivered;
    }
  }
  EXPECT_EQ(advanced, counts.recomputedSteps);
  EXPECT_EQ(delivered, 40);
}

// Executor::lastStoredUse reads a checkpoint's future from the plan's decisions (the action stream counts
// its reads by it): here the executor runs and every anchor's advances and held stage values at its
// delivery are counted and compared with what was read when it was stored.
TEST(CamsPlan, LastStoredUseIsWhatTheExecutorDoesWithTheCheckpoint) {
  struct Visitor {
    cams::Executor& executor;
    std::map<std::int64_t, std::pair<cams::Executor::AnchorUse, std::int64_t>> byRef;  // read, counted
    std::int64_t loaded = -1, stored = 0, delivered = 0;
    void add(std::int64_t ref) {
      EXPECT_EQ(byRef.count(ref), 0u);  // a unit is reused only after its checkpoint was delivered
      byRef[ref] = {executor.lastStoredUse(), 0};
      ++stored;
    }
    void store(std::int64_t ref, std::int64_t, bool) { add(ref); }
    void upgrade(std::int64_t, std::int64_t) {}
    void capture(std::int64_t, std::int64_t) {}
    void load(std::int64_t ref) { loaded = ref; }
    void advance(std::int64_t, std::int64_t) {
      if (loaded >= 0) ++byRef.at(loaded).second;  // one advance from the checkpoint per load
      loaded = -1;
    }
    void deliver(std::int64_t, std::int64_t ref, bool filled) {
      loaded = -1;
      if (ref < 0) return;  // a position replayed without a checkpoint of its own
      const auto it = byRef.find(ref);
      ASSERT_NE(it, byRef.end());
      EXPECT_EQ(it->second.second, it->second.first.advances);
      EXPECT_EQ(filled, it->second.first.filledAtDelivery);
      byRef.erase(it);
      ++delivered;
    }
  };
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 300; ++trial) {
    const std::int64_t n = std::uniform_int_distribution<std::int64_t>(1, trial < 200 ? 60 : 700)(rng);
    const std::int64_t m = std::uniform_int_distribution<std::int64_t>(1, 25)(rng);
    const std::int64_t w = std::initializer_list<std::int64_t>{1, 2, 3, 4, 6, kNoRecords}.begin()[trial % 6];
    SCOPED_TRACE("N = " + std::to_string(n) + ", M = " + std::to_string(m) + ", w = " + std::to_string(w));
    const cams::Plan plan(n, m, w);
    cams::Executor executor;
    executor.reset(&plan);
    Visitor visitor{executor, {}};
    for (std::int64_t k = 0; k < n; ++k) {
      bool record = false;
      const std::int64_t ref = executor.recordForward(k, &record);
      if (ref >= 0) visitor.add(ref);
    }
    for (std::int64_t e = n - 1; e >= 0; --e) executor.restoreStep(e, visitor);
    EXPECT_TRUE(visitor.byRef.empty());
    EXPECT_EQ(visitor.delivered, visitor.stored);
  }
}

// The online mode's interval plans build the replay tables alone: every decision is the full plan's.
TEST(CamsPlan, ReplayOnlyPlanHasTheFullPlansReplayDecisions) {
  std::mt19937_64 rng(13);
  for (int trial = 0; trial < 60; ++trial) {
    const std::int64_t n = std::uniform_int_distribution<std::int64_t>(1, 400)(rng);
    const std::int64_t m = std::uniform_int_distribution<std::int64_t>(1, 30)(rng);
    const std::int64_t w = std::initializer_list<std::int64_t>{1, 2, 3, 4, 6, kNoRecords}.begin()[trial % 6];
    const cams::Plan full(n, m, w), replay = cams::Plan::replayOnly(n, m, w);
    ASSERT_EQ(replay.memoryUnits(), full.memoryUnits());
    EXPECT_EQ(replay.optimalStepEvaluations(), -1);
    for (std::int64_t u = 0; u <= full.memoryUnits(); ++u) {
      for (std::int64_t l = 1; l <= n; ++l) {
        for (bool record : {false, true}) {
          ASSERT_EQ(replay.decision(false, record, l, u), full.decision(false, record, l, u))
              << "N = " << n << ", M = " << m << ", w = " << w << ", l = " << l << ", m = " << u;
        }
      }
    }
  }
}

// Plans of up to 2^15 steps keep their decisions as int16, longer ones as int32; a row does not depend on
// the plan's N, so both hold the same decisions where they overlap, and the longer one attains its optimum.
TEST(CamsPlan, NarrowAndWideDecisionTablesAgree) {
  for (std::int64_t w : std::initializer_list<std::int64_t>{2, 4}) {
    const std::int64_t narrowSteps = std::int64_t{1} << 15;
    const cams::Plan narrow(narrowSteps, 4, w), wide(narrowSteps + 1000, 4, w);
    for (std::int64_t m = 0; m <= 4; ++m) {
      for (std::int64_t l = 1; l <= narrowSteps; ++l) {
        for (int table = 0; table < 4; ++table) {
          ASSERT_EQ(narrow.decision(table >= 2, table % 2 == 1, l, m),
                    wide.decision(table >= 2, table % 2 == 1, l, m))
              << "l = " << l << ", m = " << m << ", w = " << w;
        }
      }
    }
    EXPECT_EQ(cams::simulate(wide).stepEvaluations(), wide.optimalStepEvaluations());
    EXPECT_EQ(cams::simulate(narrow).stepEvaluations(), narrow.optimalStepEvaluations());
  }
}

TEST(CamsPlan, BadInputIsRejectedWithTheFieldNamed) {
  EXPECT_THROW(cams::Plan(0, 3, 1), std::invalid_argument);
  EXPECT_THROW(cams::Plan(10, 0, 1), std::invalid_argument);
  EXPECT_THROW(createStorage("cams"), std::invalid_argument);
  EXPECT_THROW(createStorage("cams:checkpoints=3,budget=1MiB"), std::invalid_argument);
  EXPECT_THROW(createStorage("cams:checkpoints=0"), std::invalid_argument);
  try {
    createStorage("cams:budget=0");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cams.budget"), std::string::npos) << e.what();
  }
  EXPECT_EQ(createStorage("cams:checkpoints=7")->spec(), "cams:checkpoints=7");
  EXPECT_EQ(createStorage("cams:budget=1MiB")->spec(), "cams:budget=1048576");
}

TEST(CamsCheckpointing, RealRunMatchesThePlanAndFullBitwiseWithFewerRhsThanBinomial) {
  Pendulum problem;
  const Vector p = runParameters();
  IntegratorOptions options = thousandRk4Steps();
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  for (std::int64_t c : std::initializer_list<std::int64_t>{2, 10, 50}) {
    auto binomial = createStorage("binomial:checkpoints=" + std::to_string(c));
    const GradientResult b = computeGradient(problem, p, options, *binomial);
    auto storage = createStorage("cams:checkpoints=" + std::to_string(c));
    storage->setVerifyRestores(true);
    const GradientResult r = computeGradient(problem, p, options, *storage);
    EXPECT_TRUE(sameBits(r.gradient.data(), reference.gradient.data(), 4));
    EXPECT_EQ(r.objective, reference.objective);
    // C = 2: three units hold no record of four, so cams plays the game of charged states, R(N, 3), while
    // binomial leaves x_{N-1} to the engine's working state: revolve with 3 snapshots, r(N + 1, 3) - 1 = 16
    // recomputed steps (64 rhs) below.
    if (c == 2) {
      const std::int64_t steps = b.summary.steps;
      const std::int64_t gap = static_cast<std::int64_t>(revolve::optimalRecomputedSteps(steps, 3) -
                                                         revolve::workingStateRecomputedSteps(steps, 3));
      EXPECT_EQ(gap, 16);
      EXPECT_EQ(r.summary.rhsEvaluations, b.summary.rhsEvaluations + 4 * gap);
    } else
      EXPECT_LT(r.summary.rhsEvaluations, b.summary.rhsEvaluations) << c;
    EXPECT_LE(storage->counters().peakBytesInMemory, (c + 1) * 4 * 8);
    const auto* cams = dynamic_cast<const CamsCheckpointing*>(storage.get());
    const cams::PlanCounts counts = cams::simulate(*cams->plan());
    EXPECT_EQ(storage->counters().recomputedSteps, counts.recomputedSteps);
    EXPECT_EQ(storage->counters().stepDataRestored, counts.steps - counts.adjointRecomputations);
    // The run summary carries the step data counts and the planning time (part of the forward sweep).
    EXPECT_EQ(r.summary.stepDataRestored, storage->counters().stepDataRestored);
    EXPECT_EQ(r.summary.stepDataStored, storage->counters().stepDataStored);
    EXPECT_GT(r.summary.planningSeconds, 0.0);
    EXPECT_LE(r.summary.planningSeconds, r.summary.forwardSeconds);
    // rk4 evaluates 4 right-hand sides per step, forward, recomputed and in the adjoint's recomputation.
    EXPECT_EQ(r.summary.rhsEvaluations, 4 * counts.stepEvaluations());
  }
}

TEST(CamsOnline, NeverCostsMoreThanItsPlacementWithRevolvePerIntervalAndRecordsLowerIt) {
  // cams' placement (internal::OnlinePlacement) with c = M - 1 checkpoints, each interval j reversed by
  // revolve with c - j slots, every adjoint step recomputing its stages: cams gives each interval the
  // optimal plan with at least those units, so it is never dearer.
  for (std::int64_t c : std::initializer_list<std::int64_t>{1, 2, 3, 10, 50}) {
    for (std::int64_t n : std::initializer_list<std::int64_t>{1, 2, 3, 7, 100, 1000, 5000}) {
      const std::vector<std::int64_t> positions = internal::OnlinePlacement::simulate(n, c, nullptr, nullptr);
      const std::int64_t online =
          n + static_cast<std::int64_t>(n <= 1 ? 0 : OnlineCheckpointing::forwardStepsOf(positions, n, c)) -
          (n - 1) + n;
      const cams::PlanCounts withoutRecords = cams::simulateOnline(n, c + 1, kNoRecords);
      EXPECT_LE(withoutRecords.stepEvaluations(), online) << "N = " << n << ", C = " << c;
      EXPECT_EQ(withoutRecords.adjointRecomputations, n);
      const cams::PlanCounts rk4 = cams::simulateOnline(n, c + 1, 4);
      EXPECT_LE(rk4.stepEvaluations(), withoutRecords.stepEvaluations()) << "N = " << n << ", C = " << c;
      EXPECT_LE(rk4.peakUnits, c + 1);
    }
  }
  // Where records fit, they pay: rk4 records at 5000 steps and 50 checkpoints.
  EXPECT_LT(cams::simulateOnline(5000, 51, 4).stepEvaluations(),
            cams::simulateOnline(5000, 51, kNoRecords).stepEvaluations());
}

TEST(CamsOnline, PlacementIsOnlines) {
  for (std::int64_t c : std::initializer_list<std::int64_t>{1, 4, 9}) {
    for (std::int64_t n : std::initializer_list<std::int64_t>{2, 10, 77, 1000}) {
      std::int64_t stored = 0, peak = 0;
      const std::vector<std::int64_t> positions = internal::OnlinePlacement::simulate(n, c, &stored, &peak);
      const std::int64_t d = internal::OnlinePlacement::finalSpacing(n, c);
      ASSERT_FALSE(positions.empty());
      for (std::size_t j = 0; j < positions.size(); ++j)
        EXPECT_EQ(positions[j], static_cast<std::int64_t>(j) * d);
      EXPECT_LE(peak, c);
      EXPECT_LE(internal::OnlinePlacement::longestInterval(positions, n), d);
    }
  }
}

TEST(CamsOnline, RealRunMatchesTheSimulationAndFullBitwiseFixedAndAdaptive) {
  Pendulum problem;
  const Vector p = runParameters();
  IntegratorOptions options = thousandRk4Steps();
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  for (std::int64_t c : std::initializer_list<std::int64_t>{1, 3, 10, 50}) {
    auto storage = createStorage("cams:checkpoints=" + std::to_string(c) + ",online=1");
    storage->setVerifyRestores(true);
    // Twice: the second run reuses the interval plan.
    for (int run = 0; run < 2; ++run) {
      const GradientResult r = computeGradient(problem, p, options, *storage);
      EXPECT_TRUE(sameBits(r.gradient.data(), reference.gradient.data(), 4));
      EXPECT_EQ(r.objective, reference.objective);
      EXPECT_LE(storage->counters().peakBytesInMemory, (c + 1) * 4 * 8);
      const cams::PlanCounts counts = cams::simulateOnline(1000, c + 1, 4);
      EXPECT_EQ(storage->counters().recomputedSteps, counts.recomputedSteps) << c;
      EXPECT_EQ(storage->counters().statesStored, counts.forwardStores) << c;
      EXPECT_EQ(storage->counters().stepDataRestored, counts.steps - counts.adjointRecomputations) << c;
      EXPECT_EQ(r.summary.rhsEvaluations, 4 * counts.stepEvaluations()) << c;
      // hindsight schedule predicts the same counts without the model.
      const SchedulePrediction predicted = predictSchedule(
          "cams:checkpoints=" + std::to_string(c) + ",online=1", 1000, 8 * problem.stateSize(), 4, nullptr);
      EXPECT_EQ(predicted.recomputedSteps, storage->counters().recomputedSteps) << c;
      EXPECT_EQ(predicted.rhsEvaluations, r.summary.rhsEvaluations) << c;
      EXPECT_EQ(predicted.statesStored, storage->counters().statesStored) << c;
    }
  }
  // Adaptive steps (N unknown while recording): the online mode without being asked for it.
  options.adaptive = true;
  options.method = "dopri5";
  FullStorage fullAdaptive;
  const GradientResult adaptiveReference = computeGradient(problem, p, options, fullAdaptive);
  auto storage = createStorage("cams:checkpoints=5");
  storage->setVerifyRestores(true);
  const GradientResult r = computeGradient(problem, p, options, *storage);
  EXPECT_TRUE(dynamic_cast<const CamsCheckpointing&>(*storage).onlineRun());
  EXPECT_TRUE(sameBits(r.gradient.data(), adaptiveReference.gradient.data(), 4));
  EXPECT_GT(storage->counters().recomputedSteps, 0);
}

// Intervals longer than cams::kMaxIntervalPlanSteps are reversed by revolve with the same units: 300 000
// steps with C = 10 give intervals of 65 536 steps. The run is still exact, matches the model-free counts
// and stays within its units.
TEST(CamsOnline, IntervalsBeyondThePlansTablesAreReversedByRevolveExactly) {
  Pendulum problem;
  const Vector p = runParameters();
  IntegratorOptions options = thousandRk4Steps();
  options.t1 = 1200.0;  // 300 000 steps
  const std::int64_t steps = 300'000, c = 10;
  const std::vector<std::int64_t> positions = internal::OnlinePlacement::simulate(steps, c, nullptr, nullptr);
  std::unique_ptr<cams::Plan> plan;
  const cams::PlanCounts counts = cams::simulateOnline(steps, c + 1, 4, &plan);
  ASSERT_GT(internal::OnlinePlacement::longestInterval(positions, steps), plan->steps());
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  auto storage = createStorage("cams:checkpoints=10,online=1");
  const GradientResult r = computeGradient(problem, p, options, *storage);
  EXPECT_TRUE(sameBits(r.gradient.data(), reference.gradient.data(), 4));
  EXPECT_EQ(storage->counters().recomputedSteps, counts.recomputedSteps);
  EXPECT_EQ(r.summary.rhsEvaluations, 4 * counts.stepEvaluations());
  EXPECT_LE(storage->counters().peakBytesInMemory, (c + 1) * 4 * 8);
  EXPECT_LE(counts.peakUnits, c + 1);
  // Every interval is revolve's with the slots `online` gives interval j (c + 1 - j): the same count as
  // online's own reversal of this placement, in closed form, and no records.
  EXPECT_EQ(counts.adjointRecomputations, steps);
  EXPECT_EQ(
      counts.recomputedSteps,
      static_cast<std::int64_t>(OnlineCheckpointing::forwardStepsOf(positions, steps, c)) - (steps - 1));
}

TEST(CamsOnline, OneStateIsNotEnoughAndTooLargeOfflinePlansPointToOnline) {
  Pendulum problem;
  const Vector p = runParameters();
  IntegratorOptions options = thousandRk4Steps();
  auto one = createStorage("cams:budget=24,online=1");  // at most one state (the pendulum has 2 or 4 doubles)
  try {
    computeGradient(problem, p, options, *one);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("online mode"), std::string::npos) << e.what();
  }
  options.step = 4.0 / 2e6;  // N = 2e6 with 11 units: beyond the offline table
  auto offline = createStorage("cams:checkpoints=10");
  try {
    computeGradient(problem, p, options, *offline);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("online=1"), std::string::npos) << e.what();
  }
  EXPECT_EQ(createStorage("cams:checkpoints=7,online=1")->spec(), "cams:checkpoints=7,online=1");
  // A budget far beyond N: the online mode (N unknown when it allocates) holds at most 10^6 + 1 states.
  options.step = 4e-3;
  auto large = createStorage("cams:budget=1GiB,online=1");
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  const GradientResult r = computeGradient(problem, p, options, *large);
  EXPECT_TRUE(sameBits(r.gradient.data(), reference.gradient.data(), 4));
  EXPECT_EQ(large->counters().peakBytesInMemory,
            (CamsCheckpointing::kMaxCheckpoints + 1) * 8 * problem.stateSize());
}

}  // namespace
}  // namespace hindsight
