// Eigen's product blocking pinned at load (engine/dense_blocking.h): the sizes are the pinned ones in a
// program that never names them, a product whose inner dimension is blocked gives other bits with
// another CPU's sizes and the pinned bits again once pinned, and the emulation setting is parsed or
// refused naming the variable.
#include <hindsight/engine/dense_blocking.h>

#include "support/run_cli.h"
#include "support/same_bits.h"

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include <cstdlib>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

using testing::sameBits;

Eigen::MatrixXd seeded(int rows, int cols, unsigned seed) {
  std::mt19937_64 generator(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Eigen::MatrixXd m(rows, cols);
  for (Eigen::Index j = 0; j < m.cols(); ++j)
    for (Eigen::Index i = 0; i < m.rows(); ++i) m(i, j) = uniform(generator);
  return m;
}

TEST(DenseBlocking, ThePinnedSizesHoldInAProgramThatNeverNamesThem) {
  EXPECT_TRUE(denseBlockingCacheSizes() == kPinnedCacheSizes)
      << describeCacheSizes(denseBlockingCacheSizes());
}

TEST(DenseBlocking, AnotherCpusSizesChangeTheBitsAndThePinRestoresThem) {
  // Inner dimension 4000: Eigen splits it into panels whose depth follows the L1 and L2 it plans with.
  const Eigen::MatrixXd a = seeded(4000, 24, 1), b = seeded(4000, 24, 2);
  const Eigen::MatrixXd pinned = a.transpose() * b;
  Eigen::setCpuCacheSizes(48 * 1024, 2 * 1024 * 1024, 105 * 1024 * 1024);  // an Intel Xeon's
  const Eigen::MatrixXd other = a.transpose() * b;
  pinDenseBlocking();
  const Eigen::MatrixXd again = a.transpose() * b;
  EXPECT_FALSE(sameBits(pinned, other))
      << "the blocking did not reach the product's bits: the test shows nothing";
  EXPECT_TRUE(sameBits(pinned, again));
  EXPECT_LT((pinned - other).cwiseAbs().maxCoeff(), 1e-12);  // the same sums, rounded elsewhere
}

TEST(DenseBlocking, TheEmulationSettingIsParsedOrRefusedNamingTheVariable) {
  EXPECT_FALSE(emulatedCacheSizesFromSetting(nullptr));
  EXPECT_FALSE(emulatedCacheSizesFromSetting(""));
  const auto sizes = emulatedCacheSizesFromSetting("49152,2097152,110100480");
  ASSERT_TRUE(sizes);
  EXPECT_EQ(sizes->l1, 49152);
  EXPECT_EQ(sizes->l2, 2097152);
  EXPECT_EQ(sizes->l3, 110100480);
  for (const char* bad : {"abc", "49152,2097152", "49152,2097152,110100480,1", "512,2097152,110100480",
                          "49152,,110100480", "49152,2097152,-1", "49152,2097152,2199023255553", "4e4,1,1"}) {
    try {
      emulatedCacheSizesFromSetting(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("HINDSIGHT_EMULATE_CPU_CACHES"), std::string::npos) << e.what();
    }
  }
}

#ifdef HINDSIGHT_CLI_PATH
// The tool refuses a malformed setting before any command starts (exit 2, naming the variable), and an
// optimisation leaves no output directory behind; a well-formed one changes no bit (the pin follows it).
TEST(DenseBlocking, TheToolRefusesAMalformedEmulationBeforeItStarts) {
  const std::string out = ::testing::TempDir() + "hindsight_emulation_refused";
  std::filesystem::remove_all(out);
  ::setenv("HINDSIGHT_EMULATE_CPU_CACHES", "48K,2M,105M", 1);
  const hindsight::testing::CliResult optimize =
      hindsight::testing::runCli("optimize --iterations 1 --out " + out);
  ::unsetenv("HINDSIGHT_EMULATE_CPU_CACHES");
  EXPECT_EQ(optimize.exitCode, 2) << optimize.output;
  EXPECT_NE(optimize.output.find("HINDSIGHT_EMULATE_CPU_CACHES = '48K,2M,105M'"), std::string::npos)
      << optimize.output;
  EXPECT_FALSE(std::filesystem::exists(out));
}
#endif

}  // namespace
}  // namespace hindsight
