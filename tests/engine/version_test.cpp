// The run-time hindsight::version() and the macros of <hindsight/version.h> (generated from
// CMakeLists.txt's project()) say the same thing, so code compiled against one set of headers can check
// the library it runs with.
#include <hindsight/engine/types.h>
#include <hindsight/version.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

TEST(Version, MatchesSemanticVersionShape) {
  const std::string v = hindsight::version();
  EXPECT_EQ(std::count(v.begin(), v.end(), '.'), 2) << v;
}

TEST(Version, MacrosAgreeWithTheRuntimeString) {
  const std::string fromMacros = std::to_string(HINDSIGHT_VERSION_MAJOR) + "." +
                                 std::to_string(HINDSIGHT_VERSION_MINOR) + "." +
                                 std::to_string(HINDSIGHT_VERSION_PATCH);
  EXPECT_EQ(fromMacros, HINDSIGHT_VERSION_STRING);
  EXPECT_EQ(std::string(hindsight::version()), HINDSIGHT_VERSION_STRING);
  EXPECT_EQ(HINDSIGHT_VERSION_NUMBER,
            HINDSIGHT_VERSION_MAJOR * 10000 + HINDSIGHT_VERSION_MINOR * 100 + HINDSIGHT_VERSION_PATCH);
}
