// The disk strategy's record() and restore() allocate nothing on the caller's thread (STYLE.md
// guideline 3): states go through chunk buffers and a task ring allocated at begin(). Counted with a
// replaced operator new, on the calling thread only (the I/O thread's HDF5 calls may allocate).
#include "storage/disk_storage.h"
#include "support/storage_fixtures.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <new>

namespace {
thread_local bool countThisThread = false;
thread_local long allocationsOnThisThread = 0;
}  // namespace

void* operator new(std::size_t size) {
  if (countThisThread) ++allocationsOnThisThread;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace hindsight {
namespace {

class AllocationCounter {
 public:
  AllocationCounter() {
    allocationsOnThisThread = 0;
    countThisThread = true;
  }
  ~AllocationCounter() { countThisThread = false; }
  long count() const { return allocationsOnThisThread; }
};

TEST(DiskStorageAllocation, RecordAndRestoreAllocateNothing) {
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
