#include <hindsight/problems/rod/design_io.h>

#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/storage/hdf5.h>

#include <gtest/gtest.h>

#include <cstdio>
#include <limits>

#include "support/storage_fixtures.h"

namespace hindsight {
namespace {

rod::RodConfig coarse() {
  rod::RodConfig config;
  config.elementsAlongLength = 7;
  config.elementsThroughHeight = 4;
  return config;
}

TEST(DesignIo, RoundTripAndLayoutMatchTheFeModel) {
  const rod::RodConfig config = coarse();
  Vector x(config.designCount());
  for (Eigen::Index d = 0; d < x.size(); ++d) x(d) = 0.01 + 0.9 * d / x.size();
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/design.h5";
  writeDesignFields(path, config, {{"x", x}}, 1.0);
  EXPECT_EQ(readDesignFile(path, config), x);
  // Grid cell (row j, column i) holds the design variable of FeModel element i * ny + j.
  const rod::FeModel model(config, x);
  const std::vector<double> grid = designToGrid(config, x, 1.0);
  for (int d = 0; d < config.designCount(); ++d) {
    const int e = model.designToElement(d);
    const int i = e / config.elementsThroughHeight, j = e % config.elementsThroughHeight;
    EXPECT_EQ(grid[j * config.elementsAlongLength + i], x(d));
  }
  EXPECT_EQ(grid[0], 1.0);  // interface column
}

TEST(DesignIo, BadFilesAreNamed) {
  const rod::RodConfig config = coarse();
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/bad_design.h5";
  Vector x = Vector::Constant(config.designCount(), 0.5);
  x(5) = 0.001;
  writeDesignFields(path, config, {{"x", x}}, 1.0);
  try {
    readDesignFile(path, config);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("x[1][2]"), std::string::npos) << e.what();
  }
  writeDesignFields(path, config, {{"y", x}}, 1.0);
  EXPECT_THROW(readDesignFile(path, config), std::invalid_argument);
  rod::RodConfig other = config;
  other.elementsAlongLength = 9;
  writeDesignFields(path, config, {{"x", Vector::Constant(config.designCount(), 0.5)}}, 1.0);
  EXPECT_THROW(readDesignFile(path, other), std::invalid_argument);
  EXPECT_THROW(writeDesignFields("/nonexistent/dir/f.h5", config, {{"x", x}}, 1.0), StorageError);
}

// The interface columns hold 1 in every design; another value there used to be replaced by 1
// silently. NaN densities are refused like any value outside [designLowerBound, 1].
TEST(DesignIo, InterfaceColumnsOtherThanOneAndNanAreRefusedNamingTheElement) {
  const rod::RodConfig config = coarse();
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/interface_design.h5";
  const Vector x = Vector::Constant(config.designCount(), 0.5);
  const auto messageOf = [&] {
    try {
      readDesignFile(path, config);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("<accepted>");
  };
  writeDesignFields(path, config, {{"x", x}}, 0.25);  // both end columns hold 0.25
  std::string message = messageOf();
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("x[0][0] (row 0, interface column 0) = 0.25"), std::string::npos) << message;

  // Only the last column of the top row is wrong.
  std::vector<double> grid = designToGrid(config, x, 1.0);
  const int nx = config.elementsAlongLength, ny = config.elementsThroughHeight;
  grid[static_cast<std::size_t>(ny - 1) * nx + nx - 1] = 0.5;
  {
    hdf5::Handle file = hdf5::createFile(path, H5F_ACC_TRUNC);
    hdf5::writeDoubles(file.get(), "x", {static_cast<hsize_t>(ny), static_cast<hsize_t>(nx)}, grid.data());
    hdf5::closeFile(file);
  }
  message = messageOf();
  EXPECT_NE(message.find("x[3][6] (row 3, interface column 6) = 0.5 must be 1"), std::string::npos)
      << message;

  Vector nan = x;
  nan(3) = std::numeric_limits<double>::quiet_NaN();
  writeDesignFields(path, config, {{"x", nan}}, 1.0);
  message = messageOf();
  EXPECT_NE(message.find("= nan is outside"), std::string::npos) << message;
}

}  // namespace
}  // namespace hindsight
