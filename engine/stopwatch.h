// The one timing helper: wall-clock seconds of a phase for run summaries and progress lines.
// steady_clock because it never jumps (NTP, daylight saving), so a duration is never negative.
#pragma once

#include <chrono>

namespace hindsight {

/// Measures seconds since construction or the last restart().
class Stopwatch {
 public:
  using Clock = std::chrono::steady_clock;

  Stopwatch() : start_(Clock::now()) {}

  double seconds() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

  /// Seconds so far, and starts again: consecutive phases read one clock, none is lost between them.
  double restart() {
    const Clock::time_point now = Clock::now();
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    start_ = now;
    return elapsed;
  }

 private:
  Clock::time_point start_;
};

}  // namespace hindsight
