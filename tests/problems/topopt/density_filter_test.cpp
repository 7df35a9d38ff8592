// Tests of the density filter: hand-computed weights, adjointness of the transpose, preservation of
// constants, the design mask, the identity for small radii, a finite-difference check of a chained
// objective, and argument checking.
#include <hindsight/problems/topopt/density_filter.h>

#include "support/allocation_counting.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {
namespace {

// The rod's layout in miniature: first and last element columns solid (not design).
std::vector<bool> SolidEndColumns(int nx, int ny) {
  std::vector<bool> mask(nx * ny, true);
  for (int row = 0; row < ny; ++row) {
    mask[row * nx] = false;
    mask[row * nx + nx - 1] = false;
  }
  return mask;
}

Vector RandomVector(int size, unsigned seed) {
  std::mt19937 generator(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Vector v(size);
  for (int i = 0; i < size; ++i) v(i) = uniform(generator);
  return v;
}

TEST(DensityFilter, MatchesHandComputedWeights) {
  // A 3 x 1 strip with R = 1.5: the neighbour at distance 1 has weight 0.5, the element itself 1.5.
  DensityFilter filter(3, 1, 1.5);
  const Vector x = (Vector(3) << 1.0, 2.0, 4.0).finished();
  Vector filtered(3);
  filter.apply(x, filtered);
  EXPECT_DOUBLE_EQ(filtered(0), (1.5 * 1.0 + 0.5 * 2.0) / 2.0);
  EXPECT_DOUBLE_EQ(filtered(1), (0.5 * 1.0 + 1.5 * 2.0 + 0.5 * 4.0) / 2.5);
  EXPECT_DOUBLE_EQ(filtered(2), (0.5 * 2.0 + 1.5 * 4.0) / 2.0);

  // A 2 x 2 block with R = 1.5: the diagonal neighbour at sqrt(2) has weight 1.5 - sqrt(2).
  DensityFilter square(2, 2, 1.5);
  const Vector y = (Vector(4) << 1.0, 0.0, 0.0, 0.0).finished();
  Vector ySmooth(4);
  square.apply(y, ySmooth);
  const double diagonal = 1.5 - std::sqrt(2.0);
  const double total = 1.5 + 0.5 + 0.5 + diagonal;
  EXPECT_DOUBLE_EQ(ySmooth(0), 1.5 / total);
  EXPECT_DOUBLE_EQ(ySmooth(1), 0.5 / total);  // element (1, 0): right of element 0
  EXPECT_DOUBLE_EQ(ySmooth(2), 0.5 / total);  // element (0, 1): above element 0
  EXPECT_DOUBLE_EQ(ySmooth(3), diagonal / total);
}

TEST(DensityFilter, TransposeIsTheAdjoint) {
  const int nx = 30, ny = 8;
  for (const double radius : {1.5, 2.0, 3.7}) {
    DensityFilter filter(nx, ny, radius, SolidEndColumns(nx, ny));
    ASSERT_FALSE(filter.isIdentity());
    const Vector x = RandomVector(nx * ny, 1), y = RandomVector(nx * ny, 2);
    Vector fx(nx * ny), fty(nx * ny);
    filter.apply(x, fx);
    filter.applyTranspose(y, fty);
    // <F x, y> = <x, F^T y>; both sides are sums of about nx*ny terms of size 1.
    EXPECT_NEAR(fx.dot(y), x.dot(fty), 1e-14 * std::abs(fx.dot(y))) << radius;
    // The filter is not symmetric (row normalisation, boundaries, mask), so this is not trivial.
    EXPECT_GT((fx - fty).norm(), 1e-3) << radius;
  }
}

TEST(DensityFilter, PreservesConstantsAndLeavesNonDesignElementsAlone) {
  const int nx = 12, ny = 5;
  const std::vector<bool> mask = SolidEndColumns(nx, ny);
  DensityFilter filter(nx, ny, 2.5, mask);
  Vector filtered(nx * ny);
  filter.apply(Vector::Constant(nx * ny, 0.37), filtered);
  EXPECT_LT((filtered.array() - 0.37).abs().maxCoeff(), 1e-15);

  // Non-design elements keep their value and do not influence design elements.
  Vector x = RandomVector(nx * ny, 3);
  Vector base(nx * ny);
  filter.apply(x, base);
  for (int row = 0; row < ny; ++row) x(row * nx) = 100.0;
  filter.apply(x, filtered);
  for (int e = 0; e < nx * ny; ++e) {
    if (mask[e]) {
      EXPECT_EQ(filtered(e), base(e)) << e;
    } else {
      EXPECT_EQ(filtered(e), x(e)) << e;
    }
  }
}

TEST(DensityFilter, SmallRadiusIsTheIdentity) {
  const Vector x = RandomVector(24, 4);
  for (const double radius : {0.0, 0.5, 0.999}) {
    DensityFilter filter(6, 4, radius);
    EXPECT_TRUE(filter.isIdentity());
    Vector filtered(24), transposed(24);
    filter.apply(x, filtered);
    filter.applyTranspose(x, transposed);
    EXPECT_EQ(filtered, x);
    EXPECT_EQ(transposed, x);
  }
  EXPECT_FALSE(DensityFilter(6, 4, 1.01).isIdentity());
}

// phi(x) = sum_e s_e xf_e^3 with xf = F x; dphi/dx = F^T (3 s xf^2).
double ChainedObjective(const DensityFilter& filter, const Vector& weights, const Vector& x,
                        Vector* gradient) {
  Vector filtered(x.size());
  filter.apply(x, filtered);
  if (gradient != nullptr) {
    const Vector outer = 3.0 * weights.cwiseProduct(filtered.cwiseAbs2());
    filter.applyTranspose(outer, *gradient);
  }
  return weights.dot(filtered.cwiseAbs2().cwiseProduct(filtered));
}

// Largest relative difference between `gradient` and central differences with step
// cbrt(eps) max(1, |x_j|) (docs/design.md P 5).
double FiniteDifferenceError(const DensityFilter& filter, const Vector& weights, const Vector& x,
                             const Vector& gradient) {
  double worst = 0.0;
  Vector probe = x;
  for (int j = 0; j < x.size(); ++j) {
    const double h = std::cbrt(std::numeric_limits<double>::epsilon()) * std::max(1.0, std::abs(x(j)));
    probe(j) = x(j) + h;
    const double up = ChainedObjective(filter, weights, probe, nullptr);
    probe(j) = x(j) - h;
    const double down = ChainedObjective(filter, weights, probe, nullptr);
    probe(j) = x(j);
    const double difference = (up - down) / (2.0 * h);
    worst = std::max(worst, std::abs(difference - gradient(j)) / std::max(1.0, std::abs(difference)));
  }
  return worst;
}

TEST(DensityFilter, ChainRuleMatchesFiniteDifferences) {
  const int nx = 14, ny = 6;
  DensityFilter filter(nx, ny, 2.2, SolidEndColumns(nx, ny));
  const Vector x = RandomVector(nx * ny, 5), weights = RandomVector(nx * ny, 6);
  Vector gradient(nx * ny);
  ChainedObjective(filter, weights, x, &gradient);
  const double error = FiniteDifferenceError(filter, weights, x, gradient);
  EXPECT_LT(error, 1e-8);

  // The check detects a wrong chain rule: F instead of F^T.
  Vector filtered(nx * ny), wrong(nx * ny);
  filter.apply(x, filtered);
  filter.apply(3.0 * weights.cwiseProduct(filtered.cwiseAbs2()), wrong);
  EXPECT_GT(FiniteDifferenceError(filter, weights, x, wrong), 1e-3);
}

TEST(DensityFilter, ApplyAllocatesNothing) {
  if (!testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counting unavailable";
  const int nx = 40, ny = 10;
  DensityFilter filter(nx, ny, 2.5, SolidEndColumns(nx, ny));
  const Vector x = RandomVector(nx * ny, 7);
  Vector filtered(nx * ny), back(nx * ny);
  testing::AllocationCounter counter;
  filter.apply(x, filtered);
  filter.applyTranspose(filtered, back);
  EXPECT_EQ(counter.count(), 0);
}

template <typename F>
void ExpectInvalidArgumentNaming(F&& call, const std::string& name) {
  try {
    call();
    ADD_FAILURE() << "no exception; expected one naming " << name;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
  }
}

TEST(DensityFilter, BadArgumentsThrowNamingTheArgument) {
  ExpectInvalidArgumentNaming([] { DensityFilter(0, 3, 1.5); }, "nx = 0");
  ExpectInvalidArgumentNaming([] { DensityFilter(3, -2, 1.5); }, "ny = -2");
  ExpectInvalidArgumentNaming([] { DensityFilter(3, 3, -1.0); }, "radius = -1");
  ExpectInvalidArgumentNaming([] { DensityFilter(3, 3, std::nan("")); }, "radius");
  ExpectInvalidArgumentNaming([] { DensityFilter(3, 3, 1.5, std::vector<bool>(8, true)); }, "design_mask");
  DensityFilter filter(3, 3, 1.5);
  Vector nine(9), eight(8);
  ExpectInvalidArgumentNaming([&] { filter.apply(eight, nine); }, "x has length 8");
  ExpectInvalidArgumentNaming([&] { filter.apply(nine, eight); }, "filtered");
  ExpectInvalidArgumentNaming([&] { filter.applyTranspose(eight, nine); }, "gradient_filtered");
  ExpectInvalidArgumentNaming([&] { filter.applyTranspose(nine, eight); }, "gradient has length 8");
}

}  // namespace
}  // namespace hindsight
