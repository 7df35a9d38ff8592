// The hot loops allocate nothing: after set-up, forward steps, adjoint steps and restores from
// full storage make no heap allocation (docs/design.md P 3). Counted with the interposed malloc
// of tests/support/allocation_counting.cpp (which also sees Eigen).
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/integrator.h>
#include <hindsight/problems/classic/classic_problems.h>
#include <hindsight/storage/hermite_storage.h>
#include "support/allocation_counting.h"

#include <gtest/gtest.h>

namespace hindsight {
namespace {

using testing::AllocationCounter;

class NoAllocation : public ::testing::TestWithParam<std::string> {};

INSTANTIATE_TEST_SUITE_P(Integrators, NoAllocation,
                         ::testing::Values("rk4", "dopri5", "trbdf2", "sdirk2", "midpoint",
                                           "generalized-alpha", "hht-alpha"),
                         [](const auto& info) {
                           std::string name = info.param;
                           for (char& c : name) c = c == '-' ? '_' : c;
                           return name;
                         });

TEST_P(NoAllocation, ForwardAndAdjointStepsOfASecondOrderProblem) {
  if (!AllocationCounter::available()) GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  Pendulum problem;
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  IntegratorOptions options;
  options.method = GetParam();
  const std::unique_ptr<Integrator> integrator = createIntegrator(problem, p, options);
  const int m = integrator->stateSize();  // 2 for Runge-Kutta, 4 for generalized-alpha
  Vector z(m), zStart(m), lambda = Vector::Ones(m), gradient = Vector::Zero(4);
  integrator->initialState(0.0, z);
  zStart = z;
  double error = 0.0;
  const bool embedded = integrator->hasErrorEstimate();
  long forwardAllocations = 0, adjointAllocations = 0;
  {
    AllocationCounter counter;
    for (int i = 0; i < 10; ++i) integrator->step(0.01 * i, 0.01, z, embedded ? &error : nullptr);
    forwardAllocations = counter.count();
  }
  {
    AllocationCounter counter;
    for (int i = 0; i < 10; ++i) integrator->adjointStep(0.01 * i, 0.01, zStart, lambda, gradient);
    adjointAllocations = counter.count();
  }
  EXPECT_EQ(forwardAllocations, 0);
  EXPECT_EQ(adjointAllocations, 0);
}

TEST(NoAllocation, RestoreFromFullStorage) {
  if (!AllocationCounter::available()) GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  struct NoRecompute final : StepRecomputer {
    void advance(std::int64_t, VectorRef) override { FAIL() << "full storage must not recompute"; }
  } recomputer;
  FullStorage storage;
  storage.setVerifyRestores(false);
  TrajectoryInfo info;
  info.stateSize = 8;
  info.t1 = 1.0;
  info.stepCount = 3000;
  storage.begin(info, recomputer);
  Vector z = Vector::LinSpaced(8, 0.0, 1.0);
  for (int n = 0; n < 3000; ++n) storage.record(n, n * 1e-3, z, z);
  storage.finish(3000, 1.0, z, z);
  AllocationCounter counter;
  for (int n = 2999; n >= 0; --n) storage.restore(n, z);
  EXPECT_EQ(counter.count(), 0);
}

TEST(NoAllocation, RecordRestoreAndInterpolateWithHermiteStorage) {
  if (!AllocationCounter::available()) GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  // With N announced, the hermite strategy allocates once in begin(); record, restore and
  // interpolate allocate nothing.
  struct NoRecompute final : StepRecomputer {
    void advance(std::int64_t, VectorRef) override { FAIL() << "hermite storage must not recompute"; }
  } recomputer;
  HermiteStorage storage(4);
  storage.setVerifyRestores(false);  // the debug-build hash list grows with every record
  TrajectoryInfo info;
  info.stateSize = 8;
  info.t1 = 3.0;
  info.stepCount = 3000;
  storage.begin(info, recomputer);
  Vector z = Vector::LinSpaced(8, 0.0, 1.0), zdot = Vector::Ones(8);
  long allocations = 0;
  {
    AllocationCounter counter;
    for (int n = 0; n < 3000; ++n) storage.record(n, n * 1e-3, z, zdot);
    storage.finish(3000, 3.0, z, zdot);
    for (int n = 2999; n >= 0; --n) storage.restore(n, z);
    for (int i = 0; i <= 100; ++i) storage.interpolate(0.03 * i, z);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
}

TEST(NoAllocation, CounterSeesAnAllocation) {
  if (!AllocationCounter::available()) GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  // The counter itself works: a deliberate allocation is seen.
  AllocationCounter counter;
  auto* volatile p = new double[4];
  delete[] p;
  EXPECT_GE(counter.count(), 1);
}

}  // namespace
}  // namespace hindsight
