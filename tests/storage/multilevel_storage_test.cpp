// Strategy "multilevel": bitwise-identical gradients to "full" in each regime (all in RAM, RAM and
// disk, checkpointing with a fixed or doubling stride), the RAM budget and the disk budget, the
// number of recomputations, the file's lifetime and faults -- for schedule=stride (levels()) and for
// the default schedule=optimal (the two-level plan of storage/schedule.h; tests at the end; its
// counters against the plan's prediction are in schedule_test.cpp).
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/scratch_files.h>
#include <hindsight/storage/storage_factory.h>
#include "support/storage_fixtures.h"

#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <optional>

namespace hindsight {
namespace {

using testing::adaptiveTrBdf2;
using testing::bitwiseEqual;
using testing::fixedStepRk4;
using testing::fullReference;
using testing::pendulumParameters;
using testing::ScratchDirectory;

MultilevelStorage::Options levels(std::int64_t ram, std::int64_t disk, const std::string& directory) {
  MultilevelStorage::Options options;
  options.ramBytes = ram;
  options.diskBytes = disk;
  options.directory = directory;
  options.stride = true;
  return options;
}

enum class Regime { kRamOnly, kRamAndDisk, kCheckpointing };

struct Case {
  const char* name;
  std::int64_t ram, disk;
  Regime fixedRegime;  // for rk4 with N = 2000 (32000 bytes of states)
};

// Pendulum states are 16 bytes, rows on disk 24 bytes (with the time).
const Case kCases[] = {
    {"everything in RAM", 1 << 20, 1 << 20, Regime::kRamOnly},
    {"RAM then disk", 8000, 1 << 20, Regime::kRamAndDisk},
    {"stride over both", 8000, 12000, Regime::kCheckpointing},
    {"tiny: stride over a few slots", 200, 240, Regime::kCheckpointing},
    {"RAM only, too small", 4000, 1, Regime::kCheckpointing},
};

TEST(MultilevelStorage, BitwiseIdenticalToFullInEveryRegime) {
  Pendulum problem;
  for (const IntegratorOptions& options : {fixedStepRk4(), adaptiveTrBdf2()}) {
    const GradientResult reference = fullReference(problem, pendulumParameters(), options);
    const bool fixed = !options.adaptive;
    for (const Case& c : kCases) {
      SCOPED_TRACE(std::string(c.name) + ", " + options.method);
      ScratchDirectory dir;
      MultilevelStorage storage(levels(c.ram, c.disk, dir.path()));
      storage.setVerifyRestores(true);
      const GradientResult result = computeGradient(problem, pendulumParameters(), options, storage);
      EXPECT_TRUE(bitwiseEqual(result, reference));
      ::testing::Test::RecordProperty(std::string(c.name) + " " + options.method,
                                      "steps " + std::to_string(result.summary.steps) + " stride " +
                                          std::to_string(storage.stride()) + " ram " +
                                          std::to_string(storage.statesInRam()) + " disk " +
                                          std::to_string(storage.statesOnDisk()) + " recomputed " +
                                          std::to_string(result.summary.recomputedSteps) + " peak " +
                                          std::to_string(storage.counters().peakBytesInMemory));
      EXPECT_LE(storage.counters().peakBytesInMemory, c.ram);
      EXPECT_LE(storage.statesOnDisk() * 24, c.disk);
      EXPECT_EQ(storage.statesInRam() + storage.statesOnDisk(), storage.counters().statesStored);
      EXPECT_EQ(dir.entryCount(), 0u) << "the file must be removed after the backward sweep";
      if (fixed) {
        switch (c.fixedRegime) {
          case Regime::kRamOnly:
            EXPECT_EQ(storage.statesOnDisk(), 0);
            EXPECT_TRUE(storage.filePath().empty()) << "no file when RAM suffices";
            EXPECT_EQ(result.summary.recomputedSteps, 0);
            break;
          case Regime::kRamAndDisk:
            EXPECT_GT(storage.statesInRam(), 0);
            EXPECT_GT(storage.statesOnDisk(), 0);
            EXPECT_EQ(storage.stride(), 1);
            EXPECT_EQ(result.summary.recomputedSteps, 0);
            EXPECT_GT(result.summary.bytesOnDisk, 0);
            break;
          case Regime::kCheckpointing:
            EXPECT_GT(storage.stride(), 1);
            EXPECT_GT(result.summary.recomputedSteps, 0);
            EXPECT_EQ(storage.counters().statesStored, (2000 + storage.stride() - 1) / storage.stride());
            break;
        }
      }
    }
  }
}

TEST(MultilevelStorage, KnownLengthWithScratchRecomputesEachMissingStateOnce) {
  // 8000 bytes of RAM and 12000 of disk: stride 3, and the 2 scratch states a segment needs fit.
  Pendulum problem;
  ScratchDirectory dir;
  MultilevelStorage storage(levels(8000, 12000, dir.path()));
  const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
  EXPECT_EQ(storage.stride(), 3);
  EXPECT_EQ(result.summary.recomputedSteps, result.summary.steps - storage.counters().statesStored);
}

TEST(MultilevelStorage, UnknownLengthDoublesTheStrideAndStaysExact) {
  // Adaptive steps and room for only 19 states: the stride doubles several times during the sweep.
  Pendulum problem;
  const IntegratorOptions options = adaptiveTrBdf2();
  const GradientResult reference = fullReference(problem, pendulumParameters(), options);
  ScratchDirectory dir;
  MultilevelStorage storage(levels(200, 240, dir.path()));
  const GradientResult result = computeGradient(problem, pendulumParameters(), options, storage);
  EXPECT_TRUE(bitwiseEqual(result, reference));
  EXPECT_GE(storage.stride(), 8) << result.summary.steps << " steps";
  EXPECT_LE(storage.counters().statesStored, 19);
  EXPECT_LE(storage.counters().peakBytesInMemory, 200);
}

// A cheap deterministic "integrator" for direct tests of the protocol.
struct AffineRecomputer final : StepRecomputer {
  std::int64_t calls = 0;
  void advance(std::int64_t step, VectorRef z) override {
    ++calls;
    z = 1.0001 * z + Vector::Constant(z.size(), static_cast<double>(step));
  }
};

TEST(MultilevelStorage, RestoresEveryStateOfARecordedSequence) {
  for (bool knownLength : {true, false}) {
    for (std::int64_t ram : {64, 160, 1000, 100000}) {
      SCOPED_TRACE("ram " + std::to_string(ram) + (knownLength ? ", N known" : ", N unknown"));
      ScratchDirectory dir;
      MultilevelStorage storage(levels(ram, 400, dir.path()));
      storage.setVerifyRestores(true);
      AffineRecomputer recomputer;
      TrajectoryInfo info;
      info.stateSize = 2;
      info.t1 = 1.0;
      const std::int64_t steps = 333;
      info.stepCount = knownLength ? steps : -1;
      storage.begin(info, recomputer);
      std::vector<Vector> states;
      Vector z = Eigen::Vector2d(0.5, -1.25);
      for (std::int64_t step = 0; step < steps; ++step) {
        states.push_back(z);
        storage.record(step, step * 0.003, z, z);
        recomputer.advance(step, z);
      }
      storage.finish(steps, 1.0, z, z);
      recomputer.calls = 0;
      for (std::int64_t step = steps - 1; step >= 0; --step) {
        storage.restore(step, z);
        ASSERT_EQ(std::memcmp(z.data(), states[static_cast<std::size_t>(step)].data(), 16), 0) << step;
      }
      EXPECT_EQ(recomputer.calls, storage.counters().recomputedSteps);
      EXPECT_LE(storage.counters().peakBytesInMemory, ram);
      if (ram == 100000) EXPECT_EQ(recomputer.calls, 0);
    }
  }
}

TEST(MultilevelStorage, KeptFileHoldsTheDiskLevelAndFaultsAreStorageErrors) {
  Pendulum problem;
  {
    ScratchDirectory dir;
    MultilevelStorage::Options options = levels(8000, 1 << 20, dir.path());
    options.keepFile = true;
    MultilevelStorage storage(options);
    computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
    ASSERT_FALSE(storage.filePath().empty());
    EXPECT_TRUE(std::filesystem::exists(storage.filePath()));
    EXPECT_EQ(dir.entryCount(), 1u);
  }
  {
    ScratchDirectory dir;
    MultilevelStorage::Options options = levels(8000, 1 << 20, dir.path());
    options.failWriteAfterChunks = 2;
    MultilevelStorage storage(options);
    try {
      computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
      ADD_FAILURE() << "no StorageError";
    } catch (const StorageError& e) {
      EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
      EXPECT_NE(e.path().find(dir.path() + "/hindsight-multilevel-"), std::string::npos) << e.what();
    }
  }
  {
    MultilevelStorage storage(levels(8000, 1 << 20, "/proc"));
    EXPECT_THROW(computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage), StorageError);
  }
  {
    MultilevelStorage storage(levels(10, 10, "/tmp"));  // not a single 16-byte state fits
    EXPECT_THROW(computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage), StorageError);
  }
}

