// The history's one schema (problems/topopt/history_schema.h) drives the results file's writer, reader
// and checks, the plot script's labels (problems/topopt/history_columns.json) and the table of
// docs/guides/results_files.md; these tests fail when any of them drifts from it. With
// HINDSIGHT_REGENERATE=1 in the environment they rewrite the JSON file and the documentation's table
// from the schema instead (then review the diff and commit it).
#include <hindsight/problems/topopt/history_schema.h>
#include <hindsight/problems/topopt/results_file.h>
#include <hindsight/storage/hdf5.h>

#include "support/generated_text.h"

#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <filesystem>
#include <iterator>
#include <set>
#include <string>

#include <unistd.h>

namespace hindsight {
namespace {

namespace fs = std::filesystem;
using testing::generatedFileMatches;
using testing::generatedSectionMatches;

const fs::path kSource = HINDSIGHT_SOURCE_DIR;
constexpr const char* kBegin = "<!-- history-columns: generated from problems/topopt/history_schema.h -->\n";
constexpr const char* kEnd = "<!-- history-columns: end -->\n";

// A results file with distinct values in every history column.
ResultsData fixture() {
  ResultsData data;
  data.configurationJson = "{}";
  data.nx = 4;
  data.ny = 2;
  for (int k = 0; k < 3; ++k) {
    IterationRecord r;
    r.iteration = k;
    r.backtracks = k % 2;
    r.psi1 = 0.25 / (k + 1);
    r.psi2 = 0.125 / (k + 1);
    r.volumeFraction = 0.5 + 0.01 * k;
    r.maxDesignChange = 0.1 * (k + 1);
    r.evaluationSeconds = 1.5 + k;
    r.mmaSeconds = 0.25 * k;
    r.totalSeconds = 2.0 + k;
    r.grayness = 0.3 - 0.05 * k;
    r.firstFrequencyHz = 100.0 + k;
    r.kktResidual = 1e-3 / (k + 1);
    r.innerIterations = 2 * k;
    data.history.push_back(r);
    data.densities.push_back(Vector::Constant(8, 0.5 + 0.1 * k));
  }
  data.state.iteration = 3;
  data.state.mma.iteration = 3;
  data.state.objectiveScale = 0.25;
  data.state.design = Vector::Constant(4, 0.5);
  data.state.mma.xold1 = data.state.mma.xold2 = data.state.design;
  data.state.mma.low = Vector::Constant(4, 0.1);
  data.state.mma.upp = Vector::Constant(4, 0.9);
  return data;
}

fs::path scratch(const std::string& name) {
  const fs::path directory =
      fs::temp_directory_path() / ("hindsight_history_schema_" + std::to_string(::getpid()));
  fs::create_directories(directory);
  return directory / name;
}

TEST(HistorySchema, JsonFileIsGeneratedFromTheTable) {
  EXPECT_TRUE(generatedFileMatches(kSource / "problems/topopt/history_columns.json", historyColumnsJson(),
                                   "the history's schema (problems/topopt/history_schema.h)"));
}

TEST(HistorySchema, DocumentationTableIsGeneratedFromTheTable) {
  EXPECT_TRUE(generatedSectionMatches(kSource / "docs/guides/results_files.md", kBegin, kEnd,
                                      historyColumnsMarkdown(),
                                      "the history's schema (problems/topopt/history_schema.h)"));
}

TEST(HistorySchema, NamesAreUniqueAndMembersSet) {
  std::set<std::string> names;
  for (const HistoryColumn& c : historyColumns()) {
    EXPECT_TRUE(names.insert(c.name).second) << c.name;
    EXPECT_EQ(c.type == HistoryColumnType::int32, c.integer != nullptr) << c.name;
    EXPECT_EQ(c.type == HistoryColumnType::float64, c.real != nullptr) << c.name;
    EXPECT_LE(c.lower, c.upper) << c.name;
    EXPECT_NE(std::string(c.unit), "") << c.name;
  }
}

// The file holds exactly the schema's columns, each value read back as written.
TEST(HistorySchema, FileHoldsEveryColumnAndReadsItBack) {
  const fs::path path = scratch("roundtrip.h5");
  const ResultsData data = fixture();
  writeResultsFile(path.string(), data);

  std::set<std::string> stored;
  {
    const hdf5::Handle file = hdf5::openFileReadOnly(path.string());
    const hid_t group = H5Gopen2(file.get(), "history", H5P_DEFAULT);
    ASSERT_GE(group, 0);
    H5G_info_t info;
    ASSERT_GE(H5Gget_info(group, &info), 0);
    for (hsize_t i = 0; i < info.nlinks; ++i) {
      char name[256];
      ASSERT_GT(H5Lget_name_by_idx(group, ".", H5_INDEX_NAME, H5_ITER_INC, i, name, sizeof name, H5P_DEFAULT),
                0);
      stored.insert(name);
    }
    H5Gclose(group);
  }
  std::set<std::string> expected;
  for (const HistoryColumn& c : historyColumns()) expected.insert(c.name);
  EXPECT_EQ(stored, expected);

  const ResultsData read = readResultsFile(path.string());
  ASSERT_EQ(read.history.size(), data.history.size());
  for (const HistoryColumn& c : historyColumns()) {
    for (std::size_t k = 0; k < data.history.size(); ++k) {
      EXPECT_EQ(historyValue(c, read.history[k]), historyValue(c, data.history[k])) << c.name << " row " << k;
    }
  }
  fs::remove_all(path.parent_path());
}

// The columns are stored as before the schema existed, bit for bit: each dataset's content hash
// covers its path, dimensions and values as stored (int32 or float64), and these were recorded from
// the writer that named the columns one by one. (The root hash is not pinned here: it also covers the
// optimizer state's datasets, whose layout is not the history's.)
TEST(HistorySchema, EveryColumnIsStoredAsBefore) {
  const std::pair<const char*, const char*> recorded[] = {{"iteration", "fnv1a64:37c60563f8be8725"},
                                                          {"backtracks", "fnv1a64:cbc03cb51860ba16"},
                                                          {"psi1", "fnv1a64:7c674de76a4460eb"},
                                                          {"psi2", "fnv1a64:d3074396a9bacb8a"},
                                                          {"volume_fraction", "fnv1a64:7b1ec0f9051f276d"},
                                                          {"max_design_change", "fnv1a64:550955819e1e78fc"},
                                                          {"evaluation_seconds", "fnv1a64:bce891cbaf0df7f9"},
                                                          {"mma_seconds", "fnv1a64:2b13f69c1ca688b0"},
                                                          {"total_seconds", "fnv1a64:abf549a974b72e15"},
                                                          {"grayness", "fnv1a64:fa9fb2ed57eb10dd"},
                                                          {"first_frequency_hz", "fnv1a64:ff586e4ca500b093"},
                                                          {"kkt_residual", "fnv1a64:5a8d9f421805fcc7"},
                                                          {"inner_iterations", "fnv1a64:6d72151ca19542ad"}};
  ASSERT_EQ(std::size(recorded), historyColumns().size());
  const fs::path path = scratch("hash.h5");
  writeResultsFile(path.string(), fixture());
  const hdf5::Handle file = hdf5::openFileReadOnly(path.string());
  for (std::size_t k = 0; k < historyColumns().size(); ++k) {
    EXPECT_STREQ(historyColumns()[k].name, recorded[k].first) << "the file order of the columns changed";
    const hdf5::Handle dataset = hdf5::openDataset(file.get(), std::string("history/") + recorded[k].first);
    EXPECT_EQ(hdf5::readStringAttribute(dataset.get(), "content_hash"), recorded[k].second)
        << recorded[k].first;
  }
  fs::remove_all(path.parent_path());
}

// Each column's check, as the schema states it, finds a value that breaks it and names the column.
TEST(HistorySchema, VerifyChecksEveryColumnAsTheSchemaSays) {
  for (std::size_t index = 0; index < historyColumns().size(); ++index) {
    const HistoryColumn& c = historyColumns()[index];
    ResultsData data = fixture();
    IterationRecord& row = data.history[1];
    if (c.rule == HistoryRule::rowIndex) {
      row.*(c.integer) = 7;
    } else if (c.type == HistoryColumnType::int32) {
      row.*(c.integer) = -1;
    } else if (c.nan == HistoryNaN::allowed) {
      row.*(c.real) = c.lower - 1.0;
    } else {
      row.*(c.real) = std::nan("");
    }
    const fs::path path = scratch(std::string(c.name) + ".h5");
    writeResultsFile(path.string(), data);
    const ResultsVerification verification = verifyResultsFile(path.string());
    const ResultsCheck* problem = verification.firstProblem();
    ASSERT_NE(problem, nullptr) << c.name;
    EXPECT_EQ(problem->object, std::string("/history/") + c.name) << problem->problem;
    EXPECT_NE(problem->problem.find("entry 1"), std::string::npos) << problem->problem;
    fs::remove(path);
  }
  fs::remove_all(scratch("x").parent_path());
}

}  // namespace
}  // namespace hindsight
