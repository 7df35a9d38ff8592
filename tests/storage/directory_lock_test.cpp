// DirectoryLock: one holder at a time, across processes and within one; the refusal names the
// directory and the holder's PID; the lock goes with its holder, also when the holder is killed.
#include <hindsight/engine/types.h>
#include <hindsight/storage/directory_lock.h>
#include "support/file_checks.h"
#include "support/storage_fixtures.h"

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

using testing::expectStorageErrorNaming;
using testing::ScratchDirectory;

// The message of the refusal to lock `directory`, or empty when the lock was taken.
std::string refusal(const std::string& directory) {
  try {
    DirectoryLock lock(directory, "--out");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return {};
}

TEST(DirectoryLock, ASecondHolderIsRefusedNamingTheDirectoryAndThePid) {
  ScratchDirectory dir;
  {
    const DirectoryLock lock(dir.path(), "--out");
    EXPECT_EQ(lock.path(), dir.path() + "/.lock");
    const std::string message = refusal(dir.path());
    EXPECT_NE(message.find("--out '" + dir.path() + "' is in use"), std::string::npos) << message;
    EXPECT_NE(message.find("pid " + std::to_string(::getpid())), std::string::npos) << message;
  }
  EXPECT_EQ(refusal(dir.path()), "");  // released with its holder
}

TEST(DirectoryLock, AnotherProcessIsRefusedUntilTheHolderIsKilled) {
  ScratchDirectory dir;
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const DirectoryLock lock(dir.path(), "--out");
    (void)!::write(ready[1], "x", 1);
    ::pause();  // holds the lock until killed
    std::_Exit(0);
  }
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);
  const std::string message = refusal(dir.path());
  EXPECT_NE(message.find("pid " + std::to_string(child)), std::string::npos) << message;
  ::kill(child, SIGKILL);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  EXPECT_EQ(refusal(dir.path()), "");  // the kernel dropped the killed holder's lock
  ::close(ready[0]);
  ::close(ready[1]);
}

TEST(DirectoryLock, AMissingDirectoryThrowsStorageErrorNamingTheLockFile) {
  ScratchDirectory dir;
  expectStorageErrorNaming([&] { DirectoryLock lock(dir.path() + "/missing", "--out"); },
                           dir.path() + "/missing/.lock");
}

}  // namespace
}  // namespace hindsight
