// Bit-for-bit comparison of doubles, vectors and matrices, for the tests that promise the same bits
// (recomputation, thread counts, restored state, kernels on other instruction sets). Equal bits, not
// equal values: -0.0 differs from 0.0 and a NaN equals only a NaN of the same payload. A failure says
// where the operands first differ and how many entries differ, with both values in full precision and
// hexadecimal, so that a one-ulp difference is told from a wrong result.
#pragma once

#include <gtest/gtest.h>
#include <Eigen/Core>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace hindsight::testing {

/// The value in full precision and its bits, e.g. "0.10000000000000001 (0x3fb999999999999a)".
inline std::string describeBits(double value) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &value, sizeof bits);
  char text[64];
  std::snprintf(text, sizeof text, "%.17g (0x%016llx)", value, static_cast<unsigned long long>(bits));
  return text;
}

/// Whether count doubles at a and b have the same bits; a failure names the first differing entry.
inline ::testing::AssertionResult sameBits(const double* a, const double* b, Eigen::Index count) {
  Eigen::Index differing = 0, first = -1;
  for (Eigen::Index i = 0; i < count; ++i) {
    if (std::memcmp(a + i, b + i, sizeof(double)) == 0) continue;
    if (differing++ == 0) first = i;
  }
  if (differing == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << differing << " of " << count << " entries differ in their bits, first entry " << first << ": "
         << describeBits(a[first]) << " vs " << describeBits(b[first]);
}

inline ::testing::AssertionResult sameBits(double a, double b) { return sameBits(&a, &b, 1); }

inline ::testing::AssertionResult sameBits(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size())
    return ::testing::AssertionFailure() << "sizes differ: " << a.size() << " vs " << b.size();
  return sameBits(a.data(), b.data(), static_cast<Eigen::Index>(a.size()));
}

/// Vectors and matrices (any expression; evaluated first): the same shape and the same bits in every
/// entry, entries counted in column-major order.
template <typename A, typename B>
::testing::AssertionResult sameBits(const Eigen::DenseBase<A>& a, const Eigen::DenseBase<B>& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) {
    return ::testing::AssertionFailure()
           << "shapes differ: " << a.rows() << " x " << a.cols() << " vs " << b.rows() << " x " << b.cols();
  }
  const Eigen::MatrixXd left = a, right = b;
  return sameBits(left.data(), right.data(), left.size());
}

}  // namespace hindsight::testing
