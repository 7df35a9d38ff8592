// The checkpointing strategies driven directly through the TrajectoryStorage protocol, without the
// engine: a deterministic step map stands in for the integrator, so every restored state can be
// compared with the recorded one, and heap allocations during the backward sweep are counted
// (docs/design.md P 3: restores allocate nothing) with tests/support/allocation_counting.h.
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/online_checkpointing.h>
#include "support/allocation_counting.h"

#include <gtest/gtest.h>

#include <cmath>

namespace hindsight {
namespace {

/// z_{n+1} = cos(z_n) + 0.001 n: nonlinear, step dependent, so a restore from the wrong step or a
/// recomputation from the wrong checkpoint gives other bits.
class CosineMap final : public StepRecomputer {
 public:
  void advance(std::int64_t step, VectorRef z) override {
    for (Eigen::Index i = 0; i < z.size(); ++i) z(i) = std::cos(z(i)) + 0.001 * static_cast<double>(step);
  }
};

std::vector<Vector> trajectory(std::int64_t steps, int size) {
  CosineMap map;
  std::vector<Vector> states(static_cast<std::size_t>(steps) + 1, Vector(size));
  for (int i = 0; i < size; ++i) states[0](i) = 0.1 * i;
  for (std::int64_t n = 0; n < steps; ++n) {
    states[static_cast<std::size_t>(n) + 1] = states[static_cast<std::size_t>(n)];
    map.advance(n, states[static_cast<std::size_t>(n) + 1]);
  }
  return states;
}

/// The forward sweep of the protocol over `states` (all but the last recorded, the last the end state),
/// with the given stepCount in TrajectoryInfo (-1: unknown) and restores verified; `map` recomputes.
void recordForward(TrajectoryStorage& storage, CosineMap& map, const std::vector<Vector>& states,
                   std::int64_t announcedSteps, bool workingStateHoldsLast = false) {
  const int size = static_cast<int>(states.front().size());
  const auto steps = static_cast<std::int64_t>(states.size()) - 1;
  TrajectoryInfo info;
  info.problemName = "cosine-map";
  info.stateSize = size;
  info.t0 = 0.0;
  info.t1 = 1.0;
  info.stepCount = announcedSteps;
  info.workingStateHoldsLast = workingStateHoldsLast;
  storage.setVerifyRestores(true);
  storage.begin(info, map);
  const Vector unused = Vector::Zero(size);
  for (std::int64_t n = 0; n < steps; ++n)
    storage.record(n, 0.0, states[static_cast<std::size_t>(n)], unused);
  storage.finish(steps, 1.0, states.back(), unused);
}

/// Runs the protocol with the given stepCount in TrajectoryInfo (-1: unknown) and returns the number
/// of heap allocations made during the backward sweep; every restored state is compared exactly. With
/// workingStateHoldsLast, z holds x_{N-1} at the first restore, as computeGradient's working state does.
long runProtocol(TrajectoryStorage& storage, std::int64_t steps, std::int64_t announcedSteps,
                 bool workingStateHoldsLast = false) {
  const int size = 5;
  const std::vector<Vector> states = trajectory(steps, size);
  CosineMap map;
  recordForward(storage, map, states, announcedSteps, workingStateHoldsLast);
  Vector z = workingStateHoldsLast ? states[static_cast<std::size_t>(steps - 1)] : Vector(size);
  testing::AllocationCounter counter;
  bool allEqual = true;
  for (std::int64_t n = steps - 1; n >= 0; --n) {
    storage.restore(n, z);
    allEqual = allEqual && z == states[static_cast<std::size_t>(n)];
  }
  const long allocations = counter.count();
  EXPECT_TRUE(allEqual);
  return allocations;
}

TEST(StorageProtocol, BinomialRestoresExactStatesWithoutAllocating) {
  for (const std::int64_t c : {1, 2, 3, 7, 30}) {
    for (const std::int64_t steps : {1, 2, 5, 100, 777}) {
      BinomialCheckpointing storage(c);
      EXPECT_EQ(runProtocol(storage, steps, steps), 0) << "c = " << c << ", N = " << steps;
      // Revolve over all C + 1 states (engine/binomial_checkpointing.h): T(N + 1, C + 1) - N.
      EXPECT_EQ(revolve::toString(static_cast<UnsignedInt128>(storage.counters().recomputedSteps)),
                revolve::toString(revolve::optimalRecomputedSteps(steps, std::min(c + 1, steps))))
          << "c = " << c << ", N = " << steps;
    }
  }
}

// With the caller's working state holding x_{N-1} (as computeGradient's does), binomial keeps no slot for
// it: revolve's own count with C + 1 snapshots, T(N, C + 1) - (N - 1), in min(C + 1, N - 1) slots; and a
// caller that breaks the promise is told so (verifyRestores on) before anything is restored.
TEST(StorageProtocol, BinomialLeavesTheLastStateToTheWorkingState) {
  const int size = 5;
  for (const std::int64_t c : {1, 2, 3, 7, 30}) {
    for (const std::int64_t steps : {1, 2, 5, 100, 777}) {
      const std::vector<Vector> states = trajectory(steps, size);
      BinomialCheckpointing storage(c);
      CosineMap map;
      recordForward(storage, map, states, steps, true);
      Vector z = states[static_cast<std::size_t>(steps) - 1];  // the working state
      bool allEqual = true;
      for (std::int64_t n = steps - 1; n >= 0; --n) {
        storage.restore(n, z);
        allEqual = allEqual && z == states[static_cast<std::size_t>(n)];
      }
      EXPECT_TRUE(allEqual) << "c = " << c << ", N = " << steps;
      const std::int64_t slots = std::min(c + 1, std::max<std::int64_t>(steps - 1, 1));
      EXPECT_EQ(revolve::toString(static_cast<UnsignedInt128>(storage.counters().recomputedSteps)),
                revolve::toString(revolve::optimalForwardSteps(steps, slots) -
                                  static_cast<UnsignedInt128>(steps - 1)))
          << "c = " << c << ", N = " << steps;
      EXPECT_EQ(storage.counters().peakBytesInMemory, slots * size * 8) << "c = " << c << ", N = " << steps;
    }
  }
  const std::vector<Vector> states = trajectory(20, size);
  BinomialCheckpointing storage(3);
  CosineMap map;
  recordForward(storage, map, states, 20, true);
  Vector z = states[18];  // not x_19
  try {
    storage.restore(19, z);
    FAIL() << "no std::logic_error";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("workingStateHoldsLast"), std::string::npos) << e.what();
  }
}

TEST(StorageProtocol, OnlineRestoresExactStatesWithNoStepCountAnnounced) {
  // Without the caller's working state (the cost rule, one slot the strategy's copy of the last record)
  // and with it (the two-horizon rule, c + 1 checkpoint slots).
  for (const bool working : {false, true}) {
    for (const std::int64_t c : {1, 2, 3, 7, 30}) {
      for (const std::int64_t steps : {1, 2, 5, 100, 777}) {
        OnlineCheckpointing storage(c);
        const long allocations = runProtocol(storage, steps, -1, working);
        // Online allocates a slot on its first use; beyond c + 1 steps the forward sweep has used all of
        // them (it keeps every record while slots are free), so the backward sweep allocates nothing.
        if (steps > c + 1 && testing::AllocationCounter::available())
          EXPECT_EQ(allocations, 0) << c << " " << steps;
        EXPECT_EQ(
            revolve::toString(static_cast<UnsignedInt128>(steps - 1 + storage.counters().recomputedSteps)),
            revolve::toString(OnlineCheckpointing::predictedForwardSteps(steps, c, working)))
            << "c = " << c << ", N = " << steps << ", working " << working;
        EXPECT_LE(storage.counters().peakBytesInMemory, (c + 1) * 5 * 8);
      }
    }
  }
}

TEST(StorageProtocol, BinomialRefusesAnUnknownStepCount) {
  BinomialCheckpointing storage(3);
  CosineMap map;
  TrajectoryInfo info;
  info.stateSize = 2;
  info.t1 = 1.0;
  EXPECT_THROW(storage.begin(info, map), std::invalid_argument);
}

// full with rows of 2400 bytes: its blocks are sized to whole huge pages (1747 rows in 4 MiB, the last one
// what is left) and every state comes back exact, with the announced and with an unknown step count; the
// bytes charged are the rows', as `hindsight schedule` predicts them.
TEST(StorageProtocol, FullWithLargeRowsRestoresExactStates) {
  const int size = 300;
  for (const std::int64_t steps : {std::int64_t{3000}, std::int64_t{1747}, std::int64_t{5}}) {
    const std::vector<Vector> states = trajectory(steps, size);
    for (const bool announced : {true, false}) {
      SCOPED_TRACE(std::to_string(steps) + (announced ? " announced" : " unknown"));
      FullStorage storage;
      CosineMap map;
      recordForward(storage, map, states, announced ? steps : -1);
      // Announced: blocks capped by the steps left, so exactly the rows; unknown: whole blocks of 1747 rows.
      const std::int64_t rows = announced ? steps : (steps + 1746) / 1747 * 1747;
      EXPECT_EQ(storage.counters().peakBytesInMemory, rows * size * 8);
      Vector z(size);
      bool allEqual = true;
      for (std::int64_t n = steps - 1; n >= 0; --n) {
        storage.restore(n, z);
        allEqual = allEqual && z == states[static_cast<std::size_t>(n)];
      }
      EXPECT_TRUE(allEqual);
      EXPECT_EQ(storage.counters().bytesInMemory, 0);
    }
  }
}

}  // namespace
}  // namespace hindsight
