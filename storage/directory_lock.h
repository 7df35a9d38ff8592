// An advisory lock on a directory, held while the object lives: flock(2) on DIR/.lock. Two processes
// that write the same output directory (two `hindsight optimize --out DIR`) would otherwise interleave
// their writes of the same files; the second one is refused at once instead.
//
// Why flock: the kernel releases the lock when its holder dies, kill -9 included, so a crash never
// leaves a stale lock behind and nothing has to guess whether a holder still runs. The lock file
// stays (removing it would race with a process that just opened it); it holds the PID of the last
// holder, only so that the refusal can name the process. Advisory: it keeps out other processes that
// take it, not arbitrary writers. The descriptor is close-on-exec, so spawned programs do not inherit
// the lock.
#pragma once

#include <string>

namespace hindsight {

class DirectoryLock {
 public:
  /// Takes the lock of `directory` (which must exist) without waiting. `role` names the directory in
  /// messages ("--out"). Throws std::invalid_argument naming the directory and the holder's PID when
  /// another process (or another DirectoryLock of this one) holds it; StorageError naming the lock
  /// file when it cannot be created or locked.
  DirectoryLock(const std::string& directory, const std::string& role);
  ~DirectoryLock();
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

  /// DIR/.lock
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
};

}  // namespace hindsight
