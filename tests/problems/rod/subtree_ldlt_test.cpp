#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/subtree_ldlt.h>

#include <gtest/gtest.h>
#include <Eigen/SparseCholesky>

#include <cstring>
#include <random>
#include <string>

namespace hindsight {
namespace rod {
namespace {

using RowBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

bool sameBits(const double* a, const double* b, Eigen::Index count) {
  return std::memcmp(a, b, sizeof(double) * static_cast<std::size_t>(count)) == 0;
}

FeModel randomModel(int along, int through, unsigned seed) {
  RodConfig config;
  config.elementsAlongLength = along;
  config.elementsThroughHeight = through;
  std::mt19937 generator(seed);
  std::uniform_real_distribution<double> uniform(0.01, 1.0);
  Vector design(config.designCount());
  for (auto& x : design) x = uniform(generator);
  return FeModel(config, design);
}

// Both sweeps are Eigen's serial results bit for bit, for every partition of the elimination tree (the
// schedule decides only which rows run at the same time), on the factor of the analysed design and on a
// refactorised one (the schedule depends on the pattern alone).
void expectEigensBits(const SparseMatrix& k, const SparseMatrix& other, SubtreeSchedule options,
                      const std::string& label) {
  SubtreeParallelLdlt subtree(k, options);
  ASSERT_EQ(subtree.info(), Eigen::Success) << label;
  // The tree was split, or the test would compare Eigen with itself.
  if (options.groups >= 2) EXPECT_GT(subtree.parallelShare(), 0.5) << label;
  for (const SparseMatrix* matrix : {&k, &other}) {
    if (matrix == &other) subtree.factorize(other);
    const Eigen::SimplicialLDLT<SparseMatrix> eigen(*matrix);
    ASSERT_EQ(eigen.info(), Eigen::Success);
    for (const int columns : {1, 3, 11}) {
      const Matrix rhs = Matrix::Random(k.rows(), columns);
      RowBlock forward = rhs, backward = rhs, serial = rhs;
      subtree.forwardSweep(forward.data(), columns);
      subtree.backwardSweep(backward.data(), columns, true);
      subtree.backwardSweep(serial.data(), columns, false);
      for (int c = 0; c < columns; ++c) {
        const std::string where = label + (matrix == &k ? "" : ", refactorised") + ", column " +
                                  std::to_string(c) + " of " + std::to_string(columns);
        Vector expected = rhs.col(c);
        eigen.matrixL().solveInPlace(expected);
        const Vector gotForward = forward.col(c);
        EXPECT_TRUE(sameBits(expected.data(), gotForward.data(), expected.size()))
            << where << ": L^-1, max difference " << (expected - gotForward).cwiseAbs().maxCoeff();
        expected = rhs.col(c);
        eigen.matrixU().solveInPlace(expected);
        for (const RowBlock* block : {&backward, &serial}) {
          const Vector got = block->col(c);
          EXPECT_TRUE(sameBits(expected.data(), got.data(), expected.size()))
              << where << ": L^-T " << (block == &backward ? "on the subtrees" : "serial")
              << ", max difference " << (expected - got).cwiseAbs().maxCoeff();
        }
      }
    }
  }
}

TEST(SubtreeParallelLdlt, SweepsAreEigensBitsForEveryPartition) {
  const FeModel model = randomModel(60, 8, 3), other = randomModel(60, 8, 4);
  for (const int groups : {1, 2, 3, 5}) {
    SubtreeSchedule options;
    options.groups = groups;
    options.smallest = 0;
    expectEigensBits(model.stiffness(), other.stiffness(), options, std::to_string(groups) + " groups");
  }
}

TEST(SubtreeParallelLdlt, DefaultThresholdSplitsAProductionSizedMesh) {
  // 400 x 24: order 20 050, above the threshold, so the default schedule runs in parallel.
  const FeModel model = randomModel(400, 24, 11), other = randomModel(400, 24, 12);
  SubtreeSchedule options;
  options.groups = 2;
  ASSERT_GT(model.stiffness().rows(), options.smallest);
  expectEigensBits(model.stiffness(), other.stiffness(), options, "400 x 24");
}

TEST(SubtreeParallelLdlt, SmallMatricesStaySerial) {
  const FeModel model = randomModel(40, 6, 1);
  SubtreeSchedule options;
  options.groups = 2;
  const SubtreeParallelLdlt subtree(model.stiffness(), options);
  EXPECT_EQ(subtree.parallelShare(), 0.0);
}

TEST(SubtreeParallelLdlt, TheDefaultScheduleFollowsTheThreadLimit) {
  // groups = 0 takes the threads parallelFor may use when the pattern is analysed: --threads 1 runs the
  // sweep serially, more threads split the tree (the bits are the same either way, tested above).
  const FeModel model = randomModel(400, 24, 13);
  {
    const ThreadLimit limit(1);
    EXPECT_EQ(parallelConcurrency(), 1);
    EXPECT_EQ(SubtreeParallelLdlt(model.stiffness()).parallelShare(), 0.0);
  }
  if (!threadsSupported() || availableThreads() < 2) GTEST_SKIP() << "one thread only on this machine";
  const ThreadLimit limit(2);
  EXPECT_EQ(parallelConcurrency(), 2);
  EXPECT_GT(SubtreeParallelLdlt(model.stiffness()).parallelShare(), 0.5);
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
