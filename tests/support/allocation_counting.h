// Counting heap allocations in tests (docs/design.md P 3: hot paths allocate nothing).
//
// allocation_counting.cpp, linked into every test binary, interposes malloc, calloc and realloc and
// forwards them to glibc; Eigen allocates with std::malloc and operator new ends in malloc, so both
// are seen. Only allocations made on the counter's own thread while it is alive are counted (so a
// storage's background I/O thread does not count against the caller's hot loop).
#pragma once

namespace hindsight::testing {

class AllocationCounter {
 public:
  AllocationCounter();   // starts counting from zero
  ~AllocationCounter();  // stops counting
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;
  long count() const;  // allocations since construction
  // False under AddressSanitizer, whose own malloc must not be replaced; tests then skip.
  static bool available();
};

}  // namespace hindsight::testing
