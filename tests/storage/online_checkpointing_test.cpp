// Online checkpointing: exact gradients with N unknown in advance, memory within the budget, and a
// recomputation count that equals its prediction, stays below its proven bound and is compared with the
// offline revolve optimum for the same N and c.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/engine/online_checkpointing.h>
#include <hindsight/storage/storage_factory.h>

#include <gtest/gtest.h>

#include <cstring>
#include <iostream>

namespace hindsight {
namespace {

using revolve::optimalForwardSteps;
using revolve::toString;

double ratio(UnsignedInt128 a, UnsignedInt128 b) { return static_cast<double>(a) / static_cast<double>(b); }

struct Case {
  std::int64_t steps;
  std::int64_t checkpoints;
};

class OnlineSchedule : public ::testing::TestWithParam<Case> {};

INSTANTIATE_TEST_SUITE_P(Table, OnlineSchedule,
                         ::testing::Values(Case{1'000'000, 1}, Case{1'000'000, 2}, Case{1'000'000, 5},
                                           Case{1'000'000, 20}, Case{1'000'000, 100}, Case{10'000, 20},
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
  const UnsignedInt128 bound = OnlineCheckpointing::forwardStepBound(steps, c);
  EXPECT_GE(online, optimum);
  EXPECT_LE(online, bound);
  if (c == 1) EXPECT_EQ(toString(online), toString(optimum));
  // Up to c + 1 states fit (c checkpoints and the working state): nothing is recomputed, like full storage.
  if (steps <= c + 1) EXPECT_EQ(toString(online), std::to_string(steps - 1));
  std::cout << "[ online/offline ] N = " << steps << ", c = " << c << ": online " << toString(online)
            << ", revolve optimum " << toString(optimum) << ", ratio " << ratio(online, optimum)
            << ", proven bound ratio " << ratio(bound, optimum) << '\n';
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
  for (const std::int64_t steps : {1, 2, 3, 7, 64, 1000}) {
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
    EXPECT_LE(total, OnlineCheckpointing::forwardStepBound(steps, c)) << "N = " << steps;
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
