#include <hindsight/storage/directory_lock.h>

#include <hindsight/engine/types.h>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace hindsight {

DirectoryLock::DirectoryLock(const std::string& directory, const std::string& role)
    : path_((std::filesystem::path(directory) / ".lock").string()) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw StorageError("cannot open the lock file: " + std::string(std::strerror(errno)), path_);
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    std::string holder = "unknown";
    if (error == EWOULDBLOCK) {
      char text[32] = {};
      const ssize_t length = ::pread(fd_, text, sizeof text - 1, 0);
      const long pid = length > 0 ? std::strtol(text, nullptr, 10) : 0;
      if (pid > 0) holder = std::to_string(pid);
    }
    ::close(fd_);
    fd_ = -1;
    if (error != EWOULDBLOCK)
      throw StorageError("cannot lock the lock file: " + std::string(std::strerror(error)), path_);
    throw std::invalid_argument(role + " '" + directory + "' is in use by another process (pid " + holder +
                                " holds " + path_ + "); wait for it to finish or choose another directory");
  }
  // Only for the message above: the lock itself is the flock, not this text.
  const std::string pid = std::to_string(static_cast<long>(::getpid())) + "\n";
  if (::ftruncate(fd_, 0) != 0 ||
      ::pwrite(fd_, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    // A lock without the PID still excludes; the refusal then says "pid unknown".
  }
}

DirectoryLock::~DirectoryLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the last descriptor releases the flock
}

}  // namespace hindsight
