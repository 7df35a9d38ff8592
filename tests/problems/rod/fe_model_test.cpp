#include <hindsight/problems/rod/fe_model.h>

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include "support/random_design.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace hindsight {
namespace rod {
namespace {

RodConfig coarseConfig() {
  RodConfig config;
  config.elementsAlongLength = 20;
  config.elementsThroughHeight = 4;
  return config;
}

TEST(ElementMatrices, StiffnessHasExactlyThreeRigidModes) {
  const ElementMatrix stiffness = planeStressQuadUnitStiffness(0.005, 0.005, 0.3, 0.01);
  const Eigen::SelfAdjointEigenSolver<ElementMatrix> eigen(stiffness);
  const Vector values = eigen.eigenvalues();  // ascending
  const double scale = values.maxCoeff();
  for (int i = 0; i < 3; ++i) EXPECT_LT(std::abs(values(i)), 1e-12 * scale) << i;
  EXPECT_GT(values(3), 1e-3 * scale);
  // The three rigid motions (two translations and the infinitesimal rotation) are in the null space.
  ElementVector rotation;
  const double corners[4][2] = {{0, 0}, {0.005, 0}, {0.005, 0.005}, {0, 0.005}};
  for (int a = 0; a < 4; ++a) {
    rotation(2 * a) = -corners[a][1];
    rotation(2 * a + 1) = corners[a][0];
  }
  EXPECT_LT((stiffness * rotation).norm(), 1e-12 * scale * rotation.norm());
}

TEST(ElementMatrices, MassSumsToElementMassAndIsPositiveDefinite) {
  const double width = 0.005, height = 0.004, thickness = 0.01;
  const ElementMatrix mass = quadUnitConsistentMass(width, height, thickness);
  // Each direction carries the full mass once: e_x^T M e_x = rho V; the total entry sum is 2 rho V.
  ElementVector ex = ElementVector::Zero();
  for (int a = 0; a < 4; ++a) ex(2 * a) = 1.0;
  EXPECT_NEAR(ex.dot(mass * ex), width * height * thickness, 1e-22);
  EXPECT_NEAR(mass.sum(), 2.0 * width * height * thickness, 1e-22);
  const Eigen::SelfAdjointEigenSolver<ElementMatrix> eigen(mass);
  EXPECT_GT(eigen.eigenvalues().minCoeff(), 0.0);
}

// The density law has a kink at the threshold: finite differences must straddle it only from one side.
TEST(SimpLaw, DerivativesMatchFiniteDifferencesOnBothSidesOfTheThreshold) {
  const RodConfig config;
  const SimpLaw simp(config);
  // Step cbrt(eps) max(1, |x|) ~ 6e-6; the truncation error (h/x)^2 (q-1)(q-2)/6 is below 2e-6 for x >=
  // 0.011.
  const double h = std::cbrt(std::numeric_limits<double>::epsilon());
  for (double x : {0.011, 0.05, 0.0995, 0.1005, 0.3, 0.5, 0.97}) {
    const double fdStiffness = (simp.stiffness(x + h) - simp.stiffness(x - h)) / (2 * h);
    const double fdDensity = (simp.density(x + h) - simp.density(x - h)) / (2 * h);
    EXPECT_NEAR(simp.stiffnessDerivative(x), fdStiffness, 1e-5 * std::abs(fdStiffness)) << x;
    EXPECT_NEAR(simp.densityDerivative(x), fdDensity, 1e-5 * std::abs(fdDensity)) << x;
  }
  // Continuity at the threshold, and the documented one-sided (right) derivative there.
  const double t = config.massLawThreshold;
  EXPECT_NEAR(simp.density(std::nextafter(t, 0.0)), simp.density(t), 1e-12 * simp.density(t));
  EXPECT_DOUBLE_EQ(simp.densityDerivative(t), config.density);
  EXPECT_NEAR(simp.densityDerivative(std::nextafter(t, 0.0)), config.massLawExponent * config.density,
              1e-9 * config.density);  // left slope c q t^(q-1) rho0 = q rho0: the kink is a factor q
  EXPECT_DOUBLE_EQ(simp.stiffness(0.5), 0.125 * config.youngsModulus);
}

TEST(FeModel, MeshMapsAndJointDofs) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, Vector::Constant(config.designCount(), 0.5));
  EXPECT_EQ(model.nodeCount(), 21 * 5);
  EXPECT_EQ(model.dofCount(), 210);
  EXPECT_EQ(model.freeDofCount(), 207);
  EXPECT_EQ(model.designCount(), 18 * 4);
  const Vector& coordinates = model.referenceCoordinates();
  EXPECT_DOUBLE_EQ(coordinates(2 * model.jointANode()), 0.0);
  EXPECT_DOUBLE_EQ(coordinates(2 * model.jointANode() + 1), 0.0);
  EXPECT_DOUBLE_EQ(coordinates(2 * model.jointBNode()), config.length);
  EXPECT_NEAR(coordinates(2 * model.jointBNode() + 1), 0.0, 1e-15);
  // Constrained: u_x, u_y at A and u_y at B; u_x at B is free.
  EXPECT_EQ(model.fullToFree()[2 * model.jointANode()], -1);
  EXPECT_EQ(model.fullToFree()[2 * model.jointANode() + 1], -1);
  EXPECT_EQ(model.fullToFree()[2 * model.jointBNode() + 1], -1);
  EXPECT_EQ(model.freeToFull()[model.jointBAxialFreeDof()], model.jointBAxialDof());
  for (int d = 0; d < model.designCount(); ++d) EXPECT_EQ(model.elementToDesign(model.designToElement(d)), d);
  int solid = 0;
  for (int e = 0; e < model.elementCount(); ++e) solid += model.elementToDesign(e) < 0;
  EXPECT_EQ(solid, 2 * config.elementsThroughHeight);
  // Round trip free <-> full.
  const Vector free = Vector::LinSpaced(model.freeDofCount(), 1.0, 2.0);
  EXPECT_EQ(model.restrictToFree(model.extendToFull(free)), free);
}

