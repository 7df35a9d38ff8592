// The main of every GoogleTest binary. Each test process gets a temp folder of its own: it is made under
// the temp directory the process was started with, TMPDIR and TEST_TMPDIR point at it (so
// std::filesystem::temp_directory_path, ::testing::TempDir, mkdtemp and every program a test starts
// write there), and it is removed when the tests have run, with whatever they left in it: the suite
// leaves the temp directory as it found it, also when a test fails half-way. HINDSIGHT_TEST_STRICT_TMP=1
// makes a process whose tests left anything there fail, naming it (docs/guides/testing.md).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <system_error>
#include <vector>

namespace {

std::filesystem::path makeScratch() {
  std::error_code error;
  const std::filesystem::path base = std::filesystem::temp_directory_path(error);
  std::string pattern = ((error ? std::filesystem::path("/tmp") : base) / "hindsight-test-XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) {
    std::cerr << "test_main: cannot make a temp folder from " << pattern << '\n';
    std::exit(2);
  }
  return pattern;
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  const std::filesystem::path scratch = makeScratch();
  ::setenv("TMPDIR", scratch.c_str(), 1);
  ::setenv("TEST_TMPDIR", scratch.c_str(), 1);
  int status = RUN_ALL_TESTS();
  std::vector<std::string> left;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(scratch, error)) {
    left.push_back(entry.path().filename().string());
  }
  std::filesystem::remove_all(scratch, error);
  if (!left.empty()) {
    std::cerr << "test_main: the tests left " << left.size() << " entries in the temp directory:";
    for (const std::string& name : left) std::cerr << ' ' << name;
    std::cerr << '\n';
    const char* strict = std::getenv("HINDSIGHT_TEST_STRICT_TMP");
    if (status == 0 && strict != nullptr && std::string(strict) == "1") status = 1;
  }
  return status;
}
