// Peak resident set size of the benchmark process, per benchmark: Linux keeps one high-water mark
// (VmHWM) per process, and writing "5" to /proc/self/clear_refs resets it to the current RSS (Linux >= 4.0,
// Documentation/admin-guide/mm/soft-dirty.rst). A benchmark calls resetPeakRss() before its timed loop
// and reports peakRssBytes() after it, together with the RSS at the reset (what the process held
// before: caches of earlier benchmarks, the model). No library does this; it is 30 lines of procfs.
#pragma once

#include <fstream>
#include <string>

namespace hindsight::bench {

/// A /proc/self/status field in bytes ("VmHWM", "VmRSS"), or -1 when it cannot be read.
inline double procStatusBytes(const std::string& field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.compare(0, field.size() + 1, field + ":") == 0) {
      return 1024.0 * std::stod(line.substr(field.size() + 1));  // "VmHWM:   12345 kB"
    }
  }
  return -1.0;
}

/// Resets the high-water mark to the current RSS; returns the current RSS in bytes (-1 if unknown).
/// Returns -1 as well when the reset is refused (old kernel), so that callers do not report a stale peak.
inline double resetPeakRss() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5" << std::flush;
  if (!clear) return -1.0;
  return procStatusBytes("VmRSS");
}

/// The high-water mark since the last reset [bytes], -1 if unknown.
inline double peakRssBytes() { return procStatusBytes("VmHWM"); }

}  // namespace hindsight::bench
