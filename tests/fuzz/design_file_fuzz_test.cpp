// Fuzzing readDesignFile (problems/rod/design_io.h): a design file is a user's input (--design), so
// for any file it must either return a design of the configuration's size with every value in
// [designLowerBound, 1], or throw std::invalid_argument naming the file (the CLI's exit code 2).
#include "fuzz/hdf5_fuzz.h"
#include "support/storage_fixtures.h"

#include <hindsight/problems/rod/design_io.h>

namespace hindsight {
namespace {

rod::RodConfig coarse() {
  rod::RodConfig config;
  config.elementsAlongLength = 7;
  config.elementsThroughHeight = 4;
  return config;
}

void expectDesignOrInvalidArgument(const std::string& path, const rod::RodConfig& config,
                                   const std::string& what) {
  try {
    const Vector design = readDesignFile(path, config);
    ASSERT_EQ(design.size(), config.designCount()) << what;
    for (Eigen::Index d = 0; d < design.size(); ++d) {
      ASSERT_TRUE(design(d) >= config.designLowerBound && design(d) <= 1.0)
          << "x[" << d << "] = " << design(d) << " accepted from " << what;
    }
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
        << "message does not name the file: " << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw " << typeid(e).name() << " (" << e.what()
                  << ") instead of std::invalid_argument for " << what;
  }
  EXPECT_EQ(fuzz::openHdf5Objects(), 0) << "identifiers left open after " << what;
}

// Files made with the C API: dataset x (or a look-alike name, or a group x) of any rank, shape and type,
// holding values in and out of range, NaN and infinities, next to other objects.
TEST(DesignFileFuzz, RandomObjects) {
  const fuzz::QuietHdf5 quiet;
  const rod::RodConfig config = coarse();
  const std::vector<hsize_t> shape = {static_cast<hsize_t>(config.elementsThroughHeight),
                                      static_cast<hsize_t>(config.elementsAlongLength)};
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/hindsight_fuzz_design.h5";
  fuzz::Mutator mutator(fuzz::seed(21));
  for (int k = 0; k < fuzz::cases(300); ++k) {
    const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(file, 0) << path;
    std::string what = "case " + std::to_string(k) + ":";
    const std::size_t layout = mutator.below(10);
    if (layout == 0) {
      H5Gclose(H5Gcreate2(file, "x", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
      what += " group x";
    } else if (layout == 1) {
      fuzz::writeRandomDataset(mutator, file, "X", shape);
      what += " dataset X only";
    } else {
      const std::vector<hsize_t> dims = fuzz::randomDims(mutator, shape);
      fuzz::writeRandomDataset(mutator, file, "x", dims);
      what += " dataset x of rank " + std::to_string(dims.size());
      if (mutator.chance(0.3)) fuzz::writeRandomDataset(mutator, file, "gradient", shape);
    }
    H5Fclose(file);
    expectDesignOrInvalidArgument(path, config, what);
    if (HasFailure()) return;  // the first failing input is the useful one
  }
}

// A good design file cut short or with damaged bytes.
TEST(DesignFileFuzz, DamagedBytes) {
  const rod::RodConfig config = coarse();
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string good = scratch.path() + "/hindsight_fuzz_design_good.h5";
  const std::string path = scratch.path() + "/hindsight_fuzz_design_damaged.h5";
  writeDesignFields(good, config, {{"x", Vector::Constant(config.designCount(), 0.5)}}, 1.0);
  const std::string bytes = fuzz::readText(good);
  ASSERT_GT(bytes.size(), 8u);
  fuzz::Mutator mutator(fuzz::seed(22));
  for (int k = 0; k < fuzz::cases(250); ++k) {
    const std::string damaged = fuzz::damageBytes(mutator, bytes);
    fuzz::writeText(path, damaged);
    expectDesignOrInvalidArgument(
        path, config, "case " + std::to_string(k) + " (" + std::to_string(damaged.size()) + " bytes)");
    if (HasFailure()) return;
  }
}

}  // namespace
}  // namespace hindsight
