// The atomic write: the target is always either absent/old or complete, no temporary file survives a
// finished call (successful or not), and failures name the target.
#include "storage/atomic_file.h"
#include "engine/types.h"
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
using testing::ScratchDirectory;

std::string contentsOf(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

std::set<std::string> listing(const std::string& directory) {
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(directory)) names.insert(entry.path().filename().string());
  return names;
}

void writeText(const std::string& path, const std::string& text) {
  writeStreamAtomically(path, [&](std::FILE* file) -> std::string {
    return std::fputs(text.c_str(), file) >= 0 ? std::string() : std::string("fputs failed");
  });
}

// Runs `write`, which must throw StorageError naming `path`.
template <typename Write>
void expectStorageErrorNaming(Write&& write, const std::string& path) {
  try {
    write();
    ADD_FAILURE() << "no StorageError for " << path;
  } catch (const StorageError& e) {
    EXPECT_EQ(e.path(), path);
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

TEST(AtomicFile, CreatesTheFileAndLeavesNoTemporary) {
  ScratchDirectory dir;
  const std::string path = dir.path() + "/out.txt";
  writeText(path, "complete\n");
  EXPECT_EQ(contentsOf(path), "complete\n");
  EXPECT_EQ(listing(dir.path()), std::set<std::string>{"out.txt"});
}

TEST(AtomicFile, ReplacesAnExistingFileAndTheOldOneStaysUntilTheRename) {
  ScratchDirectory dir;
  const std::string path = dir.path() + "/out.txt";
  writeText(path, "old contents\n");
  writeStreamAtomically(path, [&](std::FILE* file) -> std::string {
    std::fputs("new, half", file);
    std::fflush(file);
    // Halfway through, a reader still finds the complete old file.
    EXPECT_EQ(contentsOf(path), "old contents\n");
    std::fputs(" and the rest\n", file);
    return {};
  });
  EXPECT_EQ(contentsOf(path), "new, half and the rest\n");
  EXPECT_EQ(listing(dir.path()), std::set<std::string>{"out.txt"});
}

TEST(AtomicFile, AFailedWriteKeepsTheOldFileAndRemovesTheTemporary) {
  ScratchDirectory dir;
  const std::string path = dir.path() + "/out.txt";
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
  EXPECT_EQ(contentsOf(path), "old contents\n");
  EXPECT_EQ(listing(dir.path()), std::set<std::string>{"out.txt"});

  // A writer that throws: its exception arrives unchanged (a caller's bad argument stays one).
  EXPECT_THROW(writeFileAtomically(path,
                                   [](const std::string& temporary) {
                                     std::ofstream(temporary) << "torn";
                                     throw std::invalid_argument("bad field");
                                   }),
               std::invalid_argument);
  EXPECT_EQ(contentsOf(path), "old contents\n");
  EXPECT_EQ(listing(dir.path()), std::set<std::string>{"out.txt"});
}

TEST(AtomicFile, AWriterByNameIsFlushedAndRenamedLikeAStream) {
  ScratchDirectory dir;
  const std::string path = dir.path() + "/data.bin";
  writeFileAtomically(path, [](const std::string& temporary) { std::ofstream(temporary) << "by name"; });
  EXPECT_EQ(contentsOf(path), "by name");
  EXPECT_EQ(listing(dir.path()), std::set<std::string>{"data.bin"});

  // A writer that creates nothing cannot be committed.
  expectStorageErrorNaming([&] { writeFileAtomically(dir.path() + "/none", [](const std::string&) {}); },
                           dir.path() + "/none");
  EXPECT_EQ(listing(dir.path()), std::set<std::string>{"data.bin"});
}

TEST(AtomicFile, AMissingDirectoryThrowsAndCreatesNothing) {
  ScratchDirectory dir;
  const std::string path = dir.path() + "/no_such_directory/out.txt";
  expectStorageErrorNaming([&] { writeText(path, "x"); }, path);
  EXPECT_TRUE(listing(dir.path()).empty());
}

TEST(AtomicFile, AReadOnlyDirectoryThrowsOrWritesCompletely) {
  // /proc refuses new files even to root.
  const std::string proc = "/proc/hindsight-atomic-file-test";
  expectStorageErrorNaming([&] { writeText(proc, "x"); }, proc);
  EXPECT_FALSE(fs::exists(proc));

  // Permission bits stop everyone but root; either way nothing torn and no temporary remains.
  ScratchDirectory dir;
  const std::string path = dir.path() + "/out.txt";
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
    EXPECT_EQ(contentsOf(path), "complete\n");
    EXPECT_EQ(listing(dir.path()), std::set<std::string>{"out.txt"});
  }
}

TEST(AtomicFile, AFailedRenameRemovesTheTemporary) {
  // The target is a non-empty directory: the temporary is complete, the rename fails.
  ScratchDirectory dir;
  const std::string path = dir.path() + "/occupied";
  fs::create_directories(path + "/inside");
  expectStorageErrorNaming([&] { writeText(path, "x"); }, path);
  EXPECT_EQ(listing(dir.path()), std::set<std::string>{"occupied"});
  EXPECT_TRUE(fs::is_directory(path + "/inside"));
}

TEST(AtomicFile, RemoveStaleTemporariesKeepsThoseOfRunningProcesses) {
  ScratchDirectory dir;
  const std::string path = dir.path() + "/results.h5";
  // A pid that surely belongs to no process: a child that has exited and been reaped.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) std::_Exit(0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  const std::string dead = path + ".tmp-" + std::to_string(child) + "-0";
  const std::string alive = path + ".tmp-" + std::to_string(::getpid()) + "-3";
  for (const std::string& name :
       {dead, alive, path, dir.path() + "/other.h5.tmp-" + std::to_string(child) + "-0"})
    std::ofstream(name) << "x";
  removeStaleTemporaries(path);
  EXPECT_EQ(listing(dir.path()),
            (std::set<std::string>{"results.h5", "results.h5.tmp-" + std::to_string(::getpid()) + "-3",
                                   "other.h5.tmp-" + std::to_string(child) + "-0"}));
  removeStaleTemporaries(dir.path() + "/no_such_directory/results.h5");  // never throws
}

}  // namespace
}  // namespace hindsight
