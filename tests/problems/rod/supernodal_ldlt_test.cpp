#include <hindsight/problems/rod/modal_reduction.h>
#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/rod/solid_member.h>
#include <hindsight/problems/rod/supernodal_ldlt.h>

#include "support/allocation_counting.h"
#include "support/random_design.h"
#include "support/random_solid.h"
#include "support/same_bits.h"

#include <gtest/gtest.h>
#include <Eigen/SparseCholesky>

#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {
namespace rod {
namespace {

using RowBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

using testing::sameBits;

using hindsight::testing::randomSolidHalf;

SupernodalOptions withGroups(int groups) {
  SupernodalOptions options;
  options.groups = groups;
  options.smallest = 0;
  return options;
}

// max |x - x_simplicial| / max |x_simplicial|, the simplicial factor's solution in the same ordering.
double differenceFromSimplicial(const SparseMatrix& k, const SubtreeParallelLdlt& simplicial, const Matrix& b,
                                const Matrix& x) {
  const Matrix expected = simplicial.solve(b);
  return (x - expected).cwiseAbs().maxCoeff() / expected.cwiseAbs().maxCoeff();
}

// The same measure between Eigen's AMD-ordered solution and its METIS-ordered one: what K's conditioning
// allows two correct factorisations to differ by.
double amdAgainstMetis(const SparseMatrix& k, const SubtreeParallelLdlt& simplicial, const Matrix& b) {
  return differenceFromSimplicial(k, simplicial, b, Eigen::SimplicialLDLT<SparseMatrix>(k).solve(b));
}

// ||K x - b||_1 / (||K||_1 ||x||_1), the largest over the columns (K from its lower triangle).
double backwardError(const SparseMatrix& k, const Matrix& b, const Matrix& x) {
  const SparseMatrix full = k.selfadjointView<Eigen::Lower>();
  double normK = 0.0;
  for (int j = 0; j < full.outerSize(); ++j) normK = std::max(normK, full.col(j).cwiseAbs().sum());
  return (full * x - b).cwiseAbs().colwise().sum().maxCoeff() /
         (normK * x.cwiseAbs().colwise().sum().maxCoeff());
}

// The factor is the LDL^T of Eigen's SimplicialLDLT in the same (METIS) ordering up to round-off: the same
// permutation, the same pivots D and the same solutions to what K's conditioning allows, and a backward
// error ||K x - b|| / (||K|| ||x||) of round-off. The solid's K is ill-conditioned (pinned at A, rolling at
// B: lambda_max / lambda_1 ~ 1e9), so two correct factorisations' solutions differ by far more than eps:
// the scale is Eigen's own AMD-ordered solution against its METIS-ordered one. Measured on this
// 30 x 6 x 4 half (uniform design x = 0.5; random design of contrast 1e5): D 1.0e-9 and 5.2e-10 relative,
// solutions 1.0e-9 and 5.3e-10 where AMD against METIS gives 1.2e-9 and 1.9e-10, backward errors 3e-18
// and 4e-18. A wrong update (a descendant missed, a row misplaced, D applied twice) moves D and the
// solution by O(1) and the backward error far above 1e-15.
TEST(SupernodalLdlt, IsEigensLdltInMetissOrderingToRoundOff) {
  RodConfig config;
  config.elementsAlongLength = 30;
  config.elementsThroughHeight = 6;
  config.elementsThroughThickness = 4;
  config.midPlaneSymmetry = true;
  for (const bool uniform : {true, false}) {
    const SolidMember model(config, uniform ? Vector(Vector::Constant(config.designCount(), 0.5))
                                            : hindsight::testing::randomRodDesign(config, 3));
    const SparseMatrix& k = model.stiffness();
    SupernodalLdlt supernodal(withGroups(1));
    supernodal.compute(k);
    ASSERT_EQ(supernodal.info(), Eigen::Success);
    const SubtreeParallelLdlt simplicial(k, SubtreeSchedule{}, FillOrdering::Metis);
    ASSERT_EQ(simplicial.info(), Eigen::Success);
    EXPECT_TRUE(
        (supernodal.permutationP().indices().array() == simplicial.permutationP().indices().array()).all());
    const double pivots =
        ((supernodal.vectorD() - simplicial.vectorD()).array() / simplicial.vectorD().array())
            .abs()
            .maxCoeff();
    // Supernodes of several columns (relaxed amalgamation), so the dense kernels run.
    EXPECT_LT(supernodal.supernodeCount(), k.rows() / 6);
    EXPECT_GE(supernodal.storedNonZeros(), simplicial.matrixL().nestedExpression().nonZeros() + k.rows());
    const Matrix b = Matrix::Random(k.rows(), 3);
    const Matrix x = supernodal.solve(b);
    const double solution = differenceFromSimplicial(k, simplicial, b, x);
    const double scale = amdAgainstMetis(k, simplicial, b);
    const double backward = backwardError(k, b, x);
    std::cout << "[ supernodal ] " << (uniform ? "uniform" : "random")
              << " design: " << supernodal.supernodeCount() << " supernodes for " << k.rows()
              << " columns, stored " << supernodal.storedNonZeros() << " entries of L against "
              << simplicial.matrixL().nestedExpression().nonZeros() + k.rows() << "; D " << pivots
              << ", solution " << solution << " (AMD against METIS: " << scale << "), backward error "
              << backward << " (relative)\n";
    EXPECT_LE(pivots, 1e-8);
    EXPECT_LE(solution, 10.0 * scale + 1e-14);
    EXPECT_LE(backward, 1e-15);
  }
}

// The factor, both sweeps and the solves are the same bits for every partition of the supernodal tree (the
// groups factorised and back-substituted in parallel), on the analysed matrix and a refactorised one; a
// block of right-hand sides gives each column's one-column bits.
TEST(SupernodalLdlt, SameBitsForEveryPartitionAndBlockWidth) {
  const SolidMember model = randomSolidHalf(40, 6, 4, 5), other = randomSolidHalf(40, 6, 4, 6);
  SupernodalLdlt reference(withGroups(1));
  reference.compute(model.stiffness());
  ASSERT_EQ(reference.info(), Eigen::Success);
  EXPECT_EQ(reference.parallelShare(), 0.0);
  const Eigen::Index n = model.stiffness().rows();
  for (const SparseMatrix* matrix : {&model.stiffness(), &other.stiffness()}) {
    reference.factorize(*matrix);
    const Matrix rhs = Matrix::Random(n, 5);
    for (const int groups : {2, 3, 5}) {
      SupernodalLdlt split(withGroups(groups));
      split.analyzePattern(model.stiffness());
      // Split (on this small bar the top separators hold most of the work: 13-55 % is in the subtrees).
      EXPECT_GT(split.parallelShare(), 0.1) << groups << " groups";
      split.factorize(*matrix);
      ASSERT_EQ(split.info(), Eigen::Success);
      EXPECT_TRUE(sameBits(split.vectorD().data(), reference.vectorD().data(), n)) << groups << " groups";
      RowBlock forward = rhs, expectedForward = rhs, backward = rhs, expectedBackward = rhs;
      split.forwardSweep(forward.data(), 5);
      reference.forwardSweep(expectedForward.data(), 5);
      EXPECT_TRUE(sameBits(forward.data(), expectedForward.data(), forward.size())) << groups << " groups";
      split.backwardSweep(backward.data(), 5, true);
      reference.backwardSweep(expectedBackward.data(), 5, false);
      EXPECT_TRUE(sameBits(backward.data(), expectedBackward.data(), backward.size())) << groups << " groups";
      const Matrix x = split.solve(rhs), expected = reference.solve(rhs);
      EXPECT_TRUE(x == expected) << groups << " groups";
    }
    // A block's columns are the one-column solves, bit for bit (widths with and without unrolling).
    for (const int columns : {3, 11}) {
      const Matrix b = Matrix::Random(n, columns);
      const Matrix block = reference.solve(b);
      for (int c = 0; c < columns; ++c) {
        const Matrix single = reference.solve(b.col(c));
        EXPECT_TRUE(sameBits(single.data(), block.col(c).data(), n)) << "column " << c << " of " << columns;
      }
    }
  }
  EXPECT_THROW(reference.factorize(randomSolidHalf(41, 6, 4, 5).stiffness()), std::invalid_argument);
}

// The sweeps take the rows below a supernode in chunks of kSupernodalSweepChunk; on a bar with a wider
// cross-section (13 x 7 nodes, 273 DOFs a separator) some supernodes have more rows below them than
// that, and the solves stay the simplicial factor's in the same ordering to round-off (as in the first
// test: within the spread of AMD against METIS, backward error of round-off), with a block's columns the
// one-column solves bit for bit. A chunk's rows dropped or counted twice would move the solution by O(1).
TEST(SupernodalLdlt, SweepsTakeTheRowsBelowInChunks) {
  const SolidMember model = randomSolidHalf(16, 12, 6, 11);
  const SparseMatrix& k = model.stiffness();
  SupernodalLdlt supernodal(withGroups(2));
  supernodal.compute(k);
  ASSERT_EQ(supernodal.info(), Eigen::Success);
  EXPECT_GT(supernodal.tallestBelow(), kSupernodalSweepChunk);
  const SubtreeParallelLdlt simplicial(k, SubtreeSchedule{}, FillOrdering::Metis);
  const Matrix b = Matrix::Random(k.rows(), 11);
  const Matrix x = supernodal.solve(b);
  const double solution = differenceFromSimplicial(k, simplicial, b, x);
  const double scale = amdAgainstMetis(k, simplicial, b);
  const double backward = backwardError(k, b, x);
  std::cout << "[ supernodal ] " << supernodal.tallestBelow() << " rows below a supernode at most; solution "
            << solution << " (AMD against METIS: " << scale << "), backward error " << backward << "\n";
  EXPECT_LE(solution, 10.0 * scale + 1e-14);
  EXPECT_LE(backward, 1e-15);
  for (int c = 0; c < b.cols(); ++c) {
    const Matrix single = supernodal.solve(b.col(c));
    EXPECT_TRUE(sameBits(single.data(), x.col(c).data(), k.rows())) << "column " << c;
  }
}

// The default partition follows the threads parallelFor may use at analysis time; the stiffness
// factorisation of the solid is the supernodal one and gives the same bits on one and two threads.
TEST(SupernodalLdlt, SolidStiffnessFactorizationHasTheSameBitsOnOneAndTwoThreads) {
  const SolidMember model = randomSolidHalf(110, 10, 4, 7);
  ASSERT_EQ(stiffnessOrdering(model), FillOrdering::Metis);
  ASSERT_GT(model.freeDofCount(), SupernodalOptions{}.smallest);
  const Matrix rhs = Matrix::Random(model.freeDofCount(), 2);
  std::vector<Matrix> solutions;
  std::vector<Vector> pivots;
  for (const int threads : {1, 2}) {
    if (threads == 2 && (!threadsSupported() || availableThreads() < 2)) GTEST_SKIP() << "one thread only";
    const ThreadLimit limit(threads);
    const StiffnessFactorization factorization(model.stiffness(), stiffnessOrdering(model));
    EXPECT_THROW(factorization.solver(), std::logic_error);
    if (threads == 1)
      EXPECT_EQ(factorization.parallelShare(), 0.0);
    else
      EXPECT_GT(factorization.parallelShare(), 0.5);
    solutions.push_back(factorization.solve(rhs));
    pivots.push_back(factorization.vectorD());
  }
  EXPECT_TRUE(sameBits(pivots[0].data(), pivots[1].data(), pivots[0].size()));
  EXPECT_TRUE(solutions[0] == solutions[1]);
}

// The numeric factorisation and the sweeps allocate nothing (the blocks, maps and workspaces, with the
// blocked products' packing buffers, are made by analyzePattern); serial here, since the thread pool's
// tasks are allocated by TBB. On this bar Eigen's products would take 4 packing buffers from the heap.
TEST(SupernodalLdlt, FactorizeAndSweepsAllocateNothing) {
  if (!hindsight::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counting unavailable";
  const SolidMember model = randomSolidHalf(30, 6, 4, 9), other = randomSolidHalf(30, 6, 4, 10);
  SupernodalLdlt factor(withGroups(1));
  factor.compute(model.stiffness());
  RowBlock x = Matrix::Random(model.freeDofCount(), 4);
  hindsight::testing::AllocationCounter counter;
  factor.factorize(other.stiffness());
  factor.forwardSweep(x.data(), 4);
  factor.backwardSweep(x.data(), 4, false);
  EXPECT_EQ(counter.count(), 0);
  EXPECT_EQ(factor.info(), Eigen::Success);
}

// LDL^T without pivoting factorises an indefinite matrix too; the stiffness factorisation refuses one
// (a negative pivot), naming positive definiteness.
TEST(SupernodalLdlt, AnIndefiniteStiffnessIsRefused) {
  const SolidMember model = randomSolidHalf(12, 4, 2, 11);
  const SparseMatrix negative = -model.stiffness();
  try {
    const StiffnessFactorization factorization(negative, FillOrdering::Metis);
    FAIL() << "no exception";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("positive definite"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
