#include <hindsight/storage/scratch_files.h>

#include <hindsight/engine/hash.h>

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <set>

namespace hindsight::internal {
namespace {

bool allDigits(const std::string& text) {
  if (text.empty() || text.size() > 18) return false;
  for (char c : text) {
    if (c < '0' || c > '9') return false;
  }
  return true;
}

bool processIsGone(long long pid) {
  if (pid <= 0 || pid > 0x3fffffff) return false;
  // kill(pid, 0) sends nothing; ESRCH: no such process. EPERM means it exists (another user's).
  return ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH;
}

}  // namespace

std::string scratchHostTag() {
  static const std::string tag = [] {
    char host[256] = {};
    if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
    const std::uint64_t h = fnv1a(host, std::char_traits<char>::length(host));
    char text[9];
    std::snprintf(text, sizeof text, "%08x", static_cast<unsigned>(h & 0xffffffffULL));
    return std::string(text);
  }();
  return tag;
}

std::string scratchFileName(const std::string& prefix, const std::string& extension, bool kept) {
  static std::atomic<std::uint64_t> counter{0};
  const auto now = std::chrono::steady_clock::now().time_since_epoch().count();
  return prefix + "-" + std::to_string(::getpid()) + "-" + (kept ? std::string("kept") : scratchHostTag()) +
         "-" + std::to_string(counter.fetch_add(1)) + "-" +
         std::to_string(static_cast<unsigned long long>(now) % 1000000007ULL) + extension;
}

bool isStaleScratchFile(const std::string& name) {
  std::string rest;
  if (name.rfind("hindsight-multilevel-", 0) == 0) {
    rest = name.substr(21);
  } else if (name.rfind("hindsight-", 0) == 0) {
    rest = name.substr(10);
  } else {
    return false;
  }
  std::string stem;
  for (const char* extension : {".h5", ".slots"}) {
    const std::string e = extension;
    if (rest.size() > e.size() && rest.compare(rest.size() - e.size(), e.size(), e) == 0) {
      stem = rest.substr(0, rest.size() - e.size());
    }
  }
  // stem = PID-HOST-COUNTER-TIME
  const std::size_t a = stem.find('-');
  if (a == std::string::npos) return false;
  const std::size_t b = stem.find('-', a + 1);
  if (b == std::string::npos) return false;
  const std::size_t c = stem.find('-', b + 1);
  if (c == std::string::npos) return false;
  const std::string pid = stem.substr(0, a), host = stem.substr(a + 1, b - a - 1),
                    counter = stem.substr(b + 1, c - b - 1), time = stem.substr(c + 1);
  if (!allDigits(pid) || host != scratchHostTag() || !allDigits(counter) || !allDigits(time)) return false;
  return processIsGone(std::stoll(pid));
}

int removeStaleScratchFiles(const std::string& directory) noexcept {
  try {
    static std::mutex mutex;
    static std::set<std::string> done;
    std::error_code ec;
    const std::string key = std::filesystem::weakly_canonical(directory, ec).string();
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (!done.insert(ec ? directory : key).second) return 0;
    }
    int removed = 0;
    std::filesystem::directory_iterator it(directory, ec);
    if (ec) return 0;
    for (const std::filesystem::directory_entry& entry : it) {
      std::error_code entryError;
      if (!entry.is_regular_file(entryError) || entryError) continue;
      if (isStaleScratchFile(entry.path().filename().string()) &&
          std::filesystem::remove(entry.path(), entryError)) {
        ++removed;
      }
    }
    return removed;
  } catch (...) {
    return 0;  // best effort: a stale file left is harmless, a failed run is not
  }
}

}  // namespace hindsight::internal