TEST(MultilevelStorage, SpecStringsRoundTripThroughTheFactory) {
  ScratchDirectory dir;
  const std::string spec = "multilevel:ram=65536,disk=1048576,dir=" + dir.path() + ",level=5,keep=true";
  EXPECT_EQ(createStorage(spec)->spec(), spec);
  EXPECT_EQ(createStorage("multilevel:ram=64KiB,disk=1MiB")->spec(), "multilevel:ram=65536,disk=1048576");
  EXPECT_TRUE(createStorage("multilevel:ram=64KiB,disk=1MiB")->isExact());
  EXPECT_THROW(createStorage("multilevel:ram=64KiB"), std::invalid_argument);
  EXPECT_THROW(createStorage("multilevel:disk=64KiB"), std::invalid_argument);
  EXPECT_THROW(createStorage("multilevel:ram=-5,disk=1MiB"), std::invalid_argument);
  EXPECT_THROW(createStorage("multilevel:ram=1MiB,disk=1MiB,level=0"), std::invalid_argument);
  const std::string planned = "multilevel:ram=65536,disk=1048576,costs=0.001:0.002:0.0001:0.0001";
  const std::string written = createStorage(planned)->spec();  // shortest text of each double
  EXPECT_EQ(createStorage(written)->spec(), written);
  auto reread = createStorage(written);
  const auto& costs = *dynamic_cast<MultilevelStorage&>(*reread).options().costs;
  EXPECT_EQ(costs.forwardStep, 0.001);
  EXPECT_EQ(costs.adjointStep, 0.002);
  EXPECT_EQ(costs.diskWrite, 0.0001);
  EXPECT_EQ(costs.diskRead, 0.0001);
  EXPECT_EQ(createStorage("multilevel:ram=64KiB,disk=1MiB,schedule=stride")->spec(),
            "multilevel:ram=65536,disk=1048576,schedule=stride");
  EXPECT_THROW(createStorage("multilevel:ram=1MiB,disk=1MiB,schedule=revolve"), std::invalid_argument);
  EXPECT_EQ(createStorage("multilevel:ram=64KiB,disk=1MiB,overlap=0")->spec(),
            "multilevel:ram=65536,disk=1048576,overlap=0");
  EXPECT_EQ(createStorage("multilevel:ram=64KiB,disk=1MiB,overlap=1")->spec(),
            "multilevel:ram=65536,disk=1048576");
  EXPECT_THROW(createStorage("multilevel:ram=64KiB,disk=1MiB,overlap=2"), std::invalid_argument);
  EXPECT_EQ(createStorage("multilevel:ram=64KiB,disk=1MiB,sync=1,overlap=0")->spec(),
            "multilevel:ram=65536,disk=1048576,overlap=0,sync=1");
  EXPECT_THROW(createStorage("multilevel:ram=1MiB,disk=1MiB,costs=1:1:1"), std::invalid_argument);
  // disk=0: refused with a pointer to the strategies for RAM alone.
  for (const std::string zero : {"0", "0B", "0KiB", "0.0GiB"}) {
    try {
      createStorage("multilevel:ram=1MiB,disk=" + zero);
      ADD_FAILURE() << "disk=" << zero << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("multilevel.disk"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("binomial"), std::string::npos) << e.what();
    }
  }
}

