// Counting heap allocations in tests (STYLE.md guideline 3: hot paths allocate nothing).
//
// allocation_counting_test.cpp interposes malloc, calloc and realloc for the problems_tests binary and
// forwards them to glibc; Eigen allocates with std::malloc and operator new ends in malloc, so both
// are seen. Only allocations made while an AllocationCounter is alive are counted.
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
