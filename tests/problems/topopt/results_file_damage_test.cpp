// readResultsFile on files whose attributes claim sizes the datasets do not have: it must refuse them
// with StorageError before allocating what the attributes claim (2^31 - 1 iterations would be 8 GiB
// of history; nx = ny = 2^31 - 1 overflowed the size of the designs buffer).
#include <hindsight/problems/topopt/optimization_run.h>
#include <hindsight/problems/topopt/results_file.h>
#include <hindsight/problems/topopt/run_fingerprint.h>

#include <gtest/gtest.h>
#include <hdf5.h>

#include <chrono>
#include <climits>
#include <ostream>

#include "support/storage_fixtures.h"

namespace hindsight {
namespace {

ResultsData small() {
  ResultsData data;
  data.configurationJson = "{}";
  data.nx = 4;
  data.ny = 2;
  for (int k = 0; k < 2; ++k) {
    data.history.push_back(IterationRecord{});
    data.densities.push_back(Vector::Constant(8, 0.5));
  }
  data.state.design = Vector::Constant(3, 0.5);
  data.state.mma.xold1 = data.state.mma.xold2 = data.state.mma.low = data.state.mma.upp = data.state.design;
  return data;
}

void setIntAttribute(const std::string& path, const char* name, int value) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const hid_t attribute = H5Aopen(file, name, H5P_DEFAULT);
  ASSERT_GE(attribute, 0);
  ASSERT_GE(H5Awrite(attribute, H5T_NATIVE_INT, &value), 0);
  H5Aclose(attribute);
  H5Fclose(file);
}

TEST(ResultsFileDamage, ClaimedSizesAreCheckedBeforeAllocating) {
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/hindsight_claimed_sizes.h5";
  const struct {
    const char* attribute;
    int value;
  } claims[] = {
      {"completed_iterations", INT_MAX}, {"nx", INT_MAX}, {"ny", INT_MAX}, {"completed_iterations", 3}};
  for (const auto& claim : claims) {
    writeResultsFile(path, small());
    setIntAttribute(path, claim.attribute, claim.value);
    if (claim.attribute != std::string("completed_iterations")) setIntAttribute(path, "nx", INT_MAX);
    const auto start = std::chrono::steady_clock::now();
    try {
      readResultsFile(path);
      ADD_FAILURE() << claim.attribute << " = " << claim.value << " accepted";
    } catch (const StorageError& e) {
      EXPECT_EQ(e.path(), path);
      EXPECT_NE(std::string(e.what()).find("shape the attributes give"), std::string::npos) << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << claim.attribute << " = " << claim.value << ": " << typeid(e).name() << " " << e.what();
    }
    // Refused from the shapes, not after filling gigabytes.
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0)
        << claim.attribute;
  }
}

// The configuration fingerprint the MPI ranks agreed on: stored, read back, and recomputed from the
// stored configuration by verify; a file whose configuration is not the agreed one (all its hashes
// consistent, as a run of ranks with different configurations would have written it) is refused.
TEST(ResultsFileFingerprint, StoredAndRecomputedFromTheConfiguration) {
  // A real run's file (a tiny rod, one iteration: milliseconds).
  Config config;
  config.rod.elementsAlongLength = 8;
  config.rod.elementsThroughHeight = 2;
  config.rod.modeCount = 2;
  config.rod.endTime = 0.02;
  config.rod.rampTime = 0.01;
  config.rod.eslSamples = 4;
  config.simulation.step = 1e-3;
  config.optimization.iterations = 1;
  OptimizationRunOptions options;
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  options.outputDirectory = scratch.path() + "/hindsight_fingerprint_run";
  options.force = true;
  {
    OptimizationRun run(config, options);
    std::ostream quiet(nullptr);
    run.run(quiet);
  }
  const std::string path = options.outputDirectory + "/results.h5";
  const std::string fingerprint = configurationFingerprint(config);
  ASSERT_EQ(fingerprint.rfind("fnv1a64:", 0), 0u);
  ASSERT_EQ(fingerprint.size(), 8u + 16u);
  const ResultsVerification sound = verifyResultsFile(path);
  EXPECT_EQ(sound.firstProblem(), nullptr);
  EXPECT_EQ(sound.configurationFingerprint, fingerprint);
  EXPECT_EQ(sound.ranks, 1);
  const ResultsData data = readResultsFile(path);
  EXPECT_EQ(data.configurationFingerprint, fingerprint);
  EXPECT_EQ(configurationFingerprint(data.configurationJson), fingerprint);

  // A file whose configuration is not the one the fingerprint names, every hash consistent.
  Config other = config;
  other.optimization.iterations = 8;
  ResultsData mixed = data;
  mixed.configurationFingerprint = configurationFingerprint(other);
  writeResultsFile(path, mixed);
  const ResultsVerification refused = verifyResultsFile(path);
  ASSERT_NE(refused.firstProblem(), nullptr);
  EXPECT_EQ(refused.firstProblem()->object, "/");
  EXPECT_NE(refused.firstProblem()->problem.find("configuration_fingerprint"), std::string::npos);
  EXPECT_THROW(readResultsFile(path), StorageError);

  // Files written before the fingerprint (none stored) are read as before.
  ResultsData old = data;
  old.configurationFingerprint.clear();
  old.ranks = 0;
  writeResultsFile(path, old);
  EXPECT_EQ(verifyResultsFile(path).firstProblem(), nullptr);
  EXPECT_TRUE(verifyResultsFile(path).configurationFingerprint.empty());
}

TEST(ResultsFileFingerprint, DifferingFieldsNameEachFieldIncludingOneSidedOnes) {
  Config a;
  Config b = a;
  EXPECT_TRUE(differingFields(toJson(a), toJson(b)).empty());
  EXPECT_EQ(configurationFingerprint(a), configurationFingerprint(b));
  b.optimization.iterations = a.optimization.iterations + 1;
  b.rod.endTime = a.rod.endTime * 2;
  EXPECT_EQ(differingFields(toJson(a), toJson(b)),
            (std::vector<std::string>{"optimization.iterations", "rod.endTime"}));
  EXPECT_NE(configurationFingerprint(a), configurationFingerprint(b));
  nlohmann::json withScenarios = toJson(a);
  withScenarios["scenarios"] = nlohmann::json::array({{{"name", "x"}}});
  nlohmann::json without = toJson(a);
  without.erase("scenarios");
  EXPECT_EQ(differingFields(withScenarios, without), std::vector<std::string>{"scenarios"});
  EXPECT_EQ(differingFields(without, withScenarios), std::vector<std::string>{"scenarios"});
}

}  // namespace
}  // namespace hindsight
