#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/solid_member.h>
#include <hindsight/problems/rod/subtree_ldlt.h>

#include "support/random_design.h"
#include "support/random_solid.h"
#include "support/same_bits.h"

#include <gtest/gtest.h>
#include <metis.h>
#include <Eigen/MetisSupport>
#include <Eigen/SparseCholesky>

#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {
namespace rod {
namespace {

using testing::sameBits;

using RowBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

FeModel randomModel(int along, int through, unsigned seed) {
  RodConfig config;
  config.elementsAlongLength = along;
  config.elementsThroughHeight = through;
  return FeModel(config, hindsight::testing::randomRodDesign(config, seed));
}

using hindsight::testing::randomSolidHalf;

// Both sweeps are Eigen's serial results bit for bit, for every partition of the elimination tree (the
// schedule decides only which rows run at the same time), on the factor of the analysed design and on a
// refactorised one (the schedule depends on the pattern alone). With METIS's ordering the reference is
// Eigen's SimplicialLDLT with Eigen's own METIS wrapper as its ordering (the same permutation as
// metisOrdering, tested below).
void expectEigensBits(const SparseMatrix& k, const SparseMatrix& other, SubtreeSchedule options,
                      const std::string& label, FillOrdering ordering = FillOrdering::Amd) {
  SubtreeParallelLdlt subtree(k, options, ordering);
  ASSERT_EQ(subtree.info(), Eigen::Success) << label;
  ASSERT_EQ(subtree.ordering(), ordering);
  // The tree was split, or the test would compare Eigen with itself. (METIS's top separators are dense
  // chains: on the small solid of the test a third to a half of the work is in the subtrees.)
  if (options.groups >= 2)
    EXPECT_GT(subtree.parallelShare(), ordering == FillOrdering::Amd ? 0.5 : 0.3) << label;
  for (const SparseMatrix* matrix : {&k, &other}) {
    if (matrix == &other) subtree.factorize(other);
    Eigen::SimplicialLDLT<SparseMatrix> amd;
    Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::MetisOrdering<int>> metis;
    if (ordering == FillOrdering::Amd)
      amd.compute(*matrix);
    else
      metis.compute(*matrix);
    ASSERT_EQ(ordering == FillOrdering::Amd ? amd.info() : metis.info(), Eigen::Success);
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
        const auto solveL = [&](Vector& v) {
          if (ordering == FillOrdering::Amd)
            amd.matrixL().solveInPlace(v);
          else
            metis.matrixL().solveInPlace(v);
        };
        const auto solveU = [&](Vector& v) {
          if (ordering == FillOrdering::Amd)
            amd.matrixU().solveInPlace(v);
          else
            metis.matrixU().solveInPlace(v);
        };
        solveL(expected);
        const Vector gotForward = forward.col(c);
        EXPECT_TRUE(sameBits(expected, gotForward))
            << where << ": L^-1, max difference " << (expected - gotForward).cwiseAbs().maxCoeff();
        expected = rhs.col(c);
        solveU(expected);
        for (const RowBlock* block : {&backward, &serial}) {
          const Vector got = block->col(c);
          EXPECT_TRUE(sameBits(expected, got))
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

TEST(SubtreeParallelLdlt, MetisOrderedSweepsAreEigensBitsForEveryPartition) {
  const SolidMember model = randomSolidHalf(30, 6, 4, 3), other = randomSolidHalf(30, 6, 4, 4);
  for (const int groups : {1, 2, 3, 5}) {
    SubtreeSchedule options;
    options.groups = groups;
    options.smallest = 0;
    expectEigensBits(model.stiffness(), other.stiffness(), options,
                     "METIS, " + std::to_string(groups) + " groups", FillOrdering::Metis);
  }
}

TEST(SubtreeParallelLdlt, MetisOrderingIsMetisNodeNdOfTheSymmetricPattern) {
  // The same permutation as Eigen's own wrapper, which hands METIS_NodeND the graph of A + A^T (of the
  // full symmetric matrix here) with its default options; a function of the pattern alone (the same on
  // a second call and for other values). (Fewer nonzeros in L than AMD's is not a property of every
  // mesh: on this 30 x 6 x 4 half METIS leaves 414 k against AMD's 394 k; on the production bars it
  // leaves 28-35 % fewer, bench/RESULTS.md.)
  const SolidMember model = randomSolidHalf(30, 6, 4, 5), other = randomSolidHalf(30, 6, 4, 6);
  const SparseMatrix& k = model.stiffness();
  const auto ours = metisOrdering(k);
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> eigens;
  const SparseMatrix full = k.selfadjointView<Eigen::Lower>();
  Eigen::MetisOrdering<int>()(full, eigens);
  ASSERT_EQ(eigens.size(), k.rows());
  EXPECT_TRUE((ours.indices().array() == eigens.indices().array()).all());
  EXPECT_TRUE((metisOrdering(other.stiffness()).indices().array() == ours.indices().array()).all());
  // Orderings made at the same time on several threads (concurrent evaluations, each with its own
  // factorisation) are each the pattern's: METIS's random generator is the process's, so the calls are
  // serialised.
  std::vector<Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>> concurrent(4);
  parallelFor(4, [&](int i) {
    concurrent[static_cast<std::size_t>(i)] = metisOrdering(i % 2 ? other.stiffness() : k);
  });
  for (const auto& permutation : concurrent)
    EXPECT_TRUE((permutation.indices().array() == ours.indices().array()).all());
  EXPECT_EQ(metisOrdering(SparseMatrix(0, 0)).size(), 0);
  EXPECT_THROW(metisOrdering(SparseMatrix(3, 2)), std::invalid_argument);
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
