// Binomial (revolve) checkpointing: the schedule attains the Griewank-Walther optimum
// T(N, c) = r N - C(c + r, r - 1) exactly, as a pure schedule (large N); the strategy, which charges
// every state it keeps, attains the optimum of its game over all its C + 1 slots: with the caller's working
// state holding x_{N-1} (computeGradient) revolve's own count T(N, C + 1) - (N - 1), without it
// R(N, S) = T(N + 1, S) - N (both against exhaustive search over every schedule for small N), through the
// real storage with a real problem (moderate N), without overflow, within its byte budget.
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/storage_factory.h>

#include <hindsight/engine/adjoint.h>

#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <utility>

namespace hindsight {
namespace {

using revolve::optimalForwardSteps;
using revolve::simulateSchedule;
using revolve::toString;

// T(l, s) by dynamic programming over every first split m, independent of the closed form:
// T(1, s) = 0, T(l, 1) = l (l - 1) / 2, T(l, s) = min_m m + T(l - m, s - 1) + T(m, s).
std::int64_t dynamicProgrammingOptimum(std::int64_t l, std::int64_t s,
                                       std::map<std::pair<std::int64_t, std::int64_t>, std::int64_t>& memo) {
  if (l == 1) return 0;
  if (s == 1) return l * (l - 1) / 2;
  const auto key = std::make_pair(l, s);
  if (const auto it = memo.find(key); it != memo.end()) return it->second;
  std::int64_t best = dynamicProgrammingOptimum(l, s - 1, memo);  // not using a slot is allowed
  for (std::int64_t m = 1; m < l; ++m) {
    best = std::min(
        best, m + dynamicProgrammingOptimum(l - m, s - 1, memo) + dynamicProgrammingOptimum(m, s, memo));
  }
  memo[key] = best;
  return best;
}

TEST(RevolveFormula, EqualsDynamicProgrammingOptimumAndTheScheduleAttainsIt) {
  std::map<std::pair<std::int64_t, std::int64_t>, std::int64_t> memo;
  for (std::int64_t c = 1; c <= 6; ++c) {
    for (std::int64_t n = 1; n <= 80; ++n) {
      const std::int64_t optimum = dynamicProgrammingOptimum(n, c, memo);
      ASSERT_EQ(toString(optimalForwardSteps(n, c)), std::to_string(optimum)) << "N = " << n << ", c = " << c;
      const ScheduleCounts counts = simulateSchedule(n, c);
      ASSERT_EQ(toString(counts.totalForwardSteps()), std::to_string(optimum))
          << "N = " << n << ", c = " << c;
      ASSERT_LE(counts.maxCheckpointsHeld, c);
    }
  }
}

TEST(RevolveFormula, KnownValuesAndNoOverflow) {
  // Reference values computed with exact integer arithmetic (Python's math.comb).
  EXPECT_EQ(toString(optimalForwardSteps(10'000, 20)), "37976");
  EXPECT_EQ(toString(optimalForwardSteps(1'000'000, 2)), "941809245");
  EXPECT_EQ(toString(optimalForwardSteps(1'000'000, 100)), "3817896");
  // c = 1: N (N - 1) / 2, here about 2^123: needs 128 bits and must not saturate.
  EXPECT_EQ(toString(optimalForwardSteps(std::int64_t{1} << 62, 1)),
            "10633823966279326980924613473029062656");
  EXPECT_EQ(toString(optimalForwardSteps(std::int64_t{1} << 62, 2)), "9337128491186003968533230846");
  EXPECT_EQ(revolve::repetitionNumber(10'000, 20), 4);
  // C(10^9 + 2, 2) is exact; C(10^9 + 3, 3) ~ 1.7e26 saturates at 2^64 as documented.
  EXPECT_EQ(toString(revolve::beta(1'000'000'000, 2)), "500000001500000001");
  EXPECT_EQ(toString(revolve::beta(1'000'000'000, 3)), "18446744073709551616");
}

// The game the strategy plays (engine/binomial_checkpointing.h, storage/schedule.h): S slots, each
// holding one state; the forward sweep passes x_0 .. x_{N-1} once and may copy any of them into a slot;
// then x_{N-1}, ..., x_0 are produced in turn, each by loading a slot and advancing (one recomputed step
// per advance), copying states into free slots on the way; a produced state is consumed. The least
// number of recomputed steps over every schedule, by exhaustive search over the held sets (bit masks).
// With a working state, x_{N-1} is the caller's (produced for free, in no slot): the forward sweep's copies
// are then of x_0 .. x_{N-2}.
class ExhaustiveGame {
 public:
  ExhaustiveGame(int steps, int slots, bool working = false)
      : steps_(steps), slots_(slots), working_(working && steps >= 2) {}
  std::int64_t optimum() {
    std::int64_t best = kInfinity;
    const int copyable = working_ ? steps_ - 1 : steps_;
    // The forward sweep's copies: any set holding x_0 (nothing else can produce it) of at most S states.
    for (std::uint32_t mask = 1; mask < (1u << copyable); mask += 2)
      if (__builtin_popcount(mask) <= slots_) best = std::min(best, produce(mask, copyable - 1));
    return best;
  }

 private:
  static constexpr std::int64_t kInfinity = std::int64_t{1} << 40;
  // Least cost to produce x_e, ..., x_0 with the states of `held` (positions <= e) in slots.
  std::int64_t produce(std::uint32_t held, int e) {
    if (e < 0) return 0;
    const auto key = std::make_pair(held, e);
    if (const auto it = memo_.find(key); it != memo_.end()) return it->second;
    std::int64_t best = kInfinity;
    const std::uint32_t below = held & ((1u << e) - 1);  // x_e itself is consumed now
    for (int p = 0; p <= e; ++p) {
      if (!(held >> p & 1)) continue;
      if (p == e) {
        best = std::min(best, produce(below, e - 1));
        continue;
      }
      // Advance p -> e; keep any subset of the held states below e and add copies of positions in (p, e).
      const std::uint32_t between = ((1u << e) - 1) & ~((1u << (p + 1)) - 1);
      for (std::uint32_t keep = below;; keep = (keep - 1) & below) {
        for (std::uint32_t add = between;; add = (add - 1) & between) {
          const std::uint32_t next = keep | add;
          if (__builtin_popcount(next) <= slots_) best = std::min(best, (e - p) + produce(next, e - 1));
          if (add == 0) break;
        }
        if (keep == 0) break;
      }
    }
    memo_[key] = best;
    return best;
  }
  int steps_, slots_;
  bool working_;
  std::map<std::pair<std::uint32_t, int>, std::int64_t> memo_;
};

// With the working state the game is revolve's own: T(N, S) - (N - 1) by exhaustive search, and the
// strategy's plan (what a run of computeGradient executes, counted without states) attains it with the
// C + 1 slots of binomial:checkpoints=C for every N <= 600 and C <= 12: revolve with C + 1 snapshots.
TEST(RevolveFormula, TheGameWithAWorkingStateCostsRevolveItself) {
  for (int s = 1; s <= 3; ++s) {
    for (int n = 1; n <= (s == 3 ? 10 : 11); ++n) {
      ASSERT_EQ(toString(revolve::workingStateRecomputedSteps(n, s)),
                std::to_string(ExhaustiveGame(n, s, true).optimum()))
          << "N = " << n << ", S = " << s;
    }
  }
  for (std::int64_t c = 1; c <= 12; ++c) {
    for (std::int64_t n = 1; n <= 600; ++n) {
      const std::int64_t slots = BinomialCheckpointing::slotsFor(n, c, true);
      ASSERT_EQ(toString(BinomialCheckpointing::countPlan(n, slots, false, true).recomputedSteps),
                toString(optimalForwardSteps(n, std::min(c + 1, n)) - static_cast<UnsignedInt128>(n - 1)))
          << "N = " << n << ", C = " << c;
    }
  }
  // N = 1000, C = 2: revolve's 11 156 with 3 snapshots (11 172 without the working state); N = 10: 6.
  EXPECT_EQ(toString(BinomialCheckpointing::countPlan(1000, 3, false, true).recomputedSteps), "11156");
  EXPECT_EQ(toString(BinomialCheckpointing::countPlan(10, 3, false, true).recomputedSteps), "6");
  EXPECT_EQ(toString(BinomialCheckpointing::countPlan(1000, 3, false, false).recomputedSteps), "11172");
}

// The same game by a dynamic programme over the forward sweep's next copy at m (or none):
//   G(1, s) = 0,  G(l, s) = min( T(l, s),  min_m G(l - m, s - 1) + T(m, s) )   (s >= 2 for the copy),
// T(l, s) from dynamicProgrammingOptimum (the part left of the copy is reversed by revolve's game).
std::int64_t gameByDynamicProgramming(
    std::int64_t l, std::int64_t s,
    std::map<std::pair<std::int64_t, std::int64_t>, std::int64_t>& revolveMemo,
    std::map<std::pair<std::int64_t, std::int64_t>, std::int64_t>& memo) {
  if (l == 1) return 0;
  const auto key = std::make_pair(l, s);
  if (const auto it = memo.find(key); it != memo.end()) return it->second;
  std::int64_t best = dynamicProgrammingOptimum(l, s, revolveMemo);
  if (s >= 2) {
    for (std::int64_t m = 1; m < l; ++m) {
      best = std::min(best, gameByDynamicProgramming(l - m, s - 1, revolveMemo, memo) +
                                dynamicProgrammingOptimum(m, s, revolveMemo));
    }
  }
  memo[key] = best;
  return best;
}

TEST(RevolveFormula, TheGameOfChargedStatesCostsRevolveOverOneMorePosition) {
  for (int s = 1; s <= 3; ++s) {
    for (int n = 1; n <= (s == 3 ? 9 : 10); ++n) {
      ASSERT_EQ(toString(revolve::optimalRecomputedSteps(n, s)),
                std::to_string(ExhaustiveGame(n, s).optimum()))
          << "N = " << n << ", S = " << s;
    }
  }
  std::map<std::pair<std::int64_t, std::int64_t>, std::int64_t> revolveMemo, memo;
  for (std::int64_t s = 1; s <= 6; ++s) {
    for (std::int64_t n = 1; n <= 70; ++n) {
      ASSERT_EQ(toString(revolve::optimalRecomputedSteps(n, s)),
                std::to_string(gameByDynamicProgramming(n, s, revolveMemo, memo)))
          << "N = " << n << ", S = " << s;
    }
  }
  // N = 1000 with 3 slots: 11 172 recomputed steps. Revolve's own count with 3 checkpoints and its
  // uncharged current state is 16 (its repetition number 17, minus one) lower; 2 slots and a third parked
  // on x_{N-1} (revolve with 2 over N) give 27 821.
  EXPECT_EQ(toString(revolve::optimalRecomputedSteps(1000, 3)), "11172");
  EXPECT_EQ(toString(optimalForwardSteps(1000, 3) - 999), "11156");
  EXPECT_EQ(toString(optimalForwardSteps(1000, 2) - 999), "27821");
}

struct LargeCase {
  std::int64_t steps;
  std::int64_t checkpoints;
};

class LargeSchedule : public ::testing::TestWithParam<LargeCase> {};

INSTANTIATE_TEST_SUITE_P(Table, LargeSchedule,
                         ::testing::Values(LargeCase{1'000'000, 1}, LargeCase{1'000'000, 2},
                                           LargeCase{1'000'000, 5}, LargeCase{1'000'000, 20},
                                           LargeCase{1'000'000, 100}, LargeCase{1'048'577, 5},
                                           LargeCase{3'000'017, 20}, LargeCase{2'000'000, 100},
                                           LargeCase{5'000, 100}, LargeCase{101, 100}, LargeCase{100, 100}),
                         [](const auto& info) {
                           return "N" + std::to_string(info.param.steps) + "_c" +
                                  std::to_string(info.param.checkpoints);
                         });

TEST_P(LargeSchedule, TotalForwardStepsEqualTheRevolveOptimum) {
  const auto [steps, checkpoints] = GetParam();
  const ScheduleCounts counts = simulateSchedule(steps, checkpoints);
  EXPECT_EQ(toString(counts.totalForwardSteps()), toString(optimalForwardSteps(steps, checkpoints)));
  EXPECT_LE(counts.maxCheckpointsHeld, checkpoints);
  EXPECT_EQ(counts.workingStateLoads, steps >= 2 ? 1 : 0);
  if (checkpoints == 1) {
    const auto n = static_cast<UnsignedInt128>(steps);
    EXPECT_EQ(toString(counts.totalForwardSteps()), toString(n * (n - 1) / 2));
  }
}

// ---- Through the real storage ----

IntegratorOptions pendulumOptions(double t1, double h) {
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = t1;
  options.step = h;
  return options;
}

class BinomialOnPendulum : public ::testing::TestWithParam<std::int64_t> {};

INSTANTIATE_TEST_SUITE_P(Checkpoints, BinomialOnPendulum, ::testing::Values(1, 2, 5, 20, 100),
                         [](const auto& info) { return "c" + std::to_string(info.param); });

TEST_P(BinomialOnPendulum, BitwiseGradientOfFullAndOptimalRecomputation) {
  const std::int64_t c = GetParam();
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  for (const std::int64_t steps : {1, 2, 3, 7, 64, 1000}) {
    const auto options = pendulumOptions(2.0, 2.0 / static_cast<double>(steps));
    FullStorage full;
    full.setVerifyRestores(true);
    const GradientResult reference = computeGradient(problem, p, options, full);
    ASSERT_EQ(reference.summary.steps, steps);
    BinomialCheckpointing storage(c);
    storage.setVerifyRestores(true);
    const GradientResult result = computeGradient(problem, p, options, storage);
    EXPECT_EQ(result.objective, reference.objective);
    ASSERT_EQ(result.gradient.size(), reference.gradient.size());
    EXPECT_EQ(std::memcmp(result.gradient.data(), reference.gradient.data(),
                          sizeof(double) * static_cast<std::size_t>(result.gradient.size())),
              0);
    // Revolve over all C + 1 slots (positions 0..N-1, x_{N-1} the engine's working state): revolve's own
    // count with C + 1 snapshots.
    const std::int64_t states = BinomialCheckpointing::slotsFor(steps, c, true);
    EXPECT_EQ(toString(static_cast<UnsignedInt128>(storage.counters().recomputedSteps)),
              toString(revolve::workingStateRecomputedSteps(steps, states)))
        << "N = " << steps << ", c = " << c;
    EXPECT_EQ(toString(revolve::workingStateRecomputedSteps(steps, states)),
              toString(optimalForwardSteps(steps, std::min(c + 1, steps)) -
                       static_cast<UnsignedInt128>(steps - 1)));
    EXPECT_EQ(storage.counters().peakBytesInMemory, states * 2 * 8) << "N = " << steps;
    EXPECT_LE(storage.counters().peakBytesInMemory, storage.budgetBytes());
    EXPECT_EQ(storage.counters().bytesInMemory, 0);
  }
}

// The prediction runs the strategy's own plan with a counting visitor (up to 2^24 steps) and uses
// revolve's closed forms beyond: the two agree counter by counter, with and without stages=1, on every
// N up to 300 for 1..9 slots and on larger cases. (The counting run itself is held equal to real runs by
// tests/storage/prediction_grid_test.cpp.)
TEST(BinomialCheckpointing, ClosedFormCountsEqualTheCountingRunOfItsPlan) {
  const auto expectEqualIn = [](std::int64_t steps, std::int64_t slots, bool keepStages, bool working) {
    const auto run = BinomialCheckpointing::countPlan(steps, slots, keepStages, working);
    const auto closed = BinomialCheckpointing::closedFormCounts(steps, slots, keepStages, working);
    const std::string where = "N = " + std::to_string(steps) + ", S = " + std::to_string(slots) +
                              (keepStages ? ", stages=1" : "") + (working ? ", working state" : "");
    EXPECT_EQ(toString(run.recomputedSteps), toString(closed.recomputedSteps)) << where;
    EXPECT_EQ(run.statesStored, closed.statesStored) << where;
    EXPECT_EQ(run.ramWrites, closed.ramWrites) << where;
    EXPECT_EQ(run.stepDataStored, closed.stepDataStored) << where;
    EXPECT_EQ(run.stepDataRestored, closed.stepDataRestored) << where;
  };
  const auto expectEqual = [&](std::int64_t steps, std::int64_t slots, bool keepStages) {
    expectEqualIn(steps, slots, keepStages, false);
    // With the working state at most N - 1 slots serve (1 for N = 1).
    if (slots <= std::max<std::int64_t>(steps - 1, 1)) expectEqualIn(steps, slots, keepStages, true);
  };
  for (std::int64_t steps = 1; steps <= 300; ++steps) {
    for (std::int64_t slots = 1; slots <= std::min<std::int64_t>(9, steps); ++slots) {
      expectEqual(steps, slots, false);
      expectEqual(steps, slots, true);
    }
  }
  for (const auto& [steps, slots] : {std::pair<std::int64_t, std::int64_t>{1000, 3},
                                     {10'000, 11},
                                     {30'001, 11},
                                     {100'000, 51},
                                     {65'536, 2},
                                     {5000, 5000}}) {
    expectEqual(steps, slots, false);
    expectEqual(steps, slots, true);
  }
}

TEST(BinomialCheckpointing, ReusableForASecondRun) {
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  BinomialCheckpointing storage(4);
  storage.setVerifyRestores(true);
  const GradientResult first = computeGradient(problem, p, pendulumOptions(1.0, 0.01), storage);
  const GradientResult second = computeGradient(problem, p, pendulumOptions(1.0, 0.01), storage);
  EXPECT_EQ(first.gradient, second.gradient);
  EXPECT_EQ(toString(static_cast<UnsignedInt128>(storage.counters().recomputedSteps)),
            toString(revolve::workingStateRecomputedSteps(100, 5)));
}

TEST(BinomialCheckpointing, AdaptiveStepsAreRejectedWithAPointerToOnline) {
  Pendulum problem;
  IntegratorOptions options = pendulumOptions(1.0, 1e-3);
  options.method = "dopri5";
  options.adaptive = true;
  BinomialCheckpointing storage(10);
  try {
    computeGradient(problem, Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), options, storage);
    FAIL() << "no std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("online"), std::string::npos) << e.what();
  }
}

TEST(BinomialCheckpointing, CheckpointsThatDoNotFitTheBudgetAreRejected) {
  Pendulum problem;  // 2 doubles = 16 bytes per state
  // 10 checkpoints + 1 more slot = 176 bytes > 160.
  BinomialCheckpointing tight(10, 160);
  try {
    computeGradient(problem, Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), pendulumOptions(1.0, 0.01), tight);
    FAIL() << "no std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("binomial.checkpoints"), std::string::npos) << message;
    EXPECT_NE(message.find("binomial.budget"), std::string::npos) << message;
  }
  BinomialCheckpointing enough(10, 176);
  enough.setVerifyRestores(true);
  computeGradient(problem, Eigen::Vector4d(1.5, 0.8, 0.3, 1.2), pendulumOptions(1.0, 0.01), enough);
  EXPECT_EQ(enough.counters().peakBytesInMemory, 176);
}

TEST(BinomialCheckpointing, SpecStrings) {
  EXPECT_EQ(createStorage("binomial:checkpoints=20")->spec(), "binomial:checkpoints=20");
  EXPECT_EQ(createStorage("binomial:checkpoints=3,budget=1MiB")->spec(),
            "binomial:checkpoints=3,budget=1048576");
  const auto message = [](const std::string& spec) {
    try {
      createStorage(spec);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message("binomial").find("binomial.checkpoints is required"), std::string::npos);
  EXPECT_NE(message("binomial:checkpoints=0").find("binomial.checkpoints"), std::string::npos);
  EXPECT_NE(message("binomial:checkpoints=2x").find("binomial.checkpoints"), std::string::npos);
  EXPECT_NE(message("binomial:checkpoints=5,budget=-1").find("binomial.budget"), std::string::npos);
  EXPECT_NE(message("binomial:snaps=5").find("valid keys: checkpoints, budget"), std::string::npos);
}

}  // namespace
}  // namespace hindsight