TEST(FeModel, AssembledMatricesAreSymmetricWithRigidModesOnlyWhenUnconstrained) {
  const RodConfig config = coarseConfig();
  std::mt19937 generator(7);
  std::uniform_real_distribution<double> uniform(0.02, 1.0);
  Vector design(config.designCount());
  for (auto& x : design) x = uniform(generator);
  const FeModel model(config, design);
  const Matrix stiffnessFull = model.stiffnessFull();
  EXPECT_LT((stiffnessFull - stiffnessFull.transpose()).norm(), 1e-14 * stiffnessFull.norm());
  // Full K annihilates e_x, e_y and the infinitesimal rotation S X.
  const double scale = stiffnessFull.norm();
  EXPECT_LT((model.stiffnessFull() * model.unitTranslationX()).norm(), 1e-13 * scale);
  EXPECT_LT((model.stiffnessFull() * model.unitTranslationY()).norm(), 1e-13 * scale);
  EXPECT_LT((model.stiffnessFull() * rotateNodewise(model.referenceCoordinates())).norm(), 1e-12 * scale);
  // Constrained K is positive definite: its smallest eigenvalue is well above round-off.
  const Eigen::SelfAdjointEigenSolver<Matrix> eigen{Matrix(model.stiffness())};
  EXPECT_GT(eigen.eigenvalues().minCoeff(), 1e-10 * eigen.eigenvalues().maxCoeff());
  // Constrained = full with the three support DOFs removed.
  const Matrix restricted =
      model.restrictColumnsToFree(Matrix(model.restrictColumnsToFree(stiffnessFull).transpose()));
  EXPECT_EQ(restricted, Matrix(model.stiffness()));
}

// The assembly scatters into the mesh's pattern. Reference: Eigen's setFromTriplets over the element-ordered
// triplets, which sums an entry's contributions in element order; both must give the same pattern and
// the same bits, for the full and the constrained matrices, on two mesh heights.
SparseMatrix tripletAssembly(const FeModel& model, const ElementMatrix& unit, bool stiffness, bool free) {
  std::vector<Eigen::Triplet<double>> triplets;
  for (int e = 0; e < model.elementCount(); ++e) {
    const double x = model.elementDesignValue(e);
    const double scale = stiffness ? model.simp().stiffness(x) : model.simp().density(x);
    const std::array<int, 8> dofs = model.elementDofs(e);
    for (int a = 0; a < 8; ++a) {
      for (int b = 0; b < 8; ++b) {
        const int row = free ? model.fullToFree()[dofs[a]] : dofs[a];
        const int column = free ? model.fullToFree()[dofs[b]] : dofs[b];
        if (row >= 0 && column >= 0) triplets.emplace_back(row, column, scale * unit(a, b));
      }
    }
  }
  const int size = free ? model.freeDofCount() : model.dofCount();
  SparseMatrix matrix(size, size);
  matrix.setFromTriplets(triplets.begin(), triplets.end());
  return matrix;
}

