// storage/overlapped_io.h: the I/O thread keeps the order of the jobs (a read sees the writes queued before
// it), a failure on the thread is the caller's exception at its next call, the destructor neither hangs nor
// throws with jobs queued; the cost model equals its closed form on simple plans; and multilevel with
// overlapped I/O survives an interrupt anywhere in the run (the next run has the same bits, no file left).
#include <hindsight/engine/interrupt.h>
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/overlapped_io.h>
#include "support/allocation_counting.h"
#include "support/counting_poll.h"
#include "support/storage_fixtures.h"

#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <random>
#include <thread>
#include <vector>

namespace hindsight {
namespace {

using internal::OverlappedSlotIo;
using testing::bitwiseEqual;
using testing::fixedStepRk4;
using testing::fullReference;
using testing::pendulumParameters;
using testing::ScratchDirectory;

TEST(OverlappedSlotIo, EveryReadSeesTheWritesQueuedBeforeItInAnyMixOfWritesPrefetchesAndReads) {
  constexpr int kValues = 3;
  std::map<std::int64_t, std::vector<double>> disk;  // the I/O thread's alone until drain()
  std::map<std::int64_t, std::vector<double>> expected;
  {
    OverlappedSlotIo io(
        kValues, 2,
        [&disk](std::int64_t slot, const double* z) {
          std::this_thread::sleep_for(std::chrono::microseconds(50));  // a slow disk: the queue fills
          disk[slot].assign(z, z + kValues);
        },
        [&disk](std::int64_t slot, double* z) {
          const std::vector<double>& state = disk.at(slot);
          std::copy(state.begin(), state.end(), z);
        });
    std::mt19937 random(7);
    double value = 0.0;
    std::int64_t hits = 0;
    for (int i = 0; i < 2000; ++i) {
      const std::int64_t slot = static_cast<std::int64_t>(random() % 5);
      const unsigned action = random() % 4;
      if (action < 2 || expected.count(slot) == 0) {
        const std::vector<double> state = {value, -value, 0.5 * value};
        value += 1.0;
        io.write(slot, state.data());
        expected[slot] = state;
      } else if (action == 2) {
        io.prefetch(slot);  // may be followed by a write of the same slot: the prefetch is then dropped
      } else {
        std::vector<double> z(kValues);
        const std::int64_t before = io.prefetchedReads();
        io.read(slot, z.data());
        hits += io.prefetchedReads() - before;
        ASSERT_EQ(z, expected[slot]) << "read " << i << " of slot " << slot;
      }
    }
    EXPECT_GT(hits, 0);
    io.drain();
    EXPECT_EQ(disk, expected);
  }
}

TEST(OverlappedSlotIo, AFailureOnTheThreadIsTheCallersNextExceptionAndTheDestructorDoesNotHang) {
  {
    OverlappedSlotIo io(
        1, 2,
        [](std::int64_t slot, const double*) {
          if (slot == 3) throw StorageError("writing slot 3 failed: No space left on device", "/tmp/x.slots");
        },
        [](std::int64_t, double* z) { z[0] = 1.0; });
    const double z = 0.0;
    io.write(1, &z);
    io.write(3, &z);  // queued: the failure comes later
    try {
      for (int i = 0; i < 1000; ++i) io.write(4, &z);
      io.drain();
      ADD_FAILURE() << "no StorageError";
    } catch (const StorageError& e) {
      EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
      EXPECT_EQ(e.path(), "/tmp/x.slots");
    }
    double back = 0.0;
    EXPECT_THROW(io.read(1, &back), StorageError);  // and at every call after it
  }
  {
    // A slow disk with a full queue and a prefetch outstanding: destroyed at once (jobs discarded).
    OverlappedSlotIo io(
        1, 2, [](std::int64_t, const double*) { std::this_thread::sleep_for(std::chrono::milliseconds(20)); },
        [](std::int64_t, double* z) { z[0] = 0.0; });
    const double z = 0.0;
    for (int i = 0; i < 3; ++i) io.write(i, &z);
    io.prefetch(0);
  }
}

// The leaves plan (storage/schedule.h) with K leaves of L steps and RAM for a leaf: the forward sweep
// writes the first state of leaves 0..K-2, the backward sweep reads each once, recomputes L - 1 steps and
// takes L adjoint steps per leaf.
TEST(OverlapModel, HiddenDiskSecondsEqualTheClosedFormOfTheLeavesPlan) {
  constexpr std::int64_t kLeaves = 4;
  for (const std::int64_t length : {2, 4}) {
    const std::int64_t steps = kLeaves * length;
    const TwoLevelPlan plan = TwoLevelPlan::leaves(steps, length + 1, kLeaves, length, false);
    ASSERT_EQ(plan.counts().diskWrites, kLeaves - 1) << plan.describe();
    ASSERT_EQ(plan.counts().diskReads, kLeaves - 1) << plan.describe();
    ASSERT_EQ(plan.counts().recomputedSteps, (kLeaves - 1) * (length - 1)) << plan.describe();
    // Disk as fast as a step: writes hide behind the L forward steps of a leaf, each read behind the
    // adjoint steps of the leaf after it. Everything is hidden: W wd + Q rd.
    const ScheduleCosts fast{1, 1, 1, 1};
    EXPECT_DOUBLE_EQ(internal::hiddenDiskSeconds(plan, fast, 2), 2.0 * (kLeaves - 1)) << length;
    // Reads of 10 with L = 2: writes (1 each) still hidden; the reads queue one after the other from the
    // end of the forward sweep (N uf), the last leaf's work (L - 1) uf + L ub = 3 follows the last one:
    // the run takes N + (K - 1) rd + 3 instead of 2N + R + W + 10 Q, hiding 4K - 5 = 11.
    if (length == 2) {
      const ScheduleCosts slowReads{1, 1, 1, 10};
      const double serial = 2.0 * steps + (kLeaves - 1) * (1 + 1 + 10);
      const double overlapped = steps + (kLeaves - 1) * 10.0 + 3.0;
      EXPECT_DOUBLE_EQ(internal::hiddenDiskSeconds(plan, slowReads, 2), serial - overlapped);
      EXPECT_DOUBLE_EQ(serial - overlapped, 4.0 * kLeaves - 5.0);
    }
  }
  // Free disk or no disk traffic: nothing to hide.
  const TwoLevelPlan plan = TwoLevelPlan::leaves(8, 3, 4, 2, false);
  EXPECT_EQ(internal::hiddenDiskSeconds(plan, ScheduleCosts{1, 1, 0, 0}, 2), 0.0);
  EXPECT_EQ(
      internal::hiddenDiskSeconds(TwoLevelPlan::leaves(8, 9, 1, 8, false), ScheduleCosts{1, 1, 5, 5}, 2),
      0.0);
}

// The pendulum's disk-bound two-level case: 800 B of RAM, 1 MiB of disk in `dir`, costs 1:1:2:2.
MultilevelStorage::Options pendulumOnDisk(const ScratchDirectory& dir) {
  MultilevelStorage::Options options;
  options.ramBytes = 800;
  options.diskBytes = 1 << 20;
  options.directory = dir.path();
  options.costs = ScheduleCosts{1, 1, 2, 2};
  return options;
}

TEST(OverlapModel, ARunPredictsWhatHindsightSchedulePredicts) {
  // The run's predictedSeconds() and the registry's prediction subtract the same hidden seconds.
  Pendulum problem;
  ScratchDirectory dir;
  MultilevelStorage::Options options = pendulumOnDisk(dir);
  MultilevelStorage storage(options);
  computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
  ASSERT_TRUE(storage.usesPlan());
  ASSERT_GT(storage.diskReads(), 0);
  const double hidden = internal::hiddenDiskSeconds(storage.plan(), *options.costs, 2);
  EXPECT_GT(hidden, 0.0);
  EXPECT_EQ(storage.hiddenSeconds(), hidden);
  EXPECT_EQ(storage.predictedSeconds(), storage.plan().counts().cost(*options.costs) - hidden);
  EXPECT_EQ(storage.counters().predictedSeconds, storage.predictedSeconds());
}

TEST(OverlapModel, WritesThatReachTheDeviceKeepTheBitsWithAndWithoutOverlap) {
  // sync=1 (O_DSYNC), the disk-bound case of bench/disk_bench.cpp: milliseconds per write, the same bits.
  Pendulum problem;
  const GradientResult reference = fullReference(problem, pendulumParameters(), fixedStepRk4());
  for (const bool overlap : {false, true}) {
    ScratchDirectory dir;
    MultilevelStorage::Options options = pendulumOnDisk(dir);
    options.overlap = overlap;
    options.syncWrites = true;
    MultilevelStorage storage(options);
    EXPECT_TRUE(
        bitwiseEqual(computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage), reference));
    EXPECT_GT(storage.diskWrites(), 0);
    EXPECT_EQ(storage.prefetchedReads(), overlap ? storage.diskReads() : 0);
  }
}

// The states x_n = n (every entry): a recomputed step adds one.
struct CountingUp final : StepRecomputer {
  void advance(std::int64_t, VectorRef z) override { z.array() += 1.0; }
};

TEST(OverlapModel, RecordAndRestoreAllocateNoMoreWithOverlapThanWithout) {
  // The I/O thread's buffers, job ring and the lookahead's event list are allocated at begin() (or grow
  // to their size in the first steps): the caller's sweeps allocate what the plan alone does.
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  long allocations[2] = {0, 0};
  for (const bool overlap : {false, true}) {
    ScratchDirectory dir;
    MultilevelStorage::Options options;
    options.ramBytes = 6 * 64;
    options.diskBytes = 1 << 20;
    options.directory = dir.path();
    options.costs = ScheduleCosts{1, 1, 2, 2};
    options.overlap = overlap;
    MultilevelStorage storage(options);
    storage.setVerifyRestores(false);
    CountingUp recomputer;
    TrajectoryInfo info;
    info.problemName = "counting";
    info.stateSize = 8;
    info.t1 = 1.0;
    info.stepCount = 2000;
    storage.begin(info, recomputer);
    Vector z(8);
    long count = 0;
    {
      testing::AllocationCounter counter;
      for (std::int64_t n = 0; n < info.stepCount; ++n) {
        z.setConstant(static_cast<double>(n));
        storage.record(n, 0.0, z, z);
      }
      count += counter.count();
    }
    storage.finish(info.stepCount, 1.0, z, z);
    {
      testing::AllocationCounter counter;
      for (std::int64_t e = info.stepCount - 1; e >= 1; --e) {
        storage.restore(e, z);
        ASSERT_EQ(z(7), static_cast<double>(e));
      }
      count += counter.count();
    }
    storage.restore(0, z);
    ASSERT_GT(storage.diskReads(), 0);
    EXPECT_EQ(storage.prefetchedReads(), overlap ? storage.diskReads() : 0);
    allocations[overlap ? 1 : 0] = count;
  }
  ::testing::Test::RecordProperty("allocations_overlap0", static_cast<int>(allocations[0]));
  ::testing::Test::RecordProperty("allocations_overlap1", static_cast<int>(allocations[1]));
  EXPECT_LE(allocations[1],
            allocations[0] + 4);  // the event list growing to its few entries (measured: 1 and 2)
}

using testing::countingPoll;
using testing::polls;
using testing::Stop;
using testing::throwAfter;

TEST(OverlapModel, AnInterruptAnywhereLeavesNoThreadNoFileAndTheSameBitsNext) {
  Pendulum problem;
  const GradientResult reference = fullReference(problem, pendulumParameters(), fixedStepRk4());
  ScratchDirectory dir;
  MultilevelStorage::Options options = pendulumOnDisk(dir);
  MultilevelStorage storage(options);
  polls = 0;
  throwAfter = -1;
  setInterruptPoll(&countingPoll);
  computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
  const int total = polls;
  for (const int after : {total / 10, total / 3, total / 2, 2 * total / 3, total - 2}) {
    SCOPED_TRACE(after);
    polls = 0;
    throwAfter = after;
    EXPECT_THROW(computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage), Stop);
    throwAfter = -1;
    EXPECT_TRUE(
        bitwiseEqual(computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage), reference));
    EXPECT_EQ(dir.entryCount(), 0u);
  }
  setInterruptPoll(nullptr);
}

}  // namespace
}  // namespace hindsight
