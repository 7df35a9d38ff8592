// Tests of the 3-D density filter: hand-computed weights on flat boxes, the plate filter reproduced on one
// layer, constants kept, rows summing to one, mid-plane symmetry against the full body, the transpose
// against the adjoint identity and finite differences, no allocation, and argument checking.
#include <hindsight/problems/topopt/density_filter.h>
#include <hindsight/problems/topopt/density_filter_3d.h>

#include "support/allocation_counting.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

namespace hindsight {
namespace {

Vector randomVector(int size, unsigned seed) {
  std::mt19937 generator(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Vector v(size);
  for (int i = 0; i < size; ++i) v(i) = uniform(generator);
  return v;
}

DensityFilter3d::Grid grid(int nx, int ny, int nz, double wx, double wy, double wz, bool symmetric = false) {
  DensityFilter3d::Grid g;
  g.elementsAlongLength = nx;
  g.elementsThroughHeight = ny;
  g.elementsThroughThickness = nz;
  g.elementWidthX = wx;
  g.elementWidthY = wy;
  g.elementWidthZ = wz;
  g.midPlaneSymmetry = symmetric;
  return g;
}

// The solid rod's layout: first and last element columns solid.
std::vector<bool> solidEndColumns(int nx, int ny, int nz) {
  std::vector<bool> mask(static_cast<std::size_t>(nx * ny * nz), true);
  for (int j = 0; j < ny; ++j)
    for (int k = 0; k < nz; ++k) {
      mask[static_cast<std::size_t>((0 * ny + j) * nz + k)] = false;
      mask[static_cast<std::size_t>(((nx - 1) * ny + j) * nz + k)] = false;
    }
  return mask;
}

TEST(DensityFilter3d, MeasuresTheRadiusInLengthsAlongXOnFlatBoxes) {
  // A column of three boxes through the thickness, each half as thick as long: centres 0.5 and 1.0
  // element lengths apart, weights 1.2 - 0.5 = 0.7 and 1.2 - 1.0 = 0.2.
  const DensityFilter3d filter(grid(1, 1, 3, 0.01, 0.01, 0.005), 1.2);
  const Vector x = (Vector(3) << 1.0, 2.0, 4.0).finished();
  Vector filtered(3);
  filter.apply(x, filtered);
  EXPECT_DOUBLE_EQ(filtered(0), (1.2 * 1.0 + 0.7 * 2.0 + 0.2 * 4.0) / 2.1);
  EXPECT_DOUBLE_EQ(filtered(1), (0.7 * 1.0 + 1.2 * 2.0 + 0.7 * 4.0) / 2.6);
  // With the symmetry plane below layer 0, layer 0 also sees its own mirror at 0.5 and layer 1's at 1.0.
  const DensityFilter3d half(grid(1, 1, 3, 0.01, 0.01, 0.005, true), 1.2);
  half.apply(x, filtered);
  EXPECT_DOUBLE_EQ(filtered(0), (1.2 * 1.0 + 0.7 * 2.0 + 0.2 * 4.0 + 0.7 * 1.0 + 0.2 * 2.0) / 3.0);
}

TEST(DensityFilter3d, OneLayerOfCubesIsThePlateFilter) {
  const int nx = 9, ny = 4;
  for (double radius : {0.5, 1.5, 2.5}) {
    std::vector<bool> plateMask(nx * ny, true), solidMask = solidEndColumns(nx, ny, 1);
    for (int row = 0; row < ny; ++row) plateMask[row * nx] = plateMask[row * nx + nx - 1] = false;
    const DensityFilter plate(nx, ny, radius, plateMask);
    const DensityFilter3d solid(grid(nx, ny, 1, 0.005, 0.005, 0.005), radius, solidMask);
    EXPECT_EQ(plate.isIdentity(), solid.isIdentity()) << radius;
    const Vector x = randomVector(nx * ny, 7);
    Vector xSolid(nx * ny), plateResult(nx * ny), solidResult(nx * ny);
    // Plate: e = row nx + column; solid: e = column ny + row.
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < ny; ++j) xSolid(i * ny + j) = x(j * nx + i);
    plate.apply(x, plateResult);
    solid.apply(xSolid, solidResult);
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < ny; ++j)
        EXPECT_NEAR(solidResult(i * ny + j), plateResult(j * nx + i), 1e-15) << radius;
  }
}

TEST(DensityFilter3d, KeepsConstantsAndRowsSumToOne) {
  for (bool symmetric : {false, true}) {
    const DensityFilter3d filter(grid(8, 4, 3, 0.01, 0.005, 0.002, symmetric), 2.3, solidEndColumns(8, 4, 3));
    ASSERT_FALSE(filter.isIdentity());
    const Vector ones = Vector::Ones(filter.elementCount());
    Vector filtered(filter.elementCount());
    filter.apply(0.37 * ones, filtered);
    EXPECT_LT((filtered - 0.37 * ones).cwiseAbs().maxCoeff(), 1e-15);
    const Vector rowSums = filter.matrix() * ones;
    EXPECT_LT((rowSums - ones).cwiseAbs().maxCoeff(), 1e-14);
    EXPECT_GE(filter.matrix().coeffs().minCoeff(), 0.0);
  }
}

// The half with symmetry equals the full body filtered with the mirrored field: full layer nz + k is half
// layer k, full layer nz - 1 - k its mirror.
TEST(DensityFilter3d, SymmetricHalfEqualsTheMirroredFullBody) {
  const int nx = 7, ny = 4, nz = 3;
  const DensityFilter3d half(grid(nx, ny, nz, 0.01, 0.005, 0.003, true), 2.1, solidEndColumns(nx, ny, nz));
  const DensityFilter3d full(grid(nx, ny, 2 * nz, 0.01, 0.005, 0.003), 2.1, solidEndColumns(nx, ny, 2 * nz));
  const Vector x = randomVector(nx * ny * nz, 11);
  Vector xFull(nx * ny * 2 * nz);
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j)
      for (int k = 0; k < nz; ++k) {
        const double value = x((i * ny + j) * nz + k);
        xFull((i * ny + j) * 2 * nz + nz + k) = value;
        xFull((i * ny + j) * 2 * nz + nz - 1 - k) = value;
      }
  Vector halfResult(x.size()), fullResult(xFull.size());
  half.apply(x, halfResult);
  full.apply(xFull, fullResult);
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j)
      for (int k = 0; k < nz; ++k) {
        EXPECT_NEAR(halfResult((i * ny + j) * nz + k), fullResult((i * ny + j) * 2 * nz + nz + k), 1e-15);
        EXPECT_NEAR(halfResult((i * ny + j) * nz + k), fullResult((i * ny + j) * 2 * nz + nz - 1 - k), 1e-15);
      }
  EXPECT_GT((halfResult - x).norm(), 0.1);  // the filter did something
}