// ---- schedule=optimal (the default) ----

MultilevelStorage::Options planned(std::int64_t ram, std::int64_t disk, const std::string& directory,
                                   std::optional<ScheduleCosts> costs) {
  MultilevelStorage::Options options;
  options.ramBytes = ram;
  options.diskBytes = disk;
  options.directory = directory;
  options.costs = costs;
  return options;
}

TEST(MultilevelPlan, BitwiseIdenticalToFullWithinBothBudgetsForMeasuredAndGivenCosts) {
  Pendulum problem;
  const GradientResult reference = fullReference(problem, pendulumParameters(), fixedStepRk4());
  const std::optional<ScheduleCosts> costChoices[] = {
      std::nullopt, ScheduleCosts{1, 1, 0, 0}, ScheduleCosts{1, 1, 0.3, 0.3}, ScheduleCosts{1, 1, 50, 50}};
  for (const Case& c : kCases) {
    for (const auto& costs : costChoices) {
      for (const bool overlap : {false, true}) {
        SCOPED_TRACE(std::string(c.name) + ", costs " + (costs ? costs->text() : "measured") +
                     (overlap ? ", overlapped I/O" : ", synchronous I/O"));
        ScratchDirectory dir;
        MultilevelStorage::Options options = planned(c.ram, c.disk, dir.path(), costs);
        options.overlap = overlap;
        MultilevelStorage storage(options);
        storage.setVerifyRestores(true);
        const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
        EXPECT_TRUE(bitwiseEqual(result, reference));
        // With overlap every disk read is served by the read-ahead the plan's lookahead started.
        EXPECT_EQ(storage.prefetchedReads(), overlap ? storage.diskReads() : 0);
        if (!overlap) EXPECT_EQ(storage.hiddenSeconds(), 0.0);
        ASSERT_TRUE(storage.usesPlan());
        EXPECT_LE(storage.counters().peakBytesInMemory, c.ram);
        EXPECT_LE(storage.plan().diskSlotsUsed() * 16, c.disk);
        EXPECT_EQ(storage.diskWrites() > 0, storage.plan().diskSlotsUsed() > 0);
        EXPECT_EQ(storage.diskReads(), storage.plan().counts().diskReads);
        EXPECT_EQ(result.summary.recomputedSteps, storage.plan().counts().recomputedSteps);
        EXPECT_GE(storage.measuredSeconds(), 0.0);
        if (!costs) EXPECT_GT(storage.costs().forwardStep, 0.0);
        EXPECT_EQ(dir.entryCount(), 0u);  // the slot file is gone after the backward sweep
        ::testing::Test::RecordProperty(std::string(c.name) + " " + (costs ? costs->text() : "measured"),
                                        storage.plan().describe() + "; recomputed " +
                                            std::to_string(result.summary.recomputedSteps) +
                                            "; disk writes " + std::to_string(storage.diskWrites()) +
                                            "; predicted s " + std::to_string(storage.predictedSeconds()) +
                                            "; measured s " + std::to_string(storage.measuredSeconds()));
      }
    }
  }
}

