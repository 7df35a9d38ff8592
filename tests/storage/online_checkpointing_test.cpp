// Online checkpointing: exact gradients with N unknown in advance, memory within the budget, and a
// recomputation count that equals its prediction, stays below its proven bound and is compared with the
// offline revolve optimum for the same N and c.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/online_checkpointing.h>
#include <hindsight/engine/online_placement.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/storage_factory.h>

#include <gtest/gtest.h>

#include <cstring>
#include <iostream>
#include <set>
#include <vector>

namespace hindsight {
namespace {

using revolve::optimalForwardSteps;
using revolve::toString;

double ratio(UnsignedInt128 a, UnsignedInt128 b) { return static_cast<double>(a) / static_cast<double>(b); }

// Reference formulas written from Griewank & Walther, "Algorithm 799: revolve" (ACM TOMS 26(1), 2000),
// independently of engine/binomial_checkpointing.cpp: beta(c, r) = (c + r)! / (c! r!), the repetition
// number r(N, c) = least r with beta(c, r) >= N, and T(N, c) = r N - beta(c + 1, r - 1).
std::int64_t referenceBeta(std::int64_t c, std::int64_t r) {
  if (r < 0) return 0;
  long double value = 1;
  for (std::int64_t i = 1; i <= r; ++i)
    value = value * static_cast<long double>(c + i) / static_cast<long double>(i);
  return value > 4e18L ? std::int64_t{4'000'000'000'000'000'000} : static_cast<std::int64_t>(value + 0.5L);
}
std::int64_t referenceOptimum(std::int64_t steps, std::int64_t c) {
  std::int64_t r = 0;
  while (referenceBeta(c, r) < steps) ++r;
  return r * steps - referenceBeta(c + 1, r - 1);
}

// Stumm & Walther ("New algorithms for optimal online checkpointing", SIAM J. Sci. Comput. 32(2),
// 2010) prove their online placement optimal, T(N, c) forward steps, for every N <= beta(c, 2) (the
// repetition number at most 2): online must reach exactly that there, for every N at once (the
// placement does not know N). Counted by running the placement and reversing each interval with the
// offline optimum, and compared with the reference formula above.
// The placement's count for every N up to `last` in one pass (the placement does not know N: the run of
// N steps holds what the records 1..N-1 left), each compared through `check(N, count)`.
template <typename Check>
void forEveryStepCount(std::int64_t c, std::int64_t last, std::int64_t stride, Check&& check) {
  internal::CostPlacement placement;
  placement.reset(c);
  for (std::int64_t steps = 2; steps <= last; ++steps) {
    placement.offer(steps - 1);
    if (steps < 2000 || steps % stride == 0 || steps == last)
      check(steps, OnlineCheckpointing::forwardStepsOf(placement.positions(), steps, c));
  }
}

TEST(OnlineCheckpointing, OptimalForEveryStepCountWithRepetitionTwo) {
  for (std::int64_t c = 1; c <= 60; ++c) {
    forEveryStepCount(c, referenceBeta(c, 2) + 1, 1, [&](std::int64_t steps, UnsignedInt128 count) {
      ASSERT_EQ(toString(count), std::to_string(referenceOptimum(steps, c)))
          << "N = " << steps << ", c = " << c;
    });
    // The strategy's own prediction is the same placement.
    EXPECT_EQ(toString(OnlineCheckpointing::predictedForwardSteps(referenceBeta(c, 2), c)),
              std::to_string(referenceOptimum(referenceBeta(c, 2), c)));
  }
}

// Every online placement, by exhaustive search: the placements after the records 1..N-1 that some
// sequence of decisions (keep the candidate q = N - 2 or not, and which checkpoint it replaces) reaches
// while being at the offline optimum T(N', c) for every N' <= N. Independent of CostPlacement's rules:
// only the reference formula and OnlineCheckpointing::forwardStepsOf (held positions -> count) are used.
// The set is not empty up to N = beta(c, 2) + 1 and empty at beta(c, 2) + 2: no online rule reaches the
// offline optimum for every N beyond beta(c, 2) + 1, so an excess of one forward step somewhere in
// (beta(c, 2), beta(c, 3)] is the least any rule can have there.
TEST(OnlineCheckpointing, NoOnlineRuleReachesTheOptimumForEveryStepCountBeyondRepetitionTwo) {
  for (std::int64_t c = 2; c <= 6; ++c) {
    std::set<std::vector<std::int64_t>> reached{{0}};  // N = 2: x_0 held, x_1 the working state
    std::int64_t steps = 2;
    while (!reached.empty() && steps <= referenceBeta(c, 2) + 1) {
      std::set<std::vector<std::int64_t>> next;
      const std::int64_t q = steps - 1;  // the candidate of the record that makes N = steps + 1
      for (const std::vector<std::int64_t>& held : reached) {
        std::vector<std::vector<std::int64_t>> successors{held};
        if (static_cast<std::int64_t>(held.size()) < c) {
          successors.push_back(held);
          successors.back().push_back(q);
        } else {
          for (std::size_t j = 1; j < held.size(); ++j) {
            successors.push_back(held);
            successors.back().erase(successors.back().begin() + static_cast<std::ptrdiff_t>(j));
            successors.back().push_back(q);
          }
        }
        for (const std::vector<std::int64_t>& candidate : successors) {
          if (OnlineCheckpointing::forwardStepsOf(candidate, steps + 1, c) ==
              static_cast<UnsignedInt128>(referenceOptimum(steps + 1, c)))
            next.insert(candidate);
        }
      }
      reached = std::move(next);
      ++steps;
      if (steps <= referenceBeta(c, 2) + 1) {
        EXPECT_FALSE(reached.empty()) << "c = " << c << ", N = " << steps;
      }
    }
    EXPECT_EQ(steps, referenceBeta(c, 2) + 2) << "c = " << c;
    EXPECT_TRUE(reached.empty()) << "c = " << c << ": an online placement optimal for every N <= " << steps;
  }
}

// Repetition number 3, beta(c, 2) < N <= beta(c, 3) (Stumm & Walther's second range): the three-step
// rule (engine/online_placement.h) stays within one forward step of the offline optimum for c <= 9 (for
// c <= 6 the least possible, by the exhaustive search above) and within two for c <= 60, for every N.
TEST(OnlineCheckpointing, WithinOneOrTwoStepsOfTheOptimumWithRepetitionThree) {
  for (std::int64_t c = 2; c <= 60; ++c) {
    const std::int64_t allowed = c <= 9 ? 1 : 2;
    std::int64_t worst = 0;
    forEveryStepCount(c, referenceBeta(c, 3), 1, [&](std::int64_t steps, UnsignedInt128 count) {
      const auto optimum = static_cast<UnsignedInt128>(referenceOptimum(steps, c));
      ASSERT_GE(count, optimum) << "N = " << steps << ", c = " << c;
      const auto excess = static_cast<std::int64_t>(count - optimum);
      ASSERT_LE(excess, allowed) << "N = " << steps << ", c = " << c;
      worst = std::max(worst, excess);
    });
    EXPECT_EQ(worst, allowed) << "c = " << c;  // the bound stated is the one reached
  }
}

// Beyond beta(c, 2): never below the offline optimum, and the measured worst ratio to it over every N up
// to beta(c, 3) (Stumm & Walther's second range) and up to 10^5 (every N to 2000, then every 97th) stays
// below the figures the header of engine/online_checkpointing.h states (printed;
// docs/guides/storage_strategies.md quotes them).
TEST(OnlineCheckpointing, MeasuredAgainstTheOfflineOptimumBeyondRepetitionTwo) {
  for (const std::int64_t c : {2, 3, 5, 10, 20, 50}) {
    const std::int64_t third = referenceBeta(c, 3);
    double worstThird = 1, worstBeyond = 1;
    std::int64_t worstAt = 0, worstBeyondAt = 0;
    forEveryStepCount(c, 100'000, 97, [&](std::int64_t steps, UnsignedInt128 online) {
      const auto optimum = static_cast<UnsignedInt128>(referenceOptimum(steps, c));
      ASSERT_GE(online, optimum) << "N = " << steps << ", c = " << c;
      const double q = ratio(online, optimum);
      if (steps <= third && q > worstThird) {
        worstThird = q;
        worstAt = steps;
      }
      if (steps > third && q > worstBeyond) {
        worstBeyond = q;
        worstBeyondAt = steps;
      }
    });
    std::cout << "[ online/offline ] c = " << c << ": worst ratio " << worstThird
              << " for N <= beta(c, 3) = " << third << " (at N = " << worstAt << "), " << worstBeyond
              << " beyond up to 10^5 (at N = " << worstBeyondAt << ")\n";
    EXPECT_LT(worstThird, c == 2 ? 1.08 : 1.05) << "c = " << c;
    EXPECT_LT(worstBeyond, c == 2 ? 1.15 : 1.07) << "c = " << c;
  }
  // The cases where the earlier placement (equidistant, thinned by halves) was furthest from the optimum.
  for (const auto& [steps, c] : {std::pair<std::int64_t, std::int64_t>{10, 2}, {100, 10}, {1000, 50}}) {
    const UnsignedInt128 online = OnlineCheckpointing::predictedForwardSteps(steps, c);
    std::cout << "[ online/offline ] N = " << steps << ", c = " << c << ": " << toString(online) << " / "
              << referenceOptimum(steps, c) << " = "
              << ratio(online, static_cast<UnsignedInt128>(referenceOptimum(steps, c))) << '\n';
    EXPECT_LE(ratio(online, static_cast<UnsignedInt128>(referenceOptimum(steps, c))), 1.01);
  }
}

struct Case {
  std::int64_t steps;
  std::int64_t checkpoints;
};

class OnlineSchedule : public ::testing::TestWithParam<Case> {};

INSTANTIATE_TEST_SUITE_P(Table, OnlineSchedule,
                         ::testing::Values(Case{1'000'000, 1}, Case{1'000'000, 2}, Case{1'000'000, 5},
                                           Case{100'000, 20}, Case{100'000, 100}, Case{10'000, 20},
                                           Case{10'000, 100}, Case{1'000, 10}, Case{100, 100}, Case{101, 100},
                                           Case{102, 100}, Case{21, 20}, Case{7, 5}, Case{2, 1}),
                         [](const auto& info) {
                           return "N" + std::to_string(info.param.steps) + "_c" +
                                  std::to_string(info.param.checkpoints);
                         });

TEST_P(OnlineSchedule, WithinItsBoundAndNeverBelowTheOfflineOptimum) {
  const auto [steps, c] = GetParam();
  const UnsignedInt128 online = OnlineCheckpointing::predictedForwardSteps(steps, c);
  const UnsignedInt128 optimum = optimalForwardSteps(steps, c);
  EXPECT_GE(online, optimum);
  EXPECT_LE(ratio(online, optimum), 1.1);
  if (c == 1 || steps <= referenceBeta(c, 2)) EXPECT_EQ(toString(online), toString(optimum));
  // Up to c + 1 states fit (c checkpoints and the working state): nothing is recomputed, like full storage.
  if (steps <= c + 1) EXPECT_EQ(toString(online), std::to_string(steps - 1));
  std::cout << "[ online/offline ] N = " << steps << ", c = " << c << ": online " << toString(online)
            << ", revolve optimum " << toString(optimum) << ", ratio " << ratio(online, optimum) << '\n';
}

IntegratorOptions pendulumOptions(double t1, double h) {
  IntegratorOptions options;
  options.method = "rk4";
  options.t1 = t1;
  options.step = h;
  return options;
}

void expectBitwiseEqual(const GradientResult& a, const GradientResult& b) {
  EXPECT_EQ(a.objective, b.objective);
  ASSERT_EQ(a.gradient.size(), b.gradient.size());
  EXPECT_EQ(std::memcmp(a.gradient.data(), b.gradient.data(),
                        sizeof(double) * static_cast<std::size_t>(a.gradient.size())),
            0);
}

class OnlineOnPendulum : public ::testing::TestWithParam<std::int64_t> {};

INSTANTIATE_TEST_SUITE_P(Checkpoints, OnlineOnPendulum, ::testing::Values(1, 2, 3, 5, 20, 100),
                         [](const auto& info) { return "c" + std::to_string(info.param); });

TEST_P(OnlineOnPendulum, FixedStepsBitwiseAndAsPredicted) {
  const std::int64_t c = GetParam();
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  // 15 (c = 3), 40 (c = 5) and 1000 (c = 20) lie in (beta(c, 2), beta(c, 3)]: the three-step rule.
  for (const std::int64_t steps : {1, 2, 3, 7, 15, 40, 64, 1000}) {
    const auto options = pendulumOptions(2.0, 2.0 / static_cast<double>(steps));
    FullStorage full;
    const GradientResult reference = computeGradient(problem, p, options, full);
    OnlineCheckpointing storage(c);
    storage.setVerifyRestores(true);
    const GradientResult result = computeGradient(problem, p, options, storage);
    expectBitwiseEqual(result, reference);
    const auto total = static_cast<UnsignedInt128>(steps - 1 + storage.counters().recomputedSteps);
    EXPECT_EQ(toString(total), toString(OnlineCheckpointing::predictedForwardSteps(steps, c)))
        << "N = " << steps;
    EXPECT_GE(total, optimalForwardSteps(steps, c)) << "N = " << steps;
    EXPECT_LE(storage.counters().peakBytesInMemory, (c + 1) * 16) << "N = " << steps;
    EXPECT_EQ(storage.counters().bytesInMemory, 0);
  }
}

TEST(OnlineCheckpointing, AdaptiveTrBdf2WithABudgetInBytes) {
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  IntegratorOptions options;
  options.method = "trbdf2";
  options.t1 = 4.0;
  options.adaptive = true;
  options.step = 1e-3;
  options.relativeTolerance = 1e-8;
  options.absoluteTolerance = 1e-10;
  FullStorage full;
  const GradientResult reference = computeGradient(problem, p, options, full);
  ASSERT_GT(reference.summary.steps, 100);
  const auto storage = createStorage("online:budget=160");  // 10 states of 16 bytes: c = 9
  storage->setVerifyRestores(true);
  const GradientResult result = computeGradient(problem, p, options, *storage);
  expectBitwiseEqual(result, reference);
  EXPECT_EQ(dynamic_cast<OnlineCheckpointing&>(*storage).checkpoints(), 9);
  EXPECT_LE(storage->counters().peakBytesInMemory, 160);
  const std::int64_t steps = result.summary.steps;
  const auto total = static_cast<UnsignedInt128>(steps - 1 + storage->counters().recomputedSteps);
  EXPECT_EQ(toString(total), toString(OnlineCheckpointing::predictedForwardSteps(steps, 9)));
  std::cout << "[ online/offline ] adaptive trbdf2, N = " << steps << ", c = 9: ratio "
            << ratio(total, optimalForwardSteps(steps, 9)) << '\n';
}

TEST(OnlineCheckpointing, SpecStringsAndBudgetErrors) {
  EXPECT_EQ(createStorage("online:budget=1MiB")->spec(), "online:budget=1048576");
  EXPECT_EQ(createStorage("online:checkpoints=7")->spec(), "online:checkpoints=7");
  const auto message = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message([] { createStorage("online:checkpoints=0"); }).find("online.checkpoints"),
            std::string::npos);
  EXPECT_NE(message([] { createStorage("online:budget=lots"); }).find("online.budget"), std::string::npos);
  EXPECT_NE(message([] { createStorage("online:every=2"); }).find("valid keys: checkpoints, budget"),
            std::string::npos);
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  const std::string tooSmall = message([&] {
    auto storage = createStorage("online:budget=31");  // fewer than two 16-byte states
    computeGradient(problem, p, pendulumOptions(1.0, 0.1), *storage);
  });
  EXPECT_NE(tooSmall.find("online.budget"), std::string::npos) << tooSmall;
  const std::string tooMany = message([&] {
    auto storage = createStorage("online:checkpoints=10,budget=160");
    computeGradient(problem, p, pendulumOptions(1.0, 0.1), *storage);
  });
  EXPECT_NE(tooMany.find("online.checkpoints = 10"), std::string::npos) << tooMany;
}

}  // namespace
}  // namespace hindsight
