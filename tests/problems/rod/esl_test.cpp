#include <hindsight/problems/rod/esl.h>

#include <hindsight/engine/gradient_checker.h>
#include <hindsight/problems/rod/invariants.h>

#include <gtest/gtest.h>

#include "support/random_design.h"

#include <cmath>
#include <cstdio>
#include <random>

namespace hindsight {
namespace rod {
namespace {

RodConfig coarseConfig() {
  RodConfig config;
  config.elementsAlongLength = 20;
  config.elementsThroughHeight = 4;
  config.modeCount = 4;
  return config;
}

Vector randomDesign(const RodConfig& config, unsigned seed) { return testing::randomRodDesign(config, seed); }

// Seeded modal coordinates standing in for q(t_k), scaled so that psi2 is O(1) for this mesh.
Matrix modalSamples(int modes, int samples, unsigned seed) {
  std::mt19937 generator(seed);
  std::normal_distribution<double> normal;
  Matrix q(modes, samples);
  for (Eigen::Index k = 0; k < q.size(); ++k) q(k) = 1e-3 * normal(generator);
  return q;
}

// At the design the loads come from, u_k = Phi q_k, so psi2 = (t1/N) sum_k q_k^T K_ee q_k (docs/design.md
// §2).
TEST(Esl, AtTheLoadDesignDisplacementsAreTheModalShapes) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, randomDesign(config, 1));
  const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
  const Matrix q = modalSamples(config.modeCount, config.eslSamples, 2);
  const Matrix loads = equivalentStaticLoads(model, basis, q);
  const EslResult result = evaluateEsl(model, loads, config.endTime);
  const Matrix kee = computeInvariants(model, basis).kee;
  const double expected = config.endTime / config.eslSamples * (q.transpose() * kee * q).trace();
  EXPECT_NEAR(result.value, expected, 1e-9 * expected);
  EXPECT_LT((result.displacements - basis.modesFree * q).norm(), 1e-8 * (basis.modesFree * q).norm());
}

// The shortcut the piston rod takes (the loads from this design's own simulation) is the same psi2 and
// gradient as the solve with K, up to the solve's round-off (worse at the random design: K's condition
// grows like 1 / E(x_min)). A wrong weight, a missing factor or a transposed K_ee is off by O(1).
TEST(Esl, AtTheLoadDesignWithoutSolvingEqualsTheSolve) {
  const RodConfig config = coarseConfig();
  for (unsigned seed : {5u, 6u}) {
    const Vector design =
        seed == 5u ? Vector(Vector::Constant(config.designCount(), 0.5)) : randomDesign(config, seed);
    const FeModel model(config, design);
    const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
    const Matrix q = modalSamples(basis.columnCount(), config.eslSamples, seed);
    const EslResult solved = evaluateEsl(model, equivalentStaticLoads(model, basis, q), config.endTime);
    const EslResult direct =
        evaluateEslAtLoadDesign(model, basis, computeInvariants(model, basis).kee, q, config.endTime, true);
    const double tolerance = seed == 5u ? 1e-11 : 1e-8;
    EXPECT_NEAR(direct.value, solved.value, tolerance * solved.value) << "seed " << seed;
    EXPECT_LT((direct.gradient - solved.gradient).norm(), tolerance * solved.gradient.norm())
        << "seed " << seed;
    const EslResult valueOnly =
        evaluateEslAtLoadDesign(model, basis, computeInvariants(model, basis).kee, q, config.endTime, false);
    EXPECT_EQ(valueOnly.value, direct.value);
    EXPECT_EQ(valueOnly.gradient.size(), 0);
  }
  const FeModel model(config, Vector::Constant(config.designCount(), 0.5));
  const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
  const Matrix kee = computeInvariants(model, basis).kee;
  const int n = basis.columnCount();
  EXPECT_THROW(evaluateEslAtLoadDesign(model, basis, kee, Matrix::Zero(n + 1, 4), 3.0, false),
               std::invalid_argument);
  EXPECT_THROW(evaluateEslAtLoadDesign(model, basis, kee, Matrix::Zero(n, 0), 3.0, false),
               std::invalid_argument);
  EXPECT_THROW(evaluateEslAtLoadDesign(model, basis, kee, Matrix::Zero(n, 4), -1.0, false),
               std::invalid_argument);
}

// dpsi2/dx_e = -(t1/N) sum_k u_k^T K'_e u_k with the loads held fixed, for every design variable, at
// x0 = 0.5 and at a random design with values on both sides of 0.1.
TEST(Esl, GradientWithFixedLoadsMatchesFiniteDifferences) {
  const RodConfig config = coarseConfig();
  for (unsigned seed : {3u, 4u}) {
    const Vector design =
        seed == 3u ? Vector(Vector::Constant(config.designCount(), 0.5)) : randomDesign(config, seed);
    const FeModel model(config, design);
    const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
    // Loads from a different design, so that they are not in equilibrium with the modes of this one.
    const FeModel loadModel(config, randomDesign(config, seed + 10));
    const Matrix loads = equivalentStaticLoads(
        loadModel, computeModalBasis(loadModel, ModalReductionOptions::fromConfig(config)),
        modalSamples(config.modeCount, config.eslSamples, seed));
    const EslResult result = evaluateEsl(model, loads, config.endTime);
    GradientCheckOptions options;
    options.floor = 1.0;  // every component against ||fd||_inf
    const auto check = checkGradient(
        [&](const Vector& x) { return evaluateEsl(FeModel(config, x), loads, config.endTime).value; }, design,
        result.gradient, options);
    std::printf("[esl seed %u] ||fd - an|| / ||fd|| = %.2e, max |fd_i - an_i| / ||fd||_inf = %.2e\n", seed,
                check.normError, check.maxError);
    // psi2 is evaluated through a Cholesky factor of K whose condition number grows like 1 / E(x_min)
    // (E(0.02) = 8e-6 E0): at the random design psi2 carries ~4e-10 relative round-off, i.e. ~2e-6 of
    // the largest derivative after division by 2h; at x0 = 0.5 it is below 1e-6.
    EXPECT_LT(check.normError, seed == 3u ? 2e-6 : 2e-5);
    EXPECT_LT(check.maxError, seed == 3u ? 2e-6 : 2e-5);
    EXPECT_TRUE((result.gradient.array() <= 0.0).all());  // more stiffness, less compliance
  }
}

TEST(Esl, BadInputThrows) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, Vector::Constant(config.designCount(), 0.5));
  const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
  EXPECT_THROW(equivalentStaticLoads(model, basis, Matrix::Zero(3, 10)), std::invalid_argument);
  EXPECT_THROW(evaluateEsl(model, Matrix::Zero(model.freeDofCount() + 1, 10), 3.0), std::invalid_argument);
  EXPECT_THROW(evaluateEsl(model, Matrix::Zero(model.freeDofCount(), 0), 3.0), std::invalid_argument);
  EXPECT_THROW(evaluateEsl(model, Matrix::Zero(model.freeDofCount(), 10), 0.0), std::invalid_argument);
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
