// Threads inside one process, on oneTBB (Debian libtbb-dev) when it was found at build
// time, else serial. The one pattern used: the independent work items 0..count-1 of one evaluation
// (the adjoint-Nelson chain of each mode, the scenarios of one rank, the subtrees of a triangular
// sweep) run in parallel, each writing only its own output slot; the caller then combines the slots
// in index order. So no result depends on the thread count or on scheduling: bitwise equal for every
// K (no atomics, no reductions whose order follows the threads).
#pragma once

#include <functional>
#include <memory>

namespace hindsight {

/// Runs body(i) for i = 0..count-1, in parallel when threads are available. body must write only
/// its own slot. The first exception thrown by a body is rethrown after all bodies ended (TBB
/// cancels the rest); callers that need every item's outcome catch inside body.
void parallelFor(int count, const std::function<void(int)>& body);

/// The threads a process may use by default: the cores available to it (its affinity mask).
int availableThreads();

/// The threads parallelFor may use now: availableThreads() or less under a ThreadLimit (1 without TBB).
int parallelConcurrency();

/// True when built with TBB (otherwise everything runs on one thread).
bool threadsSupported();

/// Limits the threads of parallelFor to `threads` (>= 1) while the object lives (TBB's
/// global_control). Throws std::invalid_argument naming --threads when threads < 1.
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads);
  ~ThreadLimit();
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hindsight