TEST(MultilevelPlan, CheapDiskBeatsTheStrideAndAdaptiveStepsKeepTheStride) {
  Pendulum problem;
  ScratchDirectory dir;
  // 8000 bytes of RAM (500 states), 12000 of disk: the stride recomputes; the plan far less.
  MultilevelStorage stride(levels(8000, 12000, dir.path()));
  MultilevelStorage plan(planned(8000, 12000, dir.path(), ScheduleCosts{1, 1, 0.1, 0.1}));
  const GradientResult a = computeGradient(problem, pendulumParameters(), fixedStepRk4(), stride);
  const GradientResult b = computeGradient(problem, pendulumParameters(), fixedStepRk4(), plan);
  EXPECT_TRUE(bitwiseEqual(a, b));
  EXPECT_LT(b.summary.recomputedSteps, a.summary.recomputedSteps);
  MultilevelStorage adaptive(planned(8000, 12000, dir.path(), ScheduleCosts{1, 1, 0.1, 0.1}));
  computeGradient(problem, pendulumParameters(), adaptiveTrBdf2(), adaptive);
  EXPECT_FALSE(adaptive.usesPlan());
}

TEST(MultilevelPlan, KeptSlotFileAndFaultsAreStorageErrors) {
  Pendulum problem;
  const ScheduleCosts cheap{1, 1, 0.01, 0.01};
  {
    ScratchDirectory dir;
    MultilevelStorage::Options options = planned(800, 1 << 20, dir.path(), cheap);
    options.keepFile = true;
    MultilevelStorage storage(options);
    computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
    ASSERT_FALSE(storage.filePath().empty());
    EXPECT_TRUE(std::filesystem::exists(storage.filePath()));
    EXPECT_EQ(dir.entryCount(), 1u);
  }
  for (const bool overlap : {false, true}) {  // a full disk on the I/O thread surfaces on the caller's
    SCOPED_TRACE(overlap);
    ScratchDirectory dir;
    MultilevelStorage::Options options = planned(800, 1 << 20, dir.path(), cheap);
    options.failWriteAfterChunks = 2;
    options.overlap = overlap;
    {
      MultilevelStorage storage(options);
      try {
        computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
        ADD_FAILURE() << "no StorageError";
      } catch (const StorageError& e) {
        EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
        EXPECT_NE(e.path().find(dir.path() + "/hindsight-multilevel-"), std::string::npos) << e.what();
      }
    }
    EXPECT_EQ(dir.entryCount(), 0u);  // removed with the storage
  }
  {
    MultilevelStorage storage(planned(800, 1 << 20, "/proc", cheap));
    EXPECT_THROW(computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage), StorageError);
    MultilevelStorage measured(planned(800, 1 << 20, "/proc", std::nullopt));
    EXPECT_THROW(computeGradient(problem, pendulumParameters(), fixedStepRk4(), measured), StorageError);
  }
  {
    MultilevelStorage storage(planned(10, 10, "/tmp", cheap));  // not a single 16-byte state fits
    EXPECT_THROW(computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage), StorageError);
  }
  for (const std::int64_t ram : {16, 32}) {
    // One or two states of RAM and no costs=: the run still plans, timing the forward step from the first
    // two records (it took the stride before, a thousand times more recomputation on the rod), and its
    // plan is the one its measured costs choose.
    SCOPED_TRACE(ram);
    ScratchDirectory dir;
    MultilevelStorage tiny(planned(ram, 1 << 20, dir.path(), std::nullopt));
    tiny.setVerifyRestores(true);
    const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), tiny);
    ASSERT_TRUE(tiny.usesPlan());
    EXPECT_GT(tiny.costs().forwardStep, 0.0);
    EXPECT_TRUE(bitwiseEqual(result, fullReference(problem, pendulumParameters(), fixedStepRk4())));
    EXPECT_LE(tiny.counters().peakBytesInMemory, ram);
    const TwoLevelPlan same = TwoLevelPlan::choose(2000, ram / 16, (1 << 20) / 16, tiny.costs());
    EXPECT_EQ(result.summary.recomputedSteps, same.counts().recomputedSteps) << tiny.plan().describe();
    EXPECT_EQ(dir.entryCount(), 0u);
  }
}

