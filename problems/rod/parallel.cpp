#include <hindsight/problems/rod/parallel.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <thread>

#ifdef HINDSIGHT_HAVE_TBB
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#endif

namespace hindsight {

void parallelFor(int count, const std::function<void(int)>& body) {
#ifdef HINDSIGHT_HAVE_TBB
  if (count > 1) {
    // Grain 1, simple partitioner: the items are few and coarse (a factorisation each).
    tbb::parallel_for(
        tbb::blocked_range<int>(0, count, 1),
        [&](const tbb::blocked_range<int>& range) {
          for (int i = range.begin(); i != range.end(); ++i) body(i);
        },
        tbb::simple_partitioner());
    return;
  }
#endif
  for (int i = 0; i < count; ++i) body(i);
}

int availableThreads() {
#ifdef HINDSIGHT_HAVE_TBB
  return tbb::info::default_concurrency();
#else
  return 1;
#endif
}

int parallelConcurrency() {
#ifdef HINDSIGHT_HAVE_TBB
  const auto limit = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  return static_cast<int>(
      std::min<std::size_t>(limit, static_cast<std::size_t>(tbb::this_task_arena::max_concurrency())));
#else
  return 1;
#endif
}

bool threadsSupported() {
#ifdef HINDSIGHT_HAVE_TBB
  return true;
#else
  return false;
#endif
}

struct ThreadLimit::Impl {
#ifdef HINDSIGHT_HAVE_TBB
  explicit Impl(int threads)
      : control(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads)) {}
  tbb::global_control control;
#else
  explicit Impl(int) {}
#endif
};

ThreadLimit::ThreadLimit(int threads) {
  if (threads < 1)
    throw std::invalid_argument("--threads = " + std::to_string(threads) +
                                " is outside the allowed range [1, inf)");
  impl_ = std::make_unique<Impl>(threads);
}

ThreadLimit::~ThreadLimit() = default;

}  // namespace hindsight
