// The bitwise comparison the reproducibility tests rely on (tests/support/same_bits.h): it must tell
// apart what == does not (signed zeros, NaN payloads), compare shapes, and say where operands differ.
#include "support/same_bits.h"

#include <hindsight/engine/types.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace hindsight {
namespace {

using testing::sameBits;

TEST(SameBits, TellsSignedZerosAndNanPayloadsApart) {
  const double quiet = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(sameBits(quiet, quiet));
  EXPECT_FALSE(sameBits(0.0, -0.0));
  EXPECT_FALSE(sameBits(std::nan("1"), std::nan("2")));
  EXPECT_FALSE(sameBits(1.0, std::nextafter(1.0, 2.0)));
  EXPECT_TRUE(sameBits(std::vector<double>{1.0, quiet}, std::vector<double>{1.0, quiet}));
  EXPECT_FALSE(sameBits(std::vector<double>{0.0}, std::vector<double>{-0.0}));
}

TEST(SameBits, ComparesShapesAndNamesTheFirstDifferingEntry) {
  Vector a(6);
  a << 0.0, 0.1, 0.2, 0.3, 0.4, 0.5;
  Vector b = a;
  EXPECT_TRUE(sameBits(a, b));
  EXPECT_TRUE(sameBits(a.segment(1, 3), b.segment(1, 3)));  // expressions are evaluated first
  b(2) = std::nextafter(b(2), 1.0);
  b(4) = -b(4);
  const ::testing::AssertionResult differ = sameBits(a, b);
  ASSERT_FALSE(differ);
  const std::string message = differ.message();
  EXPECT_NE(message.find("2 of 6 entries differ"), std::string::npos) << message;
  EXPECT_NE(message.find("first entry 2: 0.20000000000000001 (0x3fc999999999999a) vs "
                         "0.20000000000000004 (0x3fc999999999999b)"),
            std::string::npos)
      << message;

  const Matrix column = a;              // 6 x 1
  const Matrix row = a.transpose();     // 1 x 6, the same entries
  EXPECT_FALSE(sameBits(column, row));  // same bits in memory, other shape
  EXPECT_NE(std::string(sameBits(column, row).message()).find("shapes differ: 6 x 1 vs 1 x 6"),
            std::string::npos);
  EXPECT_FALSE(sameBits(std::vector<double>{1.0}, std::vector<double>{1.0, 1.0}));
}

}  // namespace
}  // namespace hindsight
