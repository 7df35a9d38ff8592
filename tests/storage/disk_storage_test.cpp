// Strategy "disk": bitwise-identical gradients to "full", the byte budget, a self-describing HDF5 file
// readable with the plain HDF5 API, compression, and every fault turned into a StorageError that
// names the file (unwritable directory, full disk, truncated file, corrupted chunk).
#include <hindsight/storage/chunked_state_file.h>
#include <hindsight/storage/disk_storage.h>
#include <hindsight/storage/storage_factory.h>
#include <hindsight/storage/time_codec.h>
#include "support/storage_fixtures.h"

#include <hdf5.h>
#include <sys/mount.h>
#include <unistd.h>

#include <zstd.h>

#include <fstream>
#include <random>

namespace hindsight {
namespace {

using testing::adaptiveTrBdf2;
using testing::bitwiseEqual;
using testing::fixedStepRk4;
using testing::fullReference;
using testing::pendulumParameters;
using testing::sameBits;
using testing::ScratchDirectory;

DiskStorage::Options diskOptions(const std::string& directory, std::int64_t chunk = 64) {
  DiskStorage::Options options;
  options.directory = directory;
  options.chunkStates = chunk;
  return options;
}

// Runs computeGradient and returns the StorageError's message; fails the test when none is thrown.
std::string storageErrorOf(TrajectoryStorage& storage, const IntegratorOptions& options) {
  Pendulum problem;
  try {
    computeGradient(problem, pendulumParameters(), options, storage);
  } catch (const StorageError& e) {
    ::testing::Test::RecordProperty("message", e.what());
    return e.what();
  }
  ADD_FAILURE() << "no StorageError";
  return {};
}

TEST(DiskStorage, BitwiseIdenticalToFullWithFixedAndAdaptiveSteps) {
  Pendulum problem;
  for (const IntegratorOptions& options : {fixedStepRk4(), adaptiveTrBdf2()}) {
    const GradientResult reference = fullReference(problem, pendulumParameters(), options);
    for (std::int64_t chunk : {1, 7, 64, 0}) {
      ScratchDirectory dir;
      DiskStorage storage(diskOptions(dir.path(), chunk));
      storage.setVerifyRestores(true);
      const GradientResult result = computeGradient(problem, pendulumParameters(), options, storage);
      EXPECT_TRUE(bitwiseEqual(result, reference)) << options.method << ", chunk " << chunk;
      EXPECT_EQ(result.summary.recomputedSteps, 0);
      EXPECT_EQ(result.summary.statesStored, result.summary.steps);
      EXPECT_GT(result.summary.bytesOnDisk, 0);
      EXPECT_EQ(storage.counters().bytesInMemory, 0);
      EXPECT_EQ(dir.entryCount(), 0u) << "the file must be removed after the backward sweep";
    }
  }
}

TEST(DiskStorage, NeverExceedsItsBudget) {
  Pendulum problem;
  const IntegratorOptions options = fixedStepRk4();
  const GradientResult reference = fullReference(problem, pendulumParameters(), options);
  // A row is 3 doubles (2 state values and the time): 24 bytes; 64-state chunks are 1536 bytes.
  for (std::int64_t budget : {1536, 3000, 4608, 100000}) {
    ScratchDirectory dir;
    DiskStorage::Options o = diskOptions(dir.path(), 64);
    o.budgetBytes = budget;
    DiskStorage storage(o);
    const GradientResult result = computeGradient(problem, pendulumParameters(), options, storage);
    EXPECT_TRUE(bitwiseEqual(result, reference)) << "budget " << budget;
    EXPECT_LE(storage.counters().peakBytesInMemory, budget);
    EXPECT_GT(storage.counters().peakBytesInMemory, 0);
  }
  // Far below what full storage needs (2001 x 16 bytes).
  ScratchDirectory dir;
  DiskStorage::Options o = diskOptions(dir.path(), 0);
  o.budgetBytes = 1000;
  DiskStorage storage(o);
  const GradientResult result = computeGradient(problem, pendulumParameters(), options, storage);
  EXPECT_TRUE(bitwiseEqual(result, reference));
  EXPECT_LE(storage.counters().peakBytesInMemory, 1000);
}

TEST(DiskStorage, BudgetTooSmallForOneChunkIsAStorageError) {
  ScratchDirectory dir;
  DiskStorage::Options o = diskOptions(dir.path(), 64);
  o.budgetBytes = 1000;  // one 64-state chunk needs 1536 bytes
  DiskStorage storage(o);
  const std::string message = storageErrorOf(storage, fixedStepRk4());
  EXPECT_NE(message.find("budget"), std::string::npos) << message;
}

// Reads a scalar attribute of the root group with the plain HDF5 API.
template <typename T>
T readAttribute(hid_t file, const char* name, hid_t type) {
  T value{};
  const hid_t attribute = H5Aopen(file, name, H5P_DEFAULT);
  EXPECT_GE(attribute, 0) << name;
  EXPECT_GE(H5Aread(attribute, type, &value), 0) << name;
  H5Aclose(attribute);
  return value;
}

std::string readStringAttribute(hid_t file, const char* name) {
  const hid_t attribute = H5Aopen(file, name, H5P_DEFAULT);
  EXPECT_GE(attribute, 0) << name;
  const hid_t type = H5Aget_type(attribute);
  std::string value(H5Tget_size(type), '\0');
  EXPECT_GE(H5Aread(attribute, type, value.data()), 0) << name;
  H5Tclose(type);
  H5Aclose(attribute);
  return value.substr(0, value.find('\0'));
}

TEST(DiskStorage, KeptFileIsSelfDescribingAndHoldsTheTrajectoryBitForBit) {
  Pendulum problem;
  const IntegratorOptions options = adaptiveTrBdf2();
  ScratchDirectory dir;
  DiskStorage::Options o = diskOptions(dir.path(), 16);
  o.keepFile = true;
  o.timeCodec = false;  // codec=zstd: the older format (the time codec's file: below)
  DiskStorage storage(o);
  std::vector<double> observed;
  const GradientResult result = computeGradient(
      problem, pendulumParameters(), options, storage, [&](std::int64_t, double, ConstVectorRef z) {
        observed.insert(observed.end(), z.data(), z.data() + z.size());
      });
  ASSERT_TRUE(std::filesystem::exists(storage.filePath()));
  EXPECT_EQ(std::filesystem::path(storage.filePath()).parent_path(), std::filesystem::path(dir.path()));
  EXPECT_EQ(result.summary.bytesOnDisk,
            static_cast<std::int64_t>(std::filesystem::file_size(storage.filePath())));

  ASSERT_TRUE(internal::ensureZstdFilter());
  EXPECT_GT(H5Zfilter_avail(32015), 0);
  const hid_t file = H5Fopen(storage.filePath().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const std::int64_t steps = result.summary.steps;
  EXPECT_EQ(readStringAttribute(file, "problem"), "pendulum");
  EXPECT_EQ(readStringAttribute(file, "hindsightVersion"), std::string(version()));
  EXPECT_EQ(readStringAttribute(file, "format"), "hindsight trajectory 1");
  EXPECT_EQ(readAttribute<std::int64_t>(file, "stateSize", H5T_NATIVE_INT64), 2);
  EXPECT_EQ(readAttribute<std::int64_t>(file, "stepCount", H5T_NATIVE_INT64), steps);
  EXPECT_EQ(readAttribute<std::int64_t>(file, "chunkStates", H5T_NATIVE_INT64), 16);
  EXPECT_EQ(readAttribute<double>(file, "t0", H5T_NATIVE_DOUBLE), 0.0);
  EXPECT_EQ(readAttribute<double>(file, "t1", H5T_NATIVE_DOUBLE), 4.0);

  // /states: (N+1) x 2 through shuffle, zstd 32015 and Fletcher32, equal to the observed states.
  const hid_t states = H5Dopen2(file, "states", H5P_DEFAULT);
  ASSERT_GE(states, 0);
  const hid_t space = H5Dget_space(states);
  hsize_t dims[2] = {0, 0};
  H5Sget_simple_extent_dims(space, dims, nullptr);
  EXPECT_EQ(dims[0], static_cast<hsize_t>(steps + 1));
  EXPECT_EQ(dims[1], 2u);
  const hid_t dcpl = H5Dget_create_plist(states);
  std::vector<H5Z_filter_t> filters;
  for (int i = 0; i < H5Pget_nfilters(dcpl); ++i) {
    unsigned flags = 0;
    size_t count = 4;
    unsigned values[4] = {0, 0, 0, 0};
    char name[64];
    unsigned config = 0;
    filters.push_back(
        H5Pget_filter2(dcpl, static_cast<unsigned>(i), &flags, &count, values, sizeof name, name, &config));
    if (filters.back() == 32015) {
      EXPECT_EQ(count, 1u);
      EXPECT_EQ(values[0], 3u) << "cd_values[0] is the zstd level";
    }
  }
  EXPECT_EQ(filters, (std::vector<H5Z_filter_t>{H5Z_FILTER_SHUFFLE, 32015, H5Z_FILTER_FLETCHER32}));
  std::vector<double> stored(static_cast<std::size_t>(dims[0] * dims[1]));
  ASSERT_GE(H5Dread(states, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, stored.data()), 0);
  ASSERT_EQ(stored.size(), observed.size());
  EXPECT_TRUE(sameBits(stored.data(), observed.data(), static_cast<Eigen::Index>(stored.size())));

  const hid_t times = H5Dopen2(file, "times", H5P_DEFAULT);
  ASSERT_GE(times, 0);
  std::vector<double> storedTimes(result.times.size());
  const hid_t timeSpace = H5Dget_space(times);
  EXPECT_EQ(H5Sget_simple_extent_npoints(timeSpace), static_cast<hssize_t>(result.times.size()));
  ASSERT_GE(H5Dread(times, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, storedTimes.data()), 0);
  EXPECT_EQ(storedTimes, result.times);
  H5Sclose(timeSpace);
  H5Dclose(times);
  H5Pclose(dcpl);
  H5Sclose(space);
  H5Dclose(states);
  H5Fclose(file);
}

// What the registered zstd plugin (id 32015) decodes: each stored chunk, read raw, is one standard
// zstd frame (plus Fletcher32's 4 checksum bytes), and decompressing it with plain libzstd and
// undoing the byte shuffle gives the states. No HDF5 filter of ours is involved in this check.
TEST(DiskStorage, StoredChunksAreStandardZstdFramesOfShuffledStates) {
  Pendulum problem;
  ScratchDirectory dir;
  DiskStorage::Options o = diskOptions(dir.path(), 16);
  o.keepFile = true;
  o.timeCodec = false;
  DiskStorage storage(o);
  std::vector<double> observed;
  const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage,
                                                [&](std::int64_t, double, ConstVectorRef z) {
                                                  observed.insert(observed.end(), z.data(), z.data() + 2);
                                                });
  const hid_t file = H5Fopen(storage.filePath().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const hid_t states = H5Dopen2(file, "states", H5P_DEFAULT);
  const std::int64_t rows = result.summary.steps + 1;
  const std::size_t chunkValues = 16 * 2;
  for (hsize_t chunk = 0; chunk * 16 < static_cast<hsize_t>(rows); ++chunk) {
    const hsize_t offset[2] = {chunk * 16, 0};
    hsize_t size = 0;
    ASSERT_GE(H5Dget_chunk_storage_size(states, offset, &size), 0);
    std::vector<unsigned char> raw(size);
    std::uint32_t mask = 0;
    ASSERT_GE(H5Dread_chunk(states, H5P_DEFAULT, offset, &mask, raw.data()), 0);
    EXPECT_EQ(mask, 0u) << "no filter skipped";
    ASSERT_GT(size, 4u);
    std::vector<unsigned char> shuffled(chunkValues * 8);
    const std::size_t produced = ZSTD_decompress(shuffled.data(), shuffled.size(), raw.data(), size - 4);
    ASSERT_FALSE(ZSTD_isError(produced)) << ZSTD_getErrorName(produced);
    ASSERT_EQ(produced, shuffled.size());
    EXPECT_EQ(ZSTD_getFrameContentSize(raw.data(), size - 4), shuffled.size());
    std::vector<double> values(chunkValues);
    auto* bytes = reinterpret_cast<unsigned char*>(values.data());
    for (std::size_t i = 0; i < chunkValues; ++i) {
      for (std::size_t b = 0; b < 8; ++b) bytes[i * 8 + b] = shuffled[b * chunkValues + i];
    }
    const std::size_t first = static_cast<std::size_t>(chunk) * chunkValues;
    const std::size_t count = std::min(chunkValues, observed.size() - first);
    EXPECT_TRUE(sameBits(values.data(), observed.data() + first, static_cast<Eigen::Index>(count)))
        << "chunk " << chunk;
  }
  H5Dclose(states);
  H5Fclose(file);
}

TEST(DiskStorage, CompressesASmoothTrajectory) {
  Pendulum problem;
  ScratchDirectory dir;
  DiskStorage storage(diskOptions(dir.path(), 512));
  const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage);
  EXPECT_GT(result.summary.compressionRatio, 1.0);
  EXPECT_EQ(storage.counters().uncompressedBytes, (result.summary.steps + 1) * 16);
  EXPECT_LT(storage.counters().compressedBytes, storage.counters().uncompressedBytes);
  EXPECT_GT(storage.counters().ioSeconds, 0.0);
}

TEST(DiskStorage, EachRunHasItsOwnFile) {
  Pendulum problem;
  ScratchDirectory dir;
  DiskStorage::Options o = diskOptions(dir.path());
  o.keepFile = true;
  DiskStorage first(o), second(o);
  computeGradient(problem, pendulumParameters(), fixedStepRk4(), first);
  computeGradient(problem, pendulumParameters(), fixedStepRk4(), second);
  const std::string firstRun = first.filePath();
  computeGradient(problem, pendulumParameters(), fixedStepRk4(), first);
  EXPECT_NE(first.filePath(), second.filePath());
  EXPECT_NE(first.filePath(), firstRun);
  EXPECT_EQ(dir.entryCount(), 3u);
}

TEST(DiskStorage, SpecStringsRoundTripThroughTheFactory) {
  ScratchDirectory dir;
  const std::string spec = "disk:dir=" + dir.path() + ",level=7,chunk=32,budget=1048576,keep=true";
  EXPECT_EQ(createStorage(spec)->spec(), spec);
  EXPECT_EQ(createStorage("disk:dir=" + dir.path())->spec(), "disk:dir=" + dir.path());
  EXPECT_TRUE(createStorage("disk:dir=" + dir.path())->isExact());
  EXPECT_THROW(createStorage("disk"), std::invalid_argument);
  EXPECT_THROW(createStorage("disk:dir=" + dir.path() + ",level=23"), std::invalid_argument);
  EXPECT_THROW(createStorage("disk:dir=" + dir.path() + ",chunk=0"), std::invalid_argument);
  EXPECT_THROW(createStorage("disk:dir=" + dir.path() + ",keep=maybe"), std::invalid_argument);
  EXPECT_THROW(createStorage("disk:dir=" + dir.path() + ",colour=blue"), std::invalid_argument);
  const std::string zstd = "disk:dir=" + dir.path() + ",codec=zstd";
  EXPECT_EQ(createStorage(zstd)->spec(), zstd);
  EXPECT_EQ(createStorage("disk:dir=" + dir.path() + ",codec=time")->spec(), "disk:dir=" + dir.path());
  EXPECT_THROW(createStorage("disk:dir=" + dir.path() + ",codec=zfp"), std::invalid_argument);
}

// The default codec (time): /states and /times go through filter 306 (cd_values: values per row,
// order, zstd level) and Fletcher32; read back through the plain HDF5 API with the filter registered,
// they hold the observed trajectory bit for bit; both codecs give full storage's gradient bit for bit,
// and the time codec needs fewer bytes than shuffle + zstd on a smooth trajectory.
TEST(DiskStorage, TimeCodecFileHoldsTheTrajectoryBitForBitInFewerBytes) {
  Pendulum problem;
  const GradientResult reference = fullReference(problem, pendulumParameters(), fixedStepRk4());
  ScratchDirectory dir;
  std::int64_t bytes[2] = {0, 0};
  for (bool time : {true, false}) {
    DiskStorage::Options o = diskOptions(dir.path(), 256);
    o.keepFile = true;
    o.timeCodec = time;
    DiskStorage storage(o);
    std::vector<double> observed;
    const GradientResult result = computeGradient(problem, pendulumParameters(), fixedStepRk4(), storage,
                                                  [&](std::int64_t, double, ConstVectorRef z) {
                                                    observed.insert(observed.end(), z.data(), z.data() + 2);
                                                  });
    EXPECT_TRUE(bitwiseEqual(result, reference)) << (time ? "time" : "zstd");
    bytes[time ? 0 : 1] = storage.counters().compressedBytes;
    ASSERT_TRUE(internal::ensureTimeCodecFilter());
    const hid_t file = H5Fopen(storage.filePath().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    EXPECT_EQ(readStringAttribute(file, "codec"), time ? "time" : "zstd");
    const hid_t states = H5Dopen2(file, "states", H5P_DEFAULT);
    if (time) {
      const hid_t dcpl = H5Dget_create_plist(states);
      ASSERT_EQ(H5Pget_nfilters(dcpl), 2);
      unsigned flags = 0;
      size_t count = 4;
      unsigned values[4] = {0, 0, 0, 0};
      char name[64];
      unsigned config = 0;
      EXPECT_EQ(H5Pget_filter2(dcpl, 0, &flags, &count, values, sizeof name, name, &config),
                internal::kTimeCodecFilterId);
      EXPECT_EQ(count, 3u);
      EXPECT_EQ(values[0], 2u);
      EXPECT_EQ(values[1], static_cast<unsigned>(internal::TimeCodec::kLosslessOrder));
      EXPECT_EQ(values[2], 3u);
      EXPECT_EQ(H5Pget_filter2(dcpl, 1, &flags, &count, values, sizeof name, name, &config),
                H5Z_FILTER_FLETCHER32);
      H5Pclose(dcpl);
    }
    std::vector<double> stored(observed.size());
    ASSERT_GE(H5Dread(states, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, stored.data()), 0);
    EXPECT_TRUE(sameBits(stored.data(), observed.data(), static_cast<Eigen::Index>(stored.size())));
    const hid_t times = H5Dopen2(file, "times", H5P_DEFAULT);
    std::vector<double> storedTimes(result.times.size());
    ASSERT_GE(H5Dread(times, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, storedTimes.data()), 0);
    EXPECT_EQ(storedTimes, result.times);
    H5Dclose(times);
    H5Dclose(states);
    H5Fclose(file);
  }
  EXPECT_LT(2 * bytes[0], bytes[1]) << "time codec " << bytes[0] << " bytes, shuffle + zstd " << bytes[1];
}

// ---- faults ----

TEST(DiskStorageFaults, DirectoryUnderARegularFile) {
  ScratchDirectory dir;
  const std::string regular = dir.path() + "/plain-file";
  std::ofstream(regular) << "not a directory";
  DiskStorage storage(diskOptions(regular + "/trajectories"));
  const std::string message = storageErrorOf(storage, fixedStepRk4());
  EXPECT_NE(message.find(regular + "/trajectories"), std::string::npos) << message;
}

TEST(DiskStorageFaults, UnwritableDirectory) {
  // /proc refuses new files even to root; a chmod-ed directory does so to everybody else.
  DiskStorage storage(diskOptions("/proc"));
  const std::string message = storageErrorOf(storage, fixedStepRk4());
  EXPECT_NE(message.find("cannot create the trajectory file"), std::string::npos) << message;
  EXPECT_NE(message.find("[file: /proc/hindsight-"), std::string::npos) << message;
  // A read-only mount refuses everybody, root included.
  ScratchDirectory mountPoint;
  if (::mount("tmpfs", mountPoint.path().c_str(), "tmpfs", MS_RDONLY, "size=64k") == 0) {
    DiskStorage readOnly(diskOptions(mountPoint.path()));
    const std::string readOnlyMessage = storageErrorOf(readOnly, fixedStepRk4());
    EXPECT_NE(readOnlyMessage.find("Read-only file system"), std::string::npos) << readOnlyMessage;
    EXPECT_NE(readOnlyMessage.find("[file: " + mountPoint.path() + "/hindsight-"), std::string::npos)
        << readOnlyMessage;
    ::umount(mountPoint.path().c_str());
  }
  if (::geteuid() != 0) {
    ScratchDirectory dir;
    std::filesystem::permissions(dir.path(),
                                 std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec);
    DiskStorage readOnly(diskOptions(dir.path()));
    EXPECT_NE(storageErrorOf(readOnly, fixedStepRk4()).find(dir.path()), std::string::npos);
    std::filesystem::permissions(dir.path(), std::filesystem::perms::owner_all);
  }
}

TEST(DiskStorageFaults, InjectedWriteFailureReachesTheCaller) {
  Pendulum problem;
  const GradientResult reference = fullReference(problem, pendulumParameters(), fixedStepRk4());
  for (std::int64_t failAfter : {0, 3}) {
    ScratchDirectory dir;
    {
      DiskStorage::Options o = diskOptions(dir.path(), 64);
      o.failWriteAfterChunks = failAfter;
      DiskStorage storage(o);
      const std::string message = storageErrorOf(storage, fixedStepRk4());
      EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
      EXPECT_NE(message.find("[file: " + dir.path() + "/hindsight-"), std::string::npos) << message;
      EXPECT_EQ(dir.entryCount(), 1u);
    }
    EXPECT_EQ(dir.entryCount(), 0u) << "the failed run's file is removed with its storage";
    DiskStorage healthy(diskOptions(dir.path(), 64));
    EXPECT_TRUE(
        bitwiseEqual(computeGradient(problem, pendulumParameters(), fixedStepRk4(), healthy), reference));
  }
}

// A failed background write surfaces at one of the next record() calls, not only at finish().
TEST(DiskStorageFaults, BackgroundWriteFailureStopsTheForwardSweepEarly) {
  ScratchDirectory dir;
  DiskStorage::Options o = diskOptions(dir.path(), 1);
  o.failWriteAfterChunks = 0;
  DiskStorage storage(o);
  testing::ForbiddenRecomputer recomputer;
  TrajectoryInfo info;
  info.stateSize = 4;
  info.t1 = 1.0;
  storage.begin(info, recomputer);
  Vector z = Vector::Ones(4);
  std::int64_t step = 0;
  std::string message;
  try {
    for (; step < 100000; ++step) storage.record(step, 1e-5 * step, z, z);
  } catch (const StorageError& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
  // Three one-state buffers: the fourth record (step 3) at the latest waits for a free buffer and
  // sees the failure of the first write.
  EXPECT_LE(step, 3);
  // And the storage keeps reporting it.
  EXPECT_THROW(storage.finish(step, 1.0, z, z), StorageError);
}

// A 64 KiB tmpfs that fills up: the real ENOSPC path through HDF5.
TEST(DiskStorageFaults, FullDiskOnATinyTmpfs) {
  ScratchDirectory dir;
  if (::mount("tmpfs", dir.path().c_str(), "tmpfs", 0, "size=64k") != 0) {
    GTEST_SKIP() << "cannot mount a tmpfs here (needs root): " << std::strerror(errno);
  }
  struct Unmount {
    std::string path;
    ~Unmount() { ::umount(path.c_str()); }
  } unmount{dir.path()};
  TrajectoryInfo info;
  info.problemName = "noise";
  info.stateSize = 1000;
  info.t1 = 1.0;
  info.stepCount = 200;  // 1.6 MB of incompressible doubles
  testing::ForbiddenRecomputer recomputer;
  DiskStorage storage(diskOptions(dir.path(), 4));
  std::mt19937_64 random(42);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Vector z(info.stateSize);
  std::string message;
  try {
    storage.begin(info, recomputer);
    for (std::int64_t step = 0; step < info.stepCount; ++step) {
      for (Eigen::Index i = 0; i < z.size(); ++i) z(i) = uniform(random);
      storage.record(step, step * 0.005, z, z);
    }
    storage.finish(info.stepCount, 1.0, z, z);
  } catch (const StorageError& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
  EXPECT_NE(message.find("[file: " + dir.path() + "/hindsight-"), std::string::npos) << message;
}

TEST(DiskStorageFaults, TruncatedFileIsDetected) {
  ScratchDirectory dir;
  DiskStorage::Options o = diskOptions(dir.path(), 64);
  o.afterForwardSweep = [](const std::string& path) {
    std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  };
  DiskStorage storage(o);
  storage.setVerifyRestores(false);  // the storage itself must notice
  const std::string message = storageErrorOf(storage, fixedStepRk4());
  EXPECT_NE(message.find("[file: " + dir.path() + "/hindsight-"), std::string::npos) << message;
}

// Flips bytes in the middle of the stored chunk `chunkIndex` of /states.
void corruptChunk(const std::string& path, hsize_t chunkIndex) {
  haddr_t address = 0;
  hsize_t size = 0;
  {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hid_t states = H5Dopen2(file, "states", H5P_DEFAULT);
    hsize_t offset[2];
    unsigned mask = 0;
    const hid_t space = H5Dget_space(states);
    ASSERT_GE(H5Dget_chunk_info(states, space, chunkIndex, offset, &mask, &address, &size), 0);
    ASSERT_EQ(offset[0], chunkIndex * 64);
    H5Sclose(space);
    H5Dclose(states);
    H5Fclose(file);
  }
  std::fstream stream(path, std::ios::in | std::ios::out | std::ios::binary);
  stream.seekg(static_cast<std::streamoff>(address + size / 2));
  char byte = 0;
  stream.read(&byte, 1);
  byte = static_cast<char>(byte ^ 0x5a);
  stream.seekp(static_cast<std::streamoff>(address + size / 2));
  stream.write(&byte, 1);
}

TEST(DiskStorageFaults, CorruptedChunkIsDetectedByItsChecksum) {
  for (hsize_t chunk : {hsize_t{31}, hsize_t{5}, hsize_t{0}}) {  // 2001 rows: chunks 0..31
    ScratchDirectory dir;
    DiskStorage::Options o = diskOptions(dir.path(), 64);
    o.afterForwardSweep = [chunk](const std::string& path) { corruptChunk(path, chunk); };
    DiskStorage storage(o);
    storage.setVerifyRestores(false);  // the storage itself must notice
    const std::string message = storageErrorOf(storage, fixedStepRk4());
    EXPECT_NE(message.find("cannot read rows " + std::to_string(chunk * 64)), std::string::npos) << message;
    EXPECT_NE(message.find("[file: " + dir.path() + "/hindsight-"), std::string::npos) << message;
  }
}

TEST(DiskStorage, DestroyedMidForwardSweepJoinsItsThreadAndRemovesItsFile) {
  ScratchDirectory dir;
  {
    TrajectoryInfo info;
    info.problemName = "ramp";
    info.stateSize = 3;
    info.t1 = 1.0;
    testing::ForbiddenRecomputer recomputer;
    DiskStorage storage(diskOptions(dir.path(), 4));
    storage.begin(info, recomputer);
    Vector z = Vector::Zero(3);
    for (std::int64_t step = 0; step < 50; ++step) {
      z.setConstant(static_cast<double>(step));
      storage.record(step, step * 0.01, z, z);
    }
    EXPECT_EQ(dir.entryCount(), 1u);
  }
  EXPECT_EQ(dir.entryCount(), 0u);
}

TEST(DiskStorage, RestoresAnUnknownLengthTrajectoryDirectly) {
  TrajectoryInfo info;
  info.problemName = "ramp";
  info.stateSize = 5;
  info.t1 = 1.0;
  testing::ForbiddenRecomputer recomputer;
  ScratchDirectory dir;
  DiskStorage storage(diskOptions(dir.path(), 6));
  storage.setVerifyRestores(true);
  for (int run = 0; run < 2; ++run) {  // the same object serves several runs
    storage.begin(info, recomputer);
    Vector z(5);
    const std::int64_t steps = 97 + run;
    for (std::int64_t step = 0; step < steps; ++step) {
      z = Vector::LinSpaced(5, static_cast<double>(step), static_cast<double>(step) + 1.0);
      storage.record(step, step * 0.01, z, z);
    }
    storage.finish(steps, 1.0, z, z);
    for (std::int64_t step = steps - 1; step >= 0; --step) {
      storage.restore(step, z);
      EXPECT_EQ(z(0), static_cast<double>(step));
      EXPECT_EQ(z(4), static_cast<double>(step) + 1.0);
    }
    EXPECT_EQ(dir.entryCount(), 0u);
  }
}

}  // namespace
}  // namespace hindsight