TEST(DensityFilter3d, TransposeIsTheAdjointAndMatchesFiniteDifferences) {
  const DensityFilter3d filter(grid(6, 4, 2, 0.01, 0.005, 0.0025, true), 1.8, solidEndColumns(6, 4, 2));
  const int n = filter.elementCount();
  const Vector x = randomVector(n, 3), y = randomVector(n, 5);
  Vector fx(n), fty(n);
  filter.apply(x, fx);
  filter.applyTranspose(y, fty);
  EXPECT_NEAR(fx.dot(y), x.dot(fty), 1e-14 * std::abs(fx.dot(y)));
  // phi(x) = sum (F x)_e^3: dphi/dx = F^T (3 (F x)^2), against central differences.
  auto phi = [&filter, n](const Vector& v) {
    Vector f(n);
    filter.apply(v, f);
    return f.array().cube().sum();
  };
  Vector gradient(n);
  filter.applyTranspose(3.0 * fx.array().square().matrix(), gradient);
  const double h = std::cbrt(std::numeric_limits<double>::epsilon());
  for (int e : {0, 5, 17, n - 1}) {
    Vector up = x, down = x;
    up(e) += h;
    down(e) -= h;
    EXPECT_NEAR((phi(up) - phi(down)) / (2.0 * h), gradient(e), 1e-8) << e;
  }
}

TEST(DensityFilter3d, ApplyAllocatesNothing) {
  if (!testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counting unavailable";
  const DensityFilter3d filter(grid(6, 4, 2, 0.01, 0.005, 0.0025), 2.0);
  const Vector x = randomVector(filter.elementCount(), 1);
  Vector out(filter.elementCount());
  testing::AllocationCounter counter;
  filter.apply(x, out);
  filter.applyTranspose(x, out);
  EXPECT_EQ(counter.count(), 0);
}

TEST(DensityFilter3d, RejectsBadArguments) {
  EXPECT_THROW(DensityFilter3d(grid(0, 1, 1, 1, 1, 1), 1.5), std::invalid_argument);
  EXPECT_THROW(DensityFilter3d(grid(1, 1, 0, 1, 1, 1), 1.5), std::invalid_argument);
  EXPECT_THROW(DensityFilter3d(grid(1, 1, 1, 1, -1, 1), 1.5), std::invalid_argument);
  EXPECT_THROW(DensityFilter3d(grid(1, 1, 1, 1, 1, 1), -0.5), std::invalid_argument);
  EXPECT_THROW(DensityFilter3d(grid(2, 1, 1, 1, 1, 1), 1.5, std::vector<bool>(3, true)),
               std::invalid_argument);
  const DensityFilter3d filter(grid(2, 2, 2, 1, 1, 1), 1.5);
  Vector wrong(7), right(8);
  EXPECT_THROW(filter.apply(wrong, right), std::invalid_argument);
  EXPECT_THROW(filter.applyTranspose(right, wrong), std::invalid_argument);
}

}  // namespace
}  // namespace hindsight
