// The checkpointing strategies' hot loops allocate nothing (docs/design.md P 3): after begin(), recording
// makes no heap allocation, and after finish() (where cams' online mode plans its intervals) neither do
// the restores, their recomputations and the stage values served. The exception is `online`, which
// allocates each of its slots on first use (its memory grows with what N needs): at most C allocations
// in a run, whatever N, or C + 1 when the caller's working state holds x_{N-1} (then no slot is its own
// copy of the last record, allocated in begin()). Counted with the interposed malloc of
// tests/support/allocation_counting.cpp.
#include <hindsight/engine/trajectory_storage.h>
#include <hindsight/storage/storage_factory.h>
#include "support/allocation_counting.h"

#include <gtest/gtest.h>

namespace hindsight {
namespace {

using testing::AllocationCounter;

/// z_{n+1} = z_n + 1 componentwise; its "stage values" are the state plus one.
struct CountingRecomputer final : StepRecomputer {
  Vector last;
  void advance(std::int64_t, VectorRef z) override {
    z.array() += 1.0;
    last = z;  // same size every time: no allocation after the first
  }
  void stepData(VectorRef data) override {
    for (Eigen::Index i = 0; i < data.size(); ++i) data(i) = last(i % last.size()) + 1.0;
  }
};

class CheckpointingAllocation : public ::testing::TestWithParam<std::string> {};

INSTANTIATE_TEST_SUITE_P(Strategies, CheckpointingAllocation,
                         ::testing::Values("binomial:checkpoints=10", "binomial:checkpoints=10,stages=1",
                                           "online:checkpoints=10", "online:checkpoints=10,stages=1",
                                           "cams:checkpoints=10", "cams:checkpoints=10,online=1"));

TEST_P(CheckpointingAllocation, RecordingAndRestoringAllocateNothing) {
  if (!AllocationCounter::available()) GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  constexpr int kSteps = 2000, kSize = 8;
  for (const bool adaptive : {false, true}) {
    for (const bool working : {false, true})
      for (const std::int64_t stepData : {std::int64_t{0}, std::int64_t{3 * kSize}}) {
        auto storage = createStorage(GetParam());
        if (adaptive && GetParam().rfind("binomial", 0) == 0) continue;  // binomial needs N
        storage->setVerifyRestores(false);  // the debug-build hash list grows with every record
        CountingRecomputer recomputer;
        recomputer.last = Vector::Zero(kSize);
        TrajectoryInfo info;
        info.stateSize = kSize;
        info.t1 = 1.0;
        info.stepCount = adaptive ? -1 : kSteps;
        info.workingStateHoldsLast = working;  // z holds x_{N-1} when the restores begin
        info.stepDataSize = storage->keepsStepData() ? stepData : 0;
        Vector z = Vector::Zero(kSize), data = Vector::Zero(std::max<std::int64_t>(info.stepDataSize, 1));
        Vector expected(kSize);
        storage->begin(info, recomputer);
        std::int64_t recordingAllocations = 0;
        {
          AllocationCounter counter;
          for (int n = 0; n < kSteps; ++n) {
            z.setConstant(n);
            storage->record(n, n * 1e-3, z, z);
            if (info.stepDataSize > 0) {
              data.setConstant(n + 1.0);
              storage->recordStepData(n, data);
            }
          }
          recordingAllocations = counter.count();
        }
        storage->finish(kSteps, 1.0, z, z);
        AllocationCounter counter;
        for (int n = kSteps - 1; n >= 0; --n) {
          storage->restore(n, z);
          expected.setConstant(n);
          ASSERT_TRUE(z.isApprox(expected)) << GetParam() << " restored a wrong state at " << n;
          if (info.stepDataSize > 0) storage->restoreStepData(n, data);
        }
        // `online`: one allocation per slot on its first use, forward or backward.
        const std::int64_t allowed = GetParam().rfind("online", 0) == 0 ? (working ? 11 : 10) : 0;
        EXPECT_LE(recordingAllocations + counter.count(), allowed)
            << GetParam() << (adaptive ? " adaptive" : "") << (working ? " working" : "");
      }
  }
}

}  // namespace
}  // namespace hindsight
