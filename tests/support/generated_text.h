// Checked-in text generated from one table (the configuration's fields, the history's columns, the
// storage strategies' rows): the tests compare it with what the table generates now, and with
// HINDSIGHT_REGENERATE=1 in the environment they rewrite it from the table first (then review the diff
// and commit it). One place for the rule, so that every generated file is checked and regenerated alike.
#pragma once

#include "support/text_files.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace hindsight::testing {

/// Whether HINDSIGHT_REGENERATE=1 is set: the tests rewrite the generated text instead of only checking it.
inline bool regenerating() {
  const char* value = std::getenv("HINDSIGHT_REGENERATE");
  return value != nullptr && std::string(value) == "1";
}

/// The whole of `path` equals `generated` (rewritten first when regenerating); `source` names the table.
inline ::testing::AssertionResult generatedFileMatches(const std::filesystem::path& path,
                                                       const std::string& generated,
                                                       const std::string& source) {
  if (regenerating()) writeText(path, generated);
  if (readText(path) == generated) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << path << " differs from " << source << "; regenerate with HINDSIGHT_REGENERATE=1 and this test";
}

/// The text of `path` between the lines `begin` and `end` (markers, each ending in a newline) equals
/// `generated` (that part rewritten first when regenerating); `source` names the table.
inline ::testing::AssertionResult generatedSectionMatches(const std::filesystem::path& path,
                                                          const std::string& begin, const std::string& end,
                                                          const std::string& generated,
                                                          const std::string& source) {
  std::string text = readText(path);
  const std::size_t first = text.find(begin);
  std::size_t last = text.find(end);
  if (first == std::string::npos)
    return ::testing::AssertionFailure() << path << " lacks the marker " << begin;
  if (last == std::string::npos) return ::testing::AssertionFailure() << path << " lacks the marker " << end;
  if (last < first)
    return ::testing::AssertionFailure() << path << ": the marker " << end << " precedes " << begin;
  const std::size_t from = first + begin.size();
  if (regenerating()) {
    text.replace(from, last - from, generated);
    writeText(path, text);
    last = text.find(end);
  }
  if (text.compare(from, last - from, generated) == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << path << ": the generated part differs from " << source
                                       << "; regenerate with HINDSIGHT_REGENERATE=1 and this test";
}

}  // namespace hindsight::testing
