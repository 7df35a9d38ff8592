#include <hindsight/problems/rod/invariants.h>

#include <gtest/gtest.h>

#include "support/random_design.h"

#include <cmath>
#include <random>

namespace hindsight {
namespace rod {
namespace {

RodConfig coarseConfig() {
  RodConfig config;
  config.elementsAlongLength = 20;
  config.elementsThroughHeight = 4;
  return config;
}

// Bilinear shape functions reproduce x and y exactly and 2x2 Gauss integrates the biquadratic products
// exactly, so X^T M X = int rho (x^2 + y^2) dV with no discretisation error; likewise m and m c.
TEST(Invariants, RigidBodyQuantitiesOfTheSolidRodAreExact) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, Vector::Constant(config.designCount(), 1.0));
  ModalReductionOptions options;
  options.modeCount = 4;
  const InertiaInvariants invariants = computeInvariants(model, computeModalBasis(model, options));
  const double L = config.length, H = config.height;
  const double mass = config.density * config.thickness * L * H;
  EXPECT_NEAR(invariants.mass, mass, 1e-14 * mass);
  EXPECT_NEAR(invariants.massTimesCenter(0), mass * L / 2, 1e-14 * mass * L);
  EXPECT_NEAR(invariants.massTimesCenter(1), 0.0, 1e-14 * mass * L);
  const double polar = config.density * config.thickness * (L * L * L * H / 3.0 + L * H * H * H / 12.0);
  EXPECT_NEAR(invariants.polarMoment, polar, 1e-13 * polar);
}

TEST(Invariants, ModalBlocksAtARandomDesign) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, testing::randomRodDesign(config, 5));
  ModalReductionOptions options;
  options.modeCount = 5;
  const ModalBasis basis = computeModalBasis(model, options);
  const InertiaInvariants invariants = computeInvariants(model, basis);
  const int n = 5;
  EXPECT_LT((invariants.mee - Matrix::Identity(n, n)).cwiseAbs().maxCoeff(), 1e-10);
  const Matrix lambda = basis.eigenvalues.asDiagonal();
  EXPECT_LT((invariants.kee - lambda).cwiseAbs().maxCoeff(), 1e-8 * basis.eigenvalues.maxCoeff());
  // C~ is skew because the consistent mass couples x with x and y with y identically (M S = S M).
  EXPECT_LT((invariants.cTilde + invariants.cTilde.transpose()).cwiseAbs().maxCoeff(),
            1e-12 * invariants.cTilde.cwiseAbs().maxCoeff());
  EXPECT_GT(invariants.cTilde.cwiseAbs().maxCoeff(), 1e-3);  // and not trivially zero
  EXPECT_EQ(invariants.b, basis.modesFull.row(model.jointBAxialDof()).transpose());

  // Momentum balance of a constrained eigenmode: K_full phi = lambda M_full phi + r with reactions r at
  // the supports only. Rigid motions are in the null space of K_full, so
  //   C1(x, i) = -r_Ax / lambda_i,  C1(y, i) = -(r_Ay + r_By) / lambda_i,  a0_i = -L r_By / lambda_i.
  const Matrix reactions =
      model.stiffnessFull() * basis.modesFull - model.massFull() * basis.modesFull * lambda;
  const int ax = 2 * model.jointANode(), ay = ax + 1, by = 2 * model.jointBNode() + 1;
  for (int i = 0; i < n; ++i) {
    const double scale = std::abs(reactions(ay, i)) + std::abs(reactions(by, i)) + std::abs(reactions(ax, i));
    const double lambdaI = basis.eigenvalues(i);
    EXPECT_NEAR(invariants.c1(0, i), -reactions(ax, i) / lambdaI, 1e-8 * scale / lambdaI) << i;
    EXPECT_NEAR(invariants.c1(1, i), -(reactions(ay, i) + reactions(by, i)) / lambdaI, 1e-8 * scale / lambdaI)
        << i;
    EXPECT_NEAR(invariants.a0(i), -config.length * reactions(by, i) / lambdaI, 1e-8 * scale / lambdaI) << i;
  }
}

// K_ee is the refinement's element-by-element form of the same modes (ModalBasis::stiffnessForm), kept
// rather than summed again: the same bits as summing it here, and the form of a basis without it (the
// refinement off, or modes changed and the form cleared) is summed afresh.
TEST(Invariants, KeptStiffnessFormIsTheFormOfTheModes) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, testing::randomRodDesign(config, 9));
  ModalReductionOptions options;
  options.modeCount = 5;
  ModalBasis basis = computeModalBasis(model, options);
  ASSERT_EQ(basis.stiffnessForm.rows(), 5);
  const Matrix summed = elementwiseStiffnessForm(model, basis.modesFull);
  EXPECT_EQ(computeInvariants(model, basis).kee, summed);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(basis.stiffnessForm(i, i), basis.eigenvalues(i)) << i;
  basis.modesFull.col(0) *= 2.0;
  basis.stiffnessForm.resize(0, 0);
  const Matrix scaled = computeInvariants(model, basis).kee;
  EXPECT_EQ(scaled(0, 0), 4.0 * summed(0, 0));
  EXPECT_EQ(scaled(1, 2), summed(1, 2));
  options.inertiaReliefModes = true;
  EXPECT_EQ(computeModalBasis(model, options).stiffnessForm.rows(), 0);
}

TEST(Invariants, PackUnpackRoundTripAndLayout) {
  EXPECT_EQ(InertiaInvariants::packedSize(10), 354);  // 4 + 5 n + 3 n^2
  const RodConfig config = coarseConfig();
  const FeModel model(config, Vector::Constant(config.designCount(), 0.5));
  ModalReductionOptions options;
  options.modeCount = 3;
  const InertiaInvariants invariants = computeInvariants(model, computeModalBasis(model, options));
  const Vector packed = invariants.pack();
  ASSERT_EQ(packed.size(), InertiaInvariants::packedSize(3));
  const InvariantLayout layout(3);
  EXPECT_EQ(packed(3), invariants.polarMoment);
  EXPECT_EQ(packed(layout.c1 + 1), invariants.c1(1, 0));  // column-major
  EXPECT_EQ(packed(layout.cTilde + 1), invariants.cTilde(1, 0));
  EXPECT_EQ(packed(layout.kee + 3 * 2 + 1), invariants.kee(1, 2));
  EXPECT_EQ(packed(layout.size - 1), invariants.b(2));
  EXPECT_EQ(InertiaInvariants::unpack(packed, 3).pack(), packed);
  EXPECT_THROW(InertiaInvariants::unpack(packed.head(packed.size() - 1), 3), std::invalid_argument);
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