void expectSameBits(const SparseMatrix& actual, const SparseMatrix& expected, const char* name) {
  ASSERT_TRUE(actual.isCompressed()) << name;
  ASSERT_EQ(actual.nonZeros(), expected.nonZeros()) << name;
  ASSERT_EQ(actual.outerSize(), expected.outerSize()) << name;
  for (Eigen::Index k = 0; k <= actual.outerSize(); ++k)
    ASSERT_EQ(actual.outerIndexPtr()[k], expected.outerIndexPtr()[k]) << name << " column " << k;
  for (Eigen::Index k = 0; k < actual.nonZeros(); ++k) {
    ASSERT_EQ(actual.innerIndexPtr()[k], expected.innerIndexPtr()[k]) << name << " entry " << k;
    ASSERT_EQ(std::memcmp(actual.valuePtr() + k, expected.valuePtr() + k, sizeof(double)), 0)
        << name << " entry " << k << ": " << actual.valuePtr()[k] << " vs " << expected.valuePtr()[k];
  }
}

TEST(FeModel, AssemblyHasTheBitsOfSetFromTripletsInElementOrder) {
  for (const int height : {2, 6}) {
    RodConfig config = coarseConfig();
    config.elementsThroughHeight = height;
    const FeModel model(config, testing::randomRodDesign(config, 11));
    expectSameBits(model.stiffnessFull(), tripletAssembly(model, model.unitStiffness(), true, false),
                   "K full");
    expectSameBits(model.massFull(), tripletAssembly(model, model.unitMass(), false, false), "M full");
    expectSameBits(model.stiffness(), tripletAssembly(model, model.unitStiffness(), true, true), "K");
    expectSameBits(model.mass(), tripletAssembly(model, model.unitMass(), false, true), "M");
  }
}

TEST(FeModel, TotalMassAndVolumeFraction) {
  const RodConfig config = coarseConfig();
  Vector design = Vector::Constant(config.designCount(), 0.5);
  design(3) = 0.05;  // below the threshold: rho = c x^q rho0
  const FeModel model(config, design);
  const double elementVolume = config.length * config.height * config.thickness / model.elementCount();
  const double expectedMass = elementVolume * config.density *
                              (2 * config.elementsThroughHeight + 0.5 * (config.designCount() - 1) +
                               config.massLawFactor * std::pow(0.05, 6));
  const Vector& ex = model.unitTranslationX();
  EXPECT_NEAR(ex.dot(model.massFull() * ex), expectedMass, 1e-13 * expectedMass);
  const double expectedFraction = (2 * 4 + 0.5 * (config.designCount() - 1) + 0.05) / model.elementCount();
  EXPECT_NEAR(model.volumeFraction(), expectedFraction, 1e-15);
  EXPECT_TRUE(model.volumeFractionGradient().isApproxToConstant(1.0 / model.elementCount()));
}

TEST(FeModel, NodewiseRotationIsSAndItsTranspose) {
  const Vector u = (Vector(4) << 1.0, 2.0, 3.0, 4.0).finished();
  EXPECT_EQ(rotateNodewise(u), (Vector(4) << -2.0, 1.0, -4.0, 3.0).finished());
  EXPECT_EQ(rotateNodewiseTransposed(rotateNodewise(u)), u);
}

TEST(FeModel, BadDesignThrowsNamingTheIndex) {
  const RodConfig config = coarseConfig();
  EXPECT_THROW(FeModel(config, Vector::Constant(config.designCount() - 1, 0.5)), std::invalid_argument);
  Vector design = Vector::Constant(config.designCount(), 0.5);
  design(17) = 0.005;
  try {
    FeModel model(config, design);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("design[17]"), std::string::npos) << error.what();
  }
  RodConfig odd = config;
  odd.elementsThroughHeight = 3;
  EXPECT_THROW(FeModel(odd, Vector::Constant(odd.designCount(), 0.5)), std::invalid_argument);
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
