// The design derivative of the first eigenvalue (problems/rod/eigen_constraint.h) against central
// finite differences of freshly solved eigenproblems, and the cluster rule for a repeated eigenvalue.
#include <hindsight/problems/rod/eigen_constraint.h>

#include <hindsight/problems/rod/modal_reduction.h>

#include <gtest/gtest.h>

#include "support/random_design.h"

#include <cmath>

namespace hindsight::rod {
namespace {

RodConfig coarseConfig() {
  RodConfig config;
  config.elementsAlongLength = 20;
  config.elementsThroughHeight = 4;
  config.modeCount = 3;
  return config;
}

double lambda1(const RodConfig& config, const Vector& design) {
  const FeModel model(config, design);
  return computeModalBasis(model, ModalReductionOptions::fromConfig(config)).eigenvalues(0);
}

TEST(FirstEigenvalue, DerivativeMatchesCentralDifferencesOnARandomDesign) {
  const RodConfig config = coarseConfig();
  const Vector design = testing::randomRodDesign(config, 17);
  const FeModel model(config, design);
  const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
  const FirstEigenvalue first = firstEigenvalue(model, basis.eigenvalues, basis.modesFull);
  ASSERT_EQ(first.clusterSize, 1);
  EXPECT_EQ(first.value, basis.eigenvalues(0));
  // Every element derivative (design values are at least 2e-3 from the density law's kink).
  const double h = 1e-6;
  double worst = 0.0;
  const double scale = first.gradient.cwiseAbs().maxCoeff();
  for (int d = 0; d < config.designCount(); ++d) {
    Vector plus = design, minus = design;
    plus(d) += h;
    minus(d) -= h;
    const double fd = (lambda1(config, plus) - lambda1(config, minus)) / (2.0 * h);
    worst = std::max(worst, std::abs(fd - first.gradient(d)) / scale);
  }
  // A dropped term (the mass part, or a factor lambda) changes entries by O(scale).
  EXPECT_LT(worst, 1e-5);
}

TEST(FirstEigenvalue, ARepeatedEigenvalueIsGuardedThroughTheClusterMean) {
  const RodConfig config = coarseConfig();
  const Vector design = testing::randomRodDesign(config, 5);
  const FeModel model(config, design);
  const ModalBasis basis = computeModalBasis(model, ModalReductionOptions::fromConfig(config));
  // Pretend lambda_2 equals lambda_1 within the tolerance: the value and gradient are the means.
  const double tolerance = (basis.eigenvalues(1) - basis.eigenvalues(0)) / basis.eigenvalues(0) * 1.01;
  const FirstEigenvalue first = firstEigenvalue(model, basis.eigenvalues, basis.modesFull, tolerance);
  EXPECT_EQ(first.clusterSize, 2);
  EXPECT_DOUBLE_EQ(first.value, 0.5 * (basis.eigenvalues(0) + basis.eigenvalues(1)));
  const Vector expected =
      0.5 * (eigenvalueDesignGradient(model, basis.eigenvalues(0), basis.modesFull.col(0)) +
             eigenvalueDesignGradient(model, basis.eigenvalues(1), basis.modesFull.col(1)));
  EXPECT_LT((first.gradient - expected).cwiseAbs().maxCoeff(), 1e-12 * expected.cwiseAbs().maxCoeff());
  // The trace is basis independent: rotating the two modes within their span changes nothing.
  const double c = std::cos(0.7), s = std::sin(0.7);
  Matrix rotated = basis.modesFull;
  rotated.col(0) = c * basis.modesFull.col(0) + s * basis.modesFull.col(1);
  rotated.col(1) = -s * basis.modesFull.col(0) + c * basis.modesFull.col(1);
  Vector equal = basis.eigenvalues;
  equal(1) = equal(0);  // an exactly repeated eigenvalue, as the rotation assumes
  const FirstEigenvalue a = firstEigenvalue(model, equal, basis.modesFull, 0.0);
  const FirstEigenvalue b = firstEigenvalue(model, equal, rotated, 0.0);
  EXPECT_EQ(a.clusterSize, 2);
  EXPECT_LT((a.gradient - b.gradient).cwiseAbs().maxCoeff(), 1e-9 * a.gradient.cwiseAbs().maxCoeff());
}

TEST(FirstEigenvalue, BadInputThrows) {
  const RodConfig config = coarseConfig();
  const FeModel model(config, Vector::Constant(config.designCount(), 0.5));
  EXPECT_THROW(eigenvalueDesignGradient(model, 1.0, Vector::Zero(3)), std::invalid_argument);
  EXPECT_THROW(firstEigenvalue(model, Vector(), Matrix()), std::invalid_argument);
  EXPECT_THROW(firstEigenvalue(model, Vector::Ones(1), Matrix::Zero(model.dofCount(), 1), -1.0),
               std::invalid_argument);
}

}  // namespace
}  // namespace hindsight::rod
