#include <hindsight/storage/atomic_file.h>

#include <hindsight/engine/types.h>

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

namespace hindsight {
namespace {

std::string systemReason() { return std::strerror(errno); }

std::string temporaryPrefix(const std::string& path) { return path + ".tmp-"; }

// The pid lets removeStaleTemporaries tell a dead writer's file from a running one's; the counter
// keeps two threads of one process that write the same path apart.
std::string temporaryPath(const std::string& path) {
  static std::atomic<unsigned long> counter{0};
  return temporaryPrefix(path) + std::to_string(static_cast<long>(::getpid())) + "-" +
         std::to_string(counter.fetch_add(1));
}

std::string directoryOf(const std::string& path) {
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return path.substr(0, std::max<std::size_t>(slash, 1));  // "/file" lives in "/"
}

// Flushes a file's or directory's data to disk; an empty string on success, else the reason. Linux
// flushes through a read-only descriptor, the only kind a directory can be opened with.
std::string syncToDisk(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | flags);
  if (fd < 0) return "cannot open " + path + " to flush it to disk: " + systemReason();
  const int status = ::fsync(fd);
  const std::string reason = status != 0 ? systemReason() : std::string();
  ::close(fd);
  if (status != 0) return "cannot flush " + path + " to disk: " + reason;
  return {};
}

// Removes the files NAME.tmp-PID-N in `directory` whose process PID no longer runs; with a non-empty
// `prefix` only those whose name starts with it (the temporaries of one target).
void removeStaleTemporariesMatching(const std::string& directory, const std::string& prefix) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (fs::directory_iterator it(directory, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    // The last ".tmp-" followed by PID-N, digits only: nothing else is taken for a temporary.
    const auto marker = name.rfind(".tmp-");
    if (marker == std::string::npos || marker + 5 < prefix.size()) continue;
    const std::string tail = name.substr(marker + 5);
    const auto dash = tail.find('-');
    const auto digits = [](const std::string& text) {
      return !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
    };
    if (dash == std::string::npos || !digits(tail.substr(0, dash)) || !digits(tail.substr(dash + 1)))
      continue;
    const long pid = std::strtol(tail.c_str(), nullptr, 10);
    // kill(pid, 0) probes without sending anything; ESRCH: no such process any more.
    if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) {
      std::error_code ignored;
      fs::remove(it->path(), ignored);
    }
  }
}

}  // namespace

void writeFileAtomically(const std::string& path, const std::function<void(const std::string&)>& write) {
  const std::string temporary = temporaryPath(path);
  try {
    write(temporary);
  } catch (...) {
    std::remove(temporary.c_str());
    throw;
  }
  // Data before the rename: otherwise a power loss could leave PATH naming an empty file.
  std::string error = syncToDisk(temporary, 0);
  if (error.empty() && std::rename(temporary.c_str(), path.c_str()) != 0)
    error = "cannot rename " + temporary + " onto the target: " + systemReason();
  if (!error.empty()) {
    std::remove(temporary.c_str());
    throw StorageError(error, path);
  }
  // The rename is a change of the directory; without this a power loss may undo it.
  error = syncToDisk(directoryOf(path), O_DIRECTORY);
  if (!error.empty()) throw StorageError(error, path);
}

void writeBytesAtomically(const std::string& path, const void* data, std::size_t size,
                          const std::string& what) {
  writeStreamAtomically(path, [&](std::FILE* file) -> std::string {
    if (std::fwrite(data, 1, size, file) != size) return "cannot write " + what + ": " + std::strerror(errno);
    return {};
  });
}

void writeStreamAtomically(const std::string& path, const std::function<std::string(std::FILE*)>& write) {
  writeFileAtomically(path, [&](const std::string& temporary) {
    std::FILE* file = std::fopen(temporary.c_str(), "wb");
    if (file == nullptr)
      throw StorageError("cannot create temporary file " + temporary + ": " + systemReason(), path);
    std::string error;
    try {
      error = write(file);
    } catch (...) {
      std::fclose(file);
      throw;
    }
    if (error.empty() && std::fflush(file) != 0) error = "cannot write " + temporary + ": " + systemReason();
    if (std::fclose(file) != 0 && error.empty()) error = "cannot close " + temporary + ": " + systemReason();
    if (!error.empty()) throw StorageError(error, path);
  });
}

void removeStaleTemporaries(const std::string& path) {
  namespace fs = std::filesystem;
  removeStaleTemporariesMatching(directoryOf(path), fs::path(temporaryPrefix(path)).filename().string());
}

void removeStaleTemporariesIn(const std::string& directory) { removeStaleTemporariesMatching(directory, {}); }

}  // namespace hindsight
