#include <hindsight/problems/rod/compensated_kernels.h>

#include "support/run_cli.h"
#include "support/same_bits.h"

#include <gtest/gtest.h>
#include <Eigen/Sparse>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {
namespace rod {
namespace {

using testing::sameBits;

// Entries spread over many decades with both signs, as a stiffness contrast of 1e5 and modes give them.
double spread(std::mt19937_64& generator) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0), decades(-6.0, 6.0);
  return unit(generator) * std::pow(10.0, decades(generator));
}

// The column counts cover a vector loop's remainder (1, 3, 5, 7 columns) and whole vectors (4, 8, 12).
const int kColumnCounts[] = {1, 3, 4, 5, 7, 8, 11, 12};

// The double-double element products are exact to about eps^2 of the terms' magnitude where the sum
// nearly cancels (row 0 below, as Ke0 X_e does for a rigid-body motion), and the plain double sum is not:
// the kernel is accurate, not only reproducible. Checked against long double where it is wider.
TEST(CompensatedKernels, ElementProductsResolveCancellation) {
  if (std::numeric_limits<long double>::digits <= std::numeric_limits<double>::digits)
    GTEST_SKIP() << "long double is no wider than double here: no reference";
  std::mt19937_64 generator(3);
  double unit[64];
  for (double& u : unit) u = spread(generator);
  const int columns = 5;
  std::vector<double> x(8 * columns), product(8 * columns), high(columns), low(columns);
  for (double& value : x) value = spread(generator);
  for (int c = 0; c < columns; ++c) {  // x(7, c) cancels row 0's sum up to rounding
    double partial = 0.0;
    for (int b = 0; b < 7; ++b) partial += unit[8 * b] * x[b * columns + c];
    x[7 * columns + c] = -partial / unit[56];
  }
  for (KernelIsa isa : {KernelIsa::Baseline, KernelIsa::Fma}) {
    if (!kernelIsaAvailable(isa)) continue;
    compensatedElementProducts(unit, 8, x.data(), columns, true, product.data(), high.data(), low.data(),
                               isa);
    for (int c = 0; c < columns; ++c) {
      long double exact = 0.0L, magnitude = 0.0L;
      double plain = 0.0;
      for (int b = 0; b < 8; ++b) {
        exact += static_cast<long double>(unit[8 * b]) * static_cast<long double>(x[b * columns + c]);
        magnitude += std::abs(static_cast<long double>(unit[8 * b]) * x[b * columns + c]);
        plain += unit[8 * b] * x[b * columns + c];
      }
      // long double carries 64 bits: its own error is ~5e-20 of the magnitude.
      EXPECT_LE(std::abs(product[8 * c] - exact), 1e-18L * magnitude + 1.2e-16L * std::abs(exact)) << c;
      EXPECT_GT(std::abs(plain - exact), 1e-18L * magnitude + 1.2e-16L * std::abs(exact)) << c;
    }
  }
}

// Baseline (Dekker's split, and std::fma outside its range) and FMA give the same bits, for every column
// count, inside and outside the split's range.
TEST(CompensatedKernels, ElementProductsAreBitwiseEqualForEveryIsa) {
  if (!kernelIsaAvailable(KernelIsa::Fma)) GTEST_SKIP() << "no AVX2 and FMA here: only the baseline runs";
  std::mt19937_64 generator(5);
  for (int columns : kColumnCounts) {
    for (int pass = 0; pass < 2; ++pass) {
      double unit[64];
      for (double& u : unit) u = spread(generator);
      std::vector<double> x(static_cast<std::size_t>(8 * columns));
      for (double& value : x) value = spread(generator);
      if (pass == 1) {  // outside the split's range: the baseline takes std::fma
        unit[9] = 1e-200;
        x[0] = 1e200;
      }
      std::vector<double> baseline(x.size()), fused(x.size()), high(columns), low(columns);
      compensatedElementProducts(unit, 8, x.data(), columns, pass == 0, baseline.data(), high.data(),
                                 low.data(), KernelIsa::Baseline);
      compensatedElementProducts(unit, 8, x.data(), columns, pass == 0, fused.data(), high.data(), low.data(),
                                 KernelIsa::Fma);
      EXPECT_TRUE(sameBits(baseline, fused)) << columns << " columns, pass " << pass;
    }
  }
}

