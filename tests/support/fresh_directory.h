// Fresh paths for tests that write whole runs (results folders, CLI outputs) and may reuse a path across
// the tests of one process: every path lies in one folder of the process, which a gtest environment
// removes when the tests end -- inside RUN_ALL_TESTS, so before the test main looks for what the tests
// left in the temp directory (tests/support/test_main.cpp), also when a test failed half-way.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace hindsight::testing {

/// The folder of this process's fresh paths (made on first use, in the temp directory the test main chose).
inline const std::filesystem::path& freshParent() {
  static const std::filesystem::path parent =
      std::filesystem::temp_directory_path() / ("hindsight_fresh_" + std::to_string(::getpid()));
  return parent;
}

/// A path that does not exist (removed if an earlier test of this process left it), its parent made.
inline std::string freshDirectory(const std::string& name) {
  const std::filesystem::path path = freshParent() / name;
  std::filesystem::remove_all(path);
  std::filesystem::create_directories(path.parent_path());
  return path.string();
}

class RemoveFreshDirectories final : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ignored;  // nothing to remove when no test asked for a fresh path
    std::filesystem::remove_all(freshParent(), ignored);
  }
};

// Registered during static initialisation, before RUN_ALL_TESTS (one per program: an inline variable).
inline ::testing::Environment* const kRemoveFreshDirectories =
    ::testing::AddGlobalTestEnvironment(new RemoveFreshDirectories);

}  // namespace hindsight::testing
