// Byte counts in storage specs below one byte used to be accepted and truncated to a budget of 0
// (found by the storage-spec fuzz test): "full:budget=.024" built a strategy whose own spec,
// "full:budget=0", was then refused.
#include <hindsight/engine/trajectory_storage.h>
#include <hindsight/storage/storage_factory.h>

#include <gtest/gtest.h>

namespace hindsight {
namespace {

TEST(ByteCount, LessThanOneByteIsRefused) {
  for (const char* text : {"0.5", ".024", "0.9B", "0.0001KiB", "1e-300"}) {
    EXPECT_THROW(parseBytes(text, "full.budget"), std::invalid_argument) << text;
    EXPECT_THROW(createStorage(std::string("full:budget=") + text), std::invalid_argument) << text;
  }
  EXPECT_EQ(parseBytes("1", "full.budget"), 1);
  EXPECT_EQ(parseBytes("1.5", "full.budget"), 1);
  EXPECT_EQ(parseBytes("0.5KiB", "full.budget"), 512);
}

}  // namespace
}  // namespace hindsight