TEST(CompensatedKernels, SparseUpdateIsBitwiseEqualForEveryIsaAndSkipsZeros) {
  std::mt19937_64 generator(7);
  const int rows = 40;
  Eigen::SparseMatrix<double> a(rows, rows);
  std::vector<Eigen::Triplet<double>> entries;
  std::uniform_int_distribution<int> index(0, rows - 1);
  for (int k = 0; k < 6 * rows; ++k)
    entries.emplace_back(index(generator), index(generator), spread(generator));
  a.setFromTriplets(entries.begin(), entries.end());
  a.makeCompressed();
  for (int columns : kColumnCounts) {
    std::vector<double> x(static_cast<std::size_t>(rows * columns)), start(x.size());
    for (double& value : x) value = spread(generator);
    for (double& value : start) value = spread(generator);
    x[5 * columns] = 0.0;  // a row with one zero: that term is skipped, the others are not
    auto update = [&](KernelIsa isa, bool dekker) {
      std::vector<double> high = start, low(start.size(), 0.0);
      compensatedSparseUpdate(rows, a.outerIndexPtr(), a.innerIndexPtr(), a.valuePtr(), x.data(), columns,
                              dekker, high.data(), low.data(), isa);
      for (std::size_t i = 0; i < high.size(); ++i) high[i] += low[i];
      return high;
    };
    // The reference: the same sums written out column by column, each error by std::fma, zeros skipped.
    std::vector<double> reference = start, referenceLow(start.size(), 0.0);
    for (int c = 0; c < columns; ++c)
      for (int k = 0; k < rows; ++k) {
        const double xk = x[static_cast<std::size_t>(k * columns + c)];
        if (xk == 0.0) continue;
        for (Eigen::SparseMatrix<double>::InnerIterator it(a, k); it; ++it) {
          const std::size_t slot = static_cast<std::size_t>(it.index() * columns + c);
          const double product = -it.value() * xk;
          const double error = std::fma(-it.value(), xk, -product);
          const double sum = reference[slot] + product;
          const double virtualB = sum - reference[slot];
          const double sumError = (reference[slot] - (sum - virtualB)) + (product - virtualB);
          reference[slot] = sum;
          referenceLow[slot] += sumError + error;
        }
      }
    for (std::size_t i = 0; i < reference.size(); ++i) reference[i] += referenceLow[i];
    EXPECT_TRUE(sameBits(update(KernelIsa::Baseline, true), reference)) << columns << " columns";
    EXPECT_TRUE(sameBits(update(KernelIsa::Baseline, false), reference)) << columns << " columns";
    if (kernelIsaAvailable(KernelIsa::Fma))
      EXPECT_TRUE(sameBits(update(KernelIsa::Fma, true), reference)) << columns << " columns";
  }
}

// HINDSIGHT_KERNELS: auto (or unset, or empty) picks the faster available build, baseline and fma ask
// for one; anything else, and fma where it is missing, is an error that names the variable.
TEST(CompensatedKernels, TheSettingNamesTheVariableAndTheAllowedValues) {
  const KernelIsa best = kernelIsaAvailable(KernelIsa::Fma) ? KernelIsa::Fma : KernelIsa::Baseline;
  EXPECT_EQ(kernelIsaFromSetting(nullptr), best);
  EXPECT_EQ(kernelIsaFromSetting(""), best);
  EXPECT_EQ(kernelIsaFromSetting("auto"), best);
  EXPECT_EQ(kernelIsaFromSetting("baseline"), KernelIsa::Baseline);
  if (kernelIsaAvailable(KernelIsa::Fma))
    EXPECT_EQ(kernelIsaFromSetting("fma"), KernelIsa::Fma);
  else
    EXPECT_THROW(kernelIsaFromSetting("fma"), std::invalid_argument);
  for (const char* wrong : {"avx2", "Baseline", "fma ", "1"}) {
    try {
      kernelIsaFromSetting(wrong);
      ADD_FAILURE() << wrong << " was accepted";
    } catch (const std::invalid_argument& error) {
      const std::string message = error.what();
      EXPECT_NE(message.find("HINDSIGHT_KERNELS"), std::string::npos) << message;
      EXPECT_NE(message.find("auto, baseline, fma"), std::string::npos) << message;
    }
  }
}

TEST(CompensatedKernels, TheBaselineIsAlwaysAvailableAndTheDefaultIsAvailable) {
  EXPECT_TRUE(kernelIsaAvailable(KernelIsa::Baseline));
  EXPECT_TRUE(kernelIsaAvailable(defaultKernelIsa()));
  if (!kernelIsaAvailable(KernelIsa::Fma)) {
    double unit[64] = {}, x[8] = {}, product[8], high[1], low[1];
    EXPECT_THROW(compensatedElementProducts(unit, 8, x, 1, true, product, high, low, KernelIsa::Fma),
                 std::invalid_argument);
  }
}

#ifdef HINDSIGHT_CLI_PATH
// The tool checks HINDSIGHT_KERNELS before any command starts: exit 2 with the variable's name and the
// allowed values, and an optimisation leaves no output directory behind.
TEST(CompensatedKernels, TheToolRefusesAWrongSettingBeforeItStarts) {
  const std::string out = ::testing::TempDir() + "hindsight_kernels_refused";
  std::filesystem::remove_all(out);
  ::setenv("HINDSIGHT_KERNELS", "avx512", 1);
  const hindsight::testing::CliResult optimize =
      hindsight::testing::runCli("optimize --iterations 1 --out " + out);
  const hindsight::testing::CliResult evaluate = hindsight::testing::runCli("evaluate");
  ::setenv("HINDSIGHT_KERNELS", "baseline", 1);
  const hindsight::testing::CliResult baseline = hindsight::testing::runCli(
      "evaluate --set rod.elementsAlongLength=20 --set rod.elementsThroughHeight=4 --set rod.modeCount=4");
  ::unsetenv("HINDSIGHT_KERNELS");
  for (const auto& run : {optimize, evaluate}) {
    EXPECT_EQ(run.exitCode, 2) << run.output;
    EXPECT_NE(
        run.output.find("HINDSIGHT_KERNELS = 'avx512' is not one of the allowed values auto, baseline, fma"),
        std::string::npos)
        << run.output;
  }
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_EQ(baseline.exitCode, 0) << baseline.output;
}
#endif

}  // namespace
}  // namespace rod
}  // namespace hindsight
