// The allocation counter of allocation_counting.h, linked into every test binary, and a test that it
// sees the allocations of operator new and of Eigen (so that a test expecting zero allocations can fail).
#include "support/allocation_counting.h"

#include <hindsight/engine/types.h>

#include <gtest/gtest.h>

#include <cstddef>
#include <memory>
#include <vector>

namespace {
// Thread-local (initial-exec TLS of the executable: reading it never allocates).
thread_local bool g_counting = false;
thread_local long g_count = 0;

inline void Record() {
  if (g_counting) ++g_count;
}
}  // namespace

#if defined(__SANITIZE_ADDRESS__)
#define HINDSIGHT_COUNT_ALLOCATIONS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define HINDSIGHT_COUNT_ALLOCATIONS 0
#endif
#endif
#ifndef HINDSIGHT_COUNT_ALLOCATIONS
#define HINDSIGHT_COUNT_ALLOCATIONS 1
#endif

#if HINDSIGHT_COUNT_ALLOCATIONS
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);

void* malloc(std::size_t size) {
  Record();
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) {
  Record();
  return __libc_calloc(count, size);
}
void* realloc(void* p, std::size_t size) {
  Record();
  return __libc_realloc(p, size);
}
}
#endif

namespace hindsight::testing {

AllocationCounter::AllocationCounter() {
  g_count = 0;
  g_counting = true;
}
AllocationCounter::~AllocationCounter() { g_counting = false; }
long AllocationCounter::count() const { return g_count; }
bool AllocationCounter::available() { return HINDSIGHT_COUNT_ALLOCATIONS != 0; }

TEST(AllocationCounter, SeesOperatorNewAndEigen) {
  if (!AllocationCounter::available()) GTEST_SKIP() << "malloc is not replaced under AddressSanitizer";
  long counted = 0;
  {
    AllocationCounter counter;
    auto owned = std::make_unique<std::vector<int>>(100);
    Vector v(1000);
    v.setZero();
    counted = counter.count();
  }
  EXPECT_GE(counted, 3);  // the vector object, its buffer and the Eigen vector
  AllocationCounter counter;
  EXPECT_EQ(counter.count(), 0);
}

}  // namespace hindsight::testing
