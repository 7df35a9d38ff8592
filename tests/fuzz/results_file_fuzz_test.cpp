// Fuzzing readResultsFile and readResultsConfiguration (problems/topopt/results_file.h): --resume reads
// whatever DIR/results.h5 holds, which after a disk fault, a foreign tool or a hand edit may be
// anything. For any file they must return consistent data or throw StorageError naming the file
// (path() and the message); never crash, never allocate what the file's attributes claim before the
// datasets confirm it, never throw another type.
#include "fuzz/hdf5_fuzz.h"
#include "support/file_checks.h"
#include "support/storage_fixtures.h"

#include <hindsight/problems/topopt/results_file.h>

namespace hindsight {
namespace {

// A small but complete results file: 3 iterations on a 5 x 3 grid, 6 design variables, finished
// with 2 modes of 8 DOFs.
ResultsData sample() {
  ResultsData data;
  data.configurationJson = R"({"rod": {"elementsAlongLength": 5, "elementsThroughHeight": 3}})";
  data.nx = 5;
  data.ny = 3;
  for (int k = 0; k < 3; ++k) {
    IterationRecord record;
    record.iteration = k;
    record.psi1 = 1.0 / (k + 1);
    record.psi2 = 2.0 / (k + 1);
    record.volumeFraction = 0.5;
    record.maxDesignChange = k == 2 ? std::numeric_limits<double>::quiet_NaN() : 0.1;
    record.backtracks = k;
    data.history.push_back(record);
    data.densities.push_back(Vector::Constant(data.nx * data.ny, 0.5));
  }
  data.state.iteration = 2;
  data.state.objectiveScale = 3.5;
  data.state.design = Vector::Constant(6, 0.5);
  data.state.mma.xold1 = data.state.mma.xold2 = data.state.design;
  data.state.mma.low = Vector::Zero(6);
  data.state.mma.upp = Vector::Ones(6);
  data.state.mma.iteration = 2;
  data.finished = true;
  data.finalModes = Matrix::Ones(8, 2);
  data.finalFrequenciesHz = {10.0, 20.0};
  return data;
}

// The invariants readResultsFile promises its caller (the resume path indexes by them).
void expectConsistent(const ResultsData& data, const std::string& what) {
  ASSERT_GE(data.nx, 1) << what;
  ASSERT_GE(data.ny, 1) << what;
  ASSERT_EQ(data.densities.size(), data.history.size()) << what;
  for (const Vector& grid : data.densities) ASSERT_EQ(grid.size(), Eigen::Index{data.nx} * data.ny) << what;
  const Eigen::Index n = data.state.design.size();
  ASSERT_GE(n, 1) << what;
  ASSERT_EQ(data.state.mma.xold1.size(), n) << what;
  ASSERT_EQ(data.state.mma.xold2.size(), n) << what;
  ASSERT_EQ(data.state.mma.low.size(), n) << what;
  ASSERT_EQ(data.state.mma.upp.size(), n) << what;
  ASSERT_EQ(static_cast<std::size_t>(data.finalModes.cols()), data.finalFrequenciesHz.size()) << what;
}

template <typename Read>
void expectStorageErrorNamingOr(Read&& read, const std::string& path, const std::string& what) {
  try {
    read();
  } catch (const StorageError& e) {
    EXPECT_EQ(e.path(), path) << what;
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
        << "message does not name the file: " << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw " << typeid(e).name() << " (" << e.what() << ") instead of StorageError for "
                  << what;
  }
}

void expectResultsOrStorageError(const std::string& path, const std::string& what) {
  expectStorageErrorNamingOr([&] { expectConsistent(readResultsFile(path), what); }, path, what);
  expectStorageErrorNamingOr([&] { readResultsConfiguration(path); }, path, what);
  EXPECT_EQ(fuzz::openHdf5Objects(), 0) << "identifiers left open after " << what;
}

const std::vector<std::string>& rootAttributes() {
  static const std::vector<std::string> names = {
      "format", "format_version", "configuration",  "completed_iterations", "finished", "nx",
      "ny",     "updates",        "objective_scale"};
  return names;
}

// A good file with one to three of its objects replaced: attributes by random scalars, arrays and
// strings (counts that disagree with the datasets, negative and huge sizes); datasets deleted, replaced
// by a group or by data of another shape and type; groups deleted.
TEST(ResultsFileFuzz, DamagedObjects) {
  const fuzz::QuietHdf5 quiet;
  const ResultsData data = sample();
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string good = scratch.path() + "/hindsight_fuzz_results_good.h5";
  const std::string path = scratch.path() + "/hindsight_fuzz_results.h5";
  writeResultsFile(good, data);
  const std::string bytes = fuzz::readText(good);
  expectResultsOrStorageError(good, "the good file");
  fuzz::Mutator mutator(fuzz::seed(31));
  for (int k = 0; k < fuzz::cases(400); ++k) {
    fuzz::writeText(path, bytes);
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    std::string what = "case " + std::to_string(k) + ":";
    const int edits = 1 + static_cast<int>(mutator.below(3));
    for (int e = 0; e < edits; ++e) {
      switch (mutator.below(6)) {
        case 0:
        case 1: {
          const std::string& name = mutator.pick(rootAttributes());
          fuzz::writeRandomAttribute(mutator, file, name.c_str());
          what += " attribute " + name + " replaced;";
          break;
        }
        case 2: {
          const hid_t state = H5Gopen2(file, "state", H5P_DEFAULT);
          if (state >= 0) {
            fuzz::writeRandomAttribute(mutator, state, "mma_iteration");
            H5Gclose(state);
          }
          what += " attribute state/mma_iteration replaced;";
          break;
        }
        case 3: {
          const std::string& name = mutator.pick(testing::resultsDatasets());
          H5Ldelete(file, name.c_str(), H5P_DEFAULT);
          what += " " + name + " deleted;";
          break;
        }
        case 4: {
          const std::string& name = mutator.pick(testing::resultsDatasets());
          if (H5Ldelete(file, name.c_str(), H5P_DEFAULT) >= 0) {
            if (mutator.chance(0.2)) {
              const hid_t group = H5Gcreate2(file, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
              if (group >= 0) H5Gclose(group);
              what += " " + name + " made a group;";
            } else {
              fuzz::writeRandomDataset(mutator, file, name.c_str(), {3, 3, 5});
              what += " " + name + " replaced;";
            }
          }
          break;
        }
        default: {
          const char* groups[] = {"history", "state", "final"};
          const char* group = groups[mutator.below(3)];
          H5Ldelete(file, group, H5P_DEFAULT);
          what += std::string(" group ") + group + " deleted;";
          break;
        }
      }
    }
    H5Fclose(file);
    expectResultsOrStorageError(path, what);
    if (HasFailure()) return;  // the first failing input is the useful one
  }
}

// A good file cut short or with damaged bytes.
TEST(ResultsFileFuzz, DamagedBytes) {
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string good = scratch.path() + "/hindsight_fuzz_results_good.h5";
  const std::string path = scratch.path() + "/hindsight_fuzz_results_bytes.h5";
  writeResultsFile(good, sample());
  const std::string bytes = fuzz::readText(good);
  fuzz::Mutator mutator(fuzz::seed(32));
  for (int k = 0; k < fuzz::cases(400); ++k) {
    const std::string damaged = fuzz::damageBytes(mutator, bytes);
    fuzz::writeText(path, damaged);
    expectResultsOrStorageError(
        path, "case " + std::to_string(k) + " (" + std::to_string(damaged.size()) + " bytes)");
    if (HasFailure()) return;
  }
}

}  // namespace
}  // namespace hindsight
