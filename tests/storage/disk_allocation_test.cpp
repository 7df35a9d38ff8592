// The disk strategy's record() and restore() allocate nothing on the caller's thread (docs/design.md
// P 3): states go through chunk buffers and a task ring allocated at begin(). Counted with
// tests/support/allocation_counting.h, on the calling thread only (the I/O thread's HDF5 calls may
// allocate).
#include <hindsight/storage/disk_storage.h>
#include "support/allocation_counting.h"
#include "support/storage_fixtures.h"

#include <gtest/gtest.h>

namespace hindsight {
namespace {

using testing::AllocationCounter;

TEST(DiskStorageAllocation, RecordAndRestoreAllocateNothing) {
  if (!AllocationCounter::available()) GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  {  // the counter sees allocations
    AllocationCounter counter;
    int* volatile probe = new int(1);
    delete probe;
    EXPECT_EQ(counter.count(), 1);
  }
  testing::ScratchDirectory dir;
  DiskStorage::Options options;
  options.directory = dir.path();
  options.chunkStates = 16;
  DiskStorage storage(options);
  storage.setVerifyRestores(false);  // the hash list of the base class grows by itself
  testing::ForbiddenRecomputer recomputer;
  TrajectoryInfo info;
  info.problemName = "ramp";
  info.stateSize = 8;
  info.t1 = 1.0;
  storage.begin(info, recomputer);
  Vector z = Vector::Zero(8);
  const std::int64_t steps = 500;
  long recordAllocations = 0, restoreAllocations = 0;
  {
    AllocationCounter counter;
    for (std::int64_t step = 0; step < steps; ++step) {
      z.setConstant(static_cast<double>(step));
      storage.record(step, 0.001 * step, z, z);
    }
    recordAllocations = counter.count();
  }
  storage.finish(steps, 1.0, z, z);
  {
    AllocationCounter counter;
    for (std::int64_t step = steps - 1; step >= 1; --step) {
      storage.restore(step, z);
      ASSERT_EQ(z(7), static_cast<double>(step));
    }
    restoreAllocations = counter.count();
  }
  storage.restore(0, z);  // closes and removes the file
  EXPECT_EQ(recordAllocations, 0);
  EXPECT_EQ(restoreAllocations, 0);
}

}  // namespace
}  // namespace hindsight
