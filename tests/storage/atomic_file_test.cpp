// The atomic write: the target is always either absent/old or complete, no temporary file survives a
// finished call (successful or not), and failures name the target.
#include <hindsight/engine/types.h>
#include <hindsight/storage/atomic_file.h>
#include "support/file_checks.h"
#include "support/storage_fixtures.h"

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace {

namespace fs = std::filesystem;
using testing::expectStorageErrorNaming;
using testing::listing;
using testing::ScratchDirectory;

std::string contentsOf(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

void writeText(const std::string& path, const std::string& text) {
  writeStreamAtomically(path, [&](std::FILE* file) -> std::string {
    return std::fputs(text.c_str(), file) >= 0 ? std::string() : std::string("fputs failed");
  });
}

// A scratch directory with the target out.txt in it.
class AtomicFile : public ::testing::Test {
 protected:
  // The target holds `contents` and nothing else (no temporary) is in the directory.
  void expectOnlyTarget(const std::string& contents) const {
    EXPECT_EQ(contentsOf(path), contents);
    EXPECT_EQ(listing(dir.path()), std::set<std::string>{"out.txt"});
  }

  ScratchDirectory dir;
  const std::string path = dir.path() + "/out.txt";
};

TEST_F(AtomicFile, CreatesTheFileAndLeavesNoTemporary) {
  writeText(path, "complete\n");
  expectOnlyTarget("complete\n");
}

TEST_F(AtomicFile, ReplacesAnExistingFileAndTheOldOneStaysUntilTheRename) {
  writeText(path, "old contents\n");
  writeStreamAtomically(path, [&](std::FILE* file) -> std::string {
    std::fputs("new, half", file);
    std::fflush(file);
    // Halfway through, a reader still finds the complete old file.
    EXPECT_EQ(contentsOf(path), "old contents\n");
    std::fputs(" and the rest\n", file);
    return {};
  });
  expectOnlyTarget("new, half and the rest\n");
}

TEST_F(AtomicFile, AFailedWriteKeepsTheOldFileAndRemovesTheTemporary) {
  writeText(path, "old contents\n");

  // A writer that reports a failure: StorageError naming the target, with the writer's reason.
  try {
    writeStreamAtomically(path, [](std::FILE* file) -> std::string {
      std::fputs("torn", file);
      return "disk full (simulated)";
    });
    ADD_FAILURE() << "no StorageError";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.path(), path);
    EXPECT_NE(std::string(e.what()).find("disk full (simulated)"), std::string::npos) << e.what();
  }
  expectOnlyTarget("old contents\n");

  // A writer that throws: its exception arrives unchanged (a caller's bad argument stays one).
  EXPECT_THROW(writeFileAtomically(path,
                                   [](const std::string& temporary) {
                                     std::ofstream(temporary) << "torn";
                                     throw std::invalid_argument("bad field");
                                   }),
               std::invalid_argument);
  expectOnlyTarget("old contents\n");
}

TEST_F(AtomicFile, AWriterByNameIsFlushedAndRenamedLikeAStream) {
  writeFileAtomically(path, [](const std::string& temporary) { std::ofstream(temporary) << "by name"; });
  expectOnlyTarget("by name");

  // A writer that creates nothing cannot be committed.
  const std::string none = dir.path() + "/none";
  expectStorageErrorNaming([&] { writeFileAtomically(none, [](const std::string&) {}); }, none);
  expectOnlyTarget("by name");
}

TEST_F(AtomicFile, AMissingDirectoryThrowsAndCreatesNothing) {
  const std::string missing = dir.path() + "/no_such_directory/out.txt";
  expectStorageErrorNaming([&] { writeText(missing, "x"); }, missing);
  EXPECT_TRUE(listing(dir.path()).empty());
}

TEST_F(AtomicFile, AReadOnlyDirectoryThrowsOrWritesCompletely) {
  // /proc refuses new files even to root.
  const std::string proc = "/proc/hindsight-atomic-file-test";
  expectStorageErrorNaming([&] { writeText(proc, "x"); }, proc);
  EXPECT_FALSE(fs::exists(proc));

  // Permission bits stop everyone but root; either way nothing torn and no temporary remains.
  ASSERT_EQ(::chmod(dir.path().c_str(), 0555), 0);
  bool threw = false;
  try {
    writeText(path, "complete\n");
  } catch (const StorageError& e) {
    threw = true;
    EXPECT_EQ(e.path(), path);
  }
  ::chmod(dir.path().c_str(), 0755);
  if (threw) {
    EXPECT_TRUE(listing(dir.path()).empty());
  } else {
    EXPECT_EQ(::geteuid(), 0u) << "only root may write into a read-only directory";
    expectOnlyTarget("complete\n");
  }
}

TEST_F(AtomicFile, AFailedRenameRemovesTheTemporary) {
  // The target is a non-empty directory: the temporary is complete, the rename fails.
  fs::create_directories(path + "/inside");
  expectStorageErrorNaming([&] { writeText(path, "x"); }, path);
  EXPECT_EQ(listing(dir.path()), std::set<std::string>{"out.txt"});
  EXPECT_TRUE(fs::is_directory(path + "/inside"));
}

TEST_F(AtomicFile, RemoveStaleTemporariesKeepsThoseOfRunningProcesses) {
  // A pid that surely belongs to no process: a child that has exited and been reaped.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) std::_Exit(0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  const std::string dead = "out.txt.tmp-" + std::to_string(child) + "-0";
  const std::string alive = "out.txt.tmp-" + std::to_string(::getpid()) + "-3";
  const std::string otherTarget = "other.txt.tmp-" + std::to_string(child) + "-0";
  for (const std::string& name : {std::string("out.txt"), dead, alive, otherTarget})
    std::ofstream(dir.path() + "/" + name) << "x";
  removeStaleTemporaries(path);
  EXPECT_EQ(listing(dir.path()), (std::set<std::string>{"out.txt", alive, otherTarget}));
  removeStaleTemporaries(dir.path() + "/no_such_directory/out.txt");  // never throws
}

TEST_F(AtomicFile, RemoveStaleTemporariesInClearsEveryTargetsOfDeadProcessesOnly) {
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) std::_Exit(0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  const std::string deadPid = std::to_string(child);
  const std::string alive = "design_final.png.tmp-" + std::to_string(::getpid()) + "-0";
  // Not temporaries of the atomic write: no PID-N after ".tmp-".
  const std::string notes = "notes.tmp-" + deadPid;
  const std::string words = "draft.tmp-x-1";
  for (const std::string& name : {std::string("results.h5"), "results.h5.tmp-" + deadPid + "-2",
                                  "design_final.vtk.tmp-" + deadPid + "-0",
                                  "design_iter_3.png.tmp-" + deadPid + "-7", alive, notes, words})
    std::ofstream(dir.path() + "/" + name) << "x";
  removeStaleTemporariesIn(dir.path());
  EXPECT_EQ(listing(dir.path()), (std::set<std::string>{"results.h5", alive, notes, words}));
  removeStaleTemporariesIn(dir.path() + "/no_such_directory");  // never throws
}

}  // namespace
}  // namespace hindsight
