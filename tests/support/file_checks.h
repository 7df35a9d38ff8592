// Checks shared by the tests of everything that writes files (atomic writes, pictures): what a
// directory holds, and that a failed write throws StorageError naming the file.
#pragma once

#include <hindsight/engine/types.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace hindsight::testing {

/// Every dataset of a results file (the layout in problems/topopt/results_file.h), by path; each
/// carries Fletcher32 and a content hash.
inline const std::vector<std::string>& resultsDatasets() {
  static const std::vector<std::string> paths = {"history/iteration",
                                                 "history/backtracks",
                                                 "history/psi1",
                                                 "history/psi2",
                                                 "history/volume_fraction",
                                                 "history/max_design_change",
                                                 "history/evaluation_seconds",
                                                 "history/mma_seconds",
                                                 "history/total_seconds",
                                                 "history/grayness",
                                                 "history/first_frequency_hz",
                                                 "history/kkt_residual",
                                                 "history/inner_iterations",
                                                 "designs",
                                                 "state/design",
                                                 "state/mma_xold1",
                                                 "state/mma_xold2",
                                                 "state/mma_low",
                                                 "state/mma_upp",
                                                 "state/end_game",
                                                 "state/end_game_refining",
                                                 "state/best_design",
                                                 "final/modes",
                                                 "final/frequencies_hz"};
  return paths;
}

/// The names in a directory, to see that no temporary file was left behind.
inline std::set<std::string> listing(const std::filesystem::path& directory) {
  std::set<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(directory))
    names.insert(entry.path().filename().string());
  return names;
}

/// Runs `write`, which must throw StorageError naming `path` (in path() and in the message).
template <typename Write>
void expectStorageErrorNaming(Write&& write, const std::string& path) {
  try {
    write();
    ADD_FAILURE() << "no StorageError for " << path;
  } catch (const StorageError& e) {
    EXPECT_EQ(e.path(), path);
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

}  // namespace hindsight::testing