// ---- integrity of the disk level and scratch files of killed runs ----

void flipByte(const std::string& path, std::int64_t offset) {
  std::fstream stream(path, std::ios::in | std::ios::out | std::ios::binary);
  ASSERT_TRUE(stream.good()) << path;
  stream.seekg(offset);
  char byte = 0;
  stream.read(&byte, 1);
  byte = static_cast<char>(byte ^ 0x5a);
  stream.seekp(offset);
  stream.write(&byte, 1);
}

std::string storageErrorOf(MultilevelStorage& storage) {
  Pendulum problem;
  storage.setVerifyRestores(false);  // the storage itself must notice
  try {
    computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
  } catch (const StorageError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no StorageError: the corrupted disk level gave a gradient";
  return {};
}

TEST(MultilevelPlan, CorruptedSlotIsAStorageErrorNamingTheFileAndTheSlot) {
  const ScheduleCosts cheap{1, 1, 0.01, 0.01};  // a plan with disk slots
  const std::int64_t record = 16 + 16;          // pendulum state + index + checksum
  // One byte of the state, of the index and of the checksum of slot 1; one byte in every slot.
  for (std::int64_t offset : {record + 3, record + 16, record + 31, std::int64_t{-1}}) {
    SCOPED_TRACE(offset);
    ScratchDirectory dir;
    MultilevelStorage::Options options = planned(800, 1 << 20, dir.path(), cheap);
    options.afterForwardSweep = [offset, record](const std::string& path) {
      const std::int64_t size = static_cast<std::int64_t>(std::filesystem::file_size(path));
      ASSERT_GE(size, 2 * record);
      ASSERT_EQ(size % record, 0);
      if (offset >= 0) {
        flipByte(path, offset);
      } else {
        for (std::int64_t slot = 0; slot < size / record; ++slot) flipByte(path, slot * record + 5);
      }
    };
    {
      MultilevelStorage storage(options);
      const std::string message = storageErrorOf(storage);
      EXPECT_NE(message.find("is corrupted"), std::string::npos) << message;
      if (offset >= 0) EXPECT_NE(message.find("slot 1 "), std::string::npos) << message;
      EXPECT_NE(message.find("[file: " + dir.path() + "/hindsight-multilevel-"), std::string::npos)
          << message;
    }
    EXPECT_EQ(dir.entryCount(), 0u);  // the slot file is removed with the storage
  }
  // Unchanged slots read back as written: the checksums cost no bit.
  ScratchDirectory dir;
  MultilevelStorage storage(planned(800, 1 << 20, dir.path(), cheap));
  Pendulum problem;
  EXPECT_TRUE(bitwiseEqual(computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage),
                           fullReference(problem, pendulumParameters(), fixedStepRk4())));
  EXPECT_GT(storage.diskReads(), 0);
}

