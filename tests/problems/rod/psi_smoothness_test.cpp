// Hardening finding 10: psi1 must be a smooth function of the design down to the round-off of the
// integration. Before the eigenpair refinement of modal_reduction.h (refinementSteps) formed K-products
// accurately, the modal data carried round-off that changes erratically with the design (lambda_1 off by
// ~eps lambda_max, 2e-10 relative on the design below), and central differences with small steps measured
// that noise, not the derivative. These tests evaluate the full 200 x 12 model (~1 s each, 16 in all).
#include <hindsight/problems/app/piston_rod.h>

#include <gtest/gtest.h>

#include "support/random_design.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace hindsight {
namespace {

// Element (row 2, column 31) of the (ny, nx) design grid (problems/rod/design_io.h): column i counts
// all element columns, so design index d = (i - 1) ny + j.
int designIndexOf(const rod::RodConfig& config, int row, int column) {
  return (column - 1) * config.elementsThroughHeight + row;
}

double psi1(const PistonRod& rod, const Vector& x) { return rod.evaluate(x, {false, false, false}).psi1; }

// psi1(x + k 1e-12 e_d), k = -5..5, minus its least-squares line: the scatter left is noise (the
// curvature over 1e-11 is ~1e-22). Measured on this design (psi1 = 9.63): 7.7e-9 before the refinement,
// 6.5e-14 after, i.e. ~7e-15 relative, the round-off of the integration.
TEST(PsiSmoothness, Psi1ScatterUnderTinyDesignChangesIsRoundOff) {
  const PistonRod rod{Config{}};
  const Vector x = testing::randomRodDesign(rod.config().rod, 3);  // psi1 = 9.63
  const int d = designIndexOf(rod.config().rod, 2, 31);
  double sk = 0, skk = 0, sp = 0, skp = 0;
  std::vector<double> values;
  for (int k = -5; k <= 5; ++k) {
    Vector y = x;
    y(d) += k * 1e-12;
    values.push_back(psi1(rod, y));
  }
  const double center = values[5];
  for (int k = -5; k <= 5; ++k) {
    const double p = values[k + 5] - center;
    sk += k, skk += k * k, sp += p, skp += k * p;
  }
  const double count = 11.0;
  const double slope = (count * skp - sk * sp) / (count * skk - sk * sk);
  const double offset = (sp - slope * sk) / count;
  double scatter = 0.0;
  for (int k = -5; k <= 5; ++k)
    scatter = std::max(scatter, std::abs(values[k + 5] - center - offset - slope * k));
  std::printf("[ scatter ] psi1 = %.15g, max |psi1 - linear fit| over k 1e-12, k = -5..5: %.2e\n", center,
              scatter);
  EXPECT_LT(scatter, 1e-13 * std::abs(center));
}

// Central differences of psi1 at element (2, 31) against the adjoint gradient. Measured relative errors
// before the refinement: 3.1e-2 with h = 1e-5 (noise / 2h) and 2.2e-5 with h = 3e-4; after: 7.6e-8 and
// 5.0e-7 (now truncation, O(h^2)).
TEST(PsiSmoothness, SmallStepCentralDifferenceMatchesTheAdjointAtOneElement) {
  const PistonRod rod{Config{}};
  const Vector x = testing::randomRodDesign(rod.config().rod, 3);  // psi1 = 9.63
  const int d = designIndexOf(rod.config().rod, 2, 31);
  const double adjoint = rod.evaluate(x, {true, false, false}).dpsi1(d);
  for (double h : {1e-5, 3e-4}) {
    Vector plus = x, minus = x;
    plus(d) += h;
    minus(d) -= h;
    const double fd = (psi1(rod, plus) - psi1(rod, minus)) / (2 * h);
    const double error = std::abs(fd - adjoint) / std::abs(adjoint);
    std::printf(
        "[ fd ] element (2, 31): h = %.0e, adjoint %.12e, central difference %.12e, relative error %.2e\n", h,
        adjoint, fd, error);
    EXPECT_LT(error, 1e-5) << "h = " << h;
  }
}

}  // namespace
}  // namespace hindsight
