#include <hindsight/engine/types.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

TEST(Version, MatchesSemanticVersionShape) {
  const std::string v = hindsight::version();
  EXPECT_EQ(std::count(v.begin(), v.end(), '.'), 2) << v;
}