TEST(MultilevelStorage, CorruptedStrideFileIsAStorageErrorNamingTheFile) {
  ScratchDirectory dir;
  MultilevelStorage::Options options = levels(8000, 1 << 20, dir.path());
  options.afterForwardSweep = [](const std::string& path) {
    haddr_t address = 0;
    hsize_t size = 0;
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hid_t states = H5Dopen2(file, "states", H5P_DEFAULT);
    const hid_t space = H5Dget_space(states);
    hsize_t offset[2];
    unsigned mask = 0;
    ASSERT_GE(H5Dget_chunk_info(states, space, 0, offset, &mask, &address, &size), 0);
    H5Sclose(space);
    H5Dclose(states);
    H5Fclose(file);
    flipByte(path, static_cast<std::int64_t>(address + size / 2));
  };
  MultilevelStorage storage(options);
  const std::string message = storageErrorOf(storage);
  EXPECT_NE(message.find("[file: " + dir.path() + "/hindsight-multilevel-"), std::string::npos) << message;
}

// The PID of a process that has ended (and been reaped).
pid_t deadPid() {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);
  return child;
}

TEST(ScratchFiles, FilesOfDeadProcessesOfThisHostAreRemovedAtTheNextStart) {
  using internal::isStaleScratchFile;
  using internal::scratchHostTag;
  const std::string dead = std::to_string(deadPid());
  const std::string live = std::to_string(::getpid());
  const std::string host = scratchHostTag();
  ASSERT_EQ(host.size(), 8u);
  const std::string stale[] = {"hindsight-" + dead + "-" + host + "-0-123.h5",
                               "hindsight-multilevel-" + dead + "-" + host + "-7-99.h5",
                               "hindsight-multilevel-" + dead + "-" + host + "-3-42.slots"};
  const std::string kept[] = {
      "hindsight-" + live + "-" + host + "-0-123.h5",          // a running process's
      "hindsight-multilevel-" + dead + "-kept-1-5.slots",      // kept on purpose (keep=true)
      "hindsight-multilevel-" + dead + "-0badc0de-1-5.slots",  // another host's
      "hindsight-multilevel-" + dead + "-3.slots",             // the older naming
      "hindsight-" + dead + "-" + host + "-0-123.h5.txt",      // not a scratch file
      "results.h5",
  };
  for (const std::string& name : stale) EXPECT_TRUE(isStaleScratchFile(name)) << name;
  for (const std::string& name : kept) EXPECT_FALSE(isStaleScratchFile(name)) << name;
  if (host == "0badc0de") GTEST_SKIP() << "this host's tag is the test's other host";

  for (const bool slots : {true, false}) {  // the slot file and the chunked file clean up alike
    ScratchDirectory dir;
    for (const std::string& name : stale) std::ofstream(dir.path() + "/" + name) << "x";
    for (const std::string& name : kept) std::ofstream(dir.path() + "/" + name) << "x";
    MultilevelStorage::Options options =
        slots ? planned(800, 1 << 20, dir.path(), ScheduleCosts{1, 1, 0.01, 0.01})
              : levels(8000, 1 << 20, dir.path());
    MultilevelStorage storage(options);
    Pendulum problem;
    computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
    EXPECT_FALSE(storage.filePath().empty());
    for (const std::string& name : stale)
      EXPECT_FALSE(std::filesystem::exists(dir.path() + "/" + name)) << name;
    for (const std::string& name : kept)
      EXPECT_TRUE(std::filesystem::exists(dir.path() + "/" + name)) << name;
  }
}

}  // namespace
}  // namespace hindsight
