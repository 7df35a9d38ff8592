#include <hindsight/engine/dense_blocking.h>

#include <Eigen/Core>

#include <cerrno>
#include <cstdlib>
#include <stdexcept>

namespace hindsight {

namespace {

std::ptrdiff_t parseSize(const std::string& whole, const std::string& text, const char* which) {
  const auto fail = [&]() {
    throw std::invalid_argument("HINDSIGHT_EMULATE_CPU_CACHES = '" + whole + "': the " + which + " size '" +
                                text +
                                "' is not an integer number of bytes in [1024, 2^40]; the form is "
                                "L1,L2,L3 in bytes, e.g. 49152,2097152,110100480");
  };
  if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos) fail();
  errno = 0;
  const unsigned long long value = std::strtoull(text.c_str(), nullptr, 10);
  if (errno != 0 || value < 1024 || value > (1ULL << 40)) fail();
  return static_cast<std::ptrdiff_t>(value);
}

// Runs when this object is loaded into a program or shared object (dense_blocking.h): first what an
// emulated CPU would report, then the pin. A malformed emulation setting is left for the tool's start-up
// check to report (an exception cannot leave a static initializer).
[[maybe_unused]] const bool kPinnedAtLoad = [] {
  try {
    if (const auto emulated = emulatedCacheSizesFromSetting(std::getenv("HINDSIGHT_EMULATE_CPU_CACHES")))
      Eigen::setCpuCacheSizes(emulated->l1, emulated->l2, emulated->l3);
  } catch (const std::invalid_argument&) {
  }
  pinDenseBlocking();
  return true;
}();

}  // namespace

void pinDenseBlocking() {
  Eigen::setCpuCacheSizes(kPinnedCacheSizes.l1, kPinnedCacheSizes.l2, kPinnedCacheSizes.l3);
}

CacheSizes denseBlockingCacheSizes() {
  return {Eigen::l1CacheSize(), Eigen::l2CacheSize(), Eigen::l3CacheSize()};
}

CacheSizes cpuReportedCacheSizes() {
  int l1 = -1, l2 = -1, l3 = -1;
  Eigen::internal::queryCacheSizes(l1, l2, l3);
  return {l1, l2, l3};
}

std::optional<CacheSizes> emulatedCacheSizesFromSetting(const char* value) {
  if (value == nullptr || *value == '\0') return std::nullopt;
  const std::string text(value);
  const auto first = text.find(',');
  const auto second = first == std::string::npos ? std::string::npos : text.find(',', first + 1);
  if (second == std::string::npos || text.find(',', second + 1) != std::string::npos)
    throw std::invalid_argument("HINDSIGHT_EMULATE_CPU_CACHES = '" + text +
                                "': expected three sizes L1,L2,L3 in bytes, e.g. 49152,2097152,110100480");
  return CacheSizes{parseSize(text, text.substr(0, first), "L1"),
                    parseSize(text, text.substr(first + 1, second - first - 1), "L2"),
                    parseSize(text, text.substr(second + 1), "L3")};
}

std::string describeCacheSizes(const CacheSizes& sizes) {
  const auto kib = [](std::ptrdiff_t bytes) {
    return bytes < 0 ? std::string("unknown") : std::to_string(bytes / 1024) + " KiB";
  };
  return kib(sizes.l1) + " L1, " + kib(sizes.l2) + " L2, " + kib(sizes.l3) + " L3";
}

}  // namespace hindsight

// The anchor the engine's link interface names (-Wl,--undefined, CMakeLists.txt): it makes the linker
// take this object, and with it the initializer above, out of the static library into every program.
extern "C" {
extern const int hindsight_dense_blocking_anchor;
const int hindsight_dense_blocking_anchor = 1;
}
