// The engine's finite-difference checker on Rosenbrock's function: the right gradient passes with both
// error measures small, one wrong term is caught and named.
#include <hindsight/engine/gradient_checker.h>

#include <gtest/gtest.h>

#include <cmath>

namespace hindsight {
namespace {

double rosenbrock(const Vector& x) {
  double sum = 0.0;
  for (Eigen::Index i = 0; i + 1 < x.size(); ++i)
    sum += 100.0 * std::pow(x(i + 1) - x(i) * x(i), 2) + std::pow(1.0 - x(i), 2);
  return sum;
}

Vector rosenbrockGradient(const Vector& x) {
  Vector g = Vector::Zero(x.size());
  for (Eigen::Index i = 0; i + 1 < x.size(); ++i) {
    g(i) += -400.0 * x(i) * (x(i + 1) - x(i) * x(i)) - 2.0 * (1.0 - x(i));
    g(i + 1) += 200.0 * (x(i + 1) - x(i) * x(i));
  }
  return g;
}

TEST(GradientCheckerRosenbrock, AcceptsTheRightGradient) {
  const Vector x = (Vector(4) << -1.2, 1.0, 0.3, 2.5).finished();
  const auto check = checkGradient(rosenbrock, x, rosenbrockGradient(x));
  EXPECT_TRUE(check.passed) << check.message;
  EXPECT_LT(check.normError, 1e-8);
  EXPECT_LT(check.maxError, 1e-7);
}

TEST(GradientCheckerRosenbrock, RejectsAGradientWithOneWrongTerm) {
  const Vector x = (Vector(4) << -1.2, 1.0, 0.3, 2.5).finished();
  Vector wrong = rosenbrockGradient(x);
  wrong(2) *= 1.0 + 1e-4;  // a small relative slip in one component
  const auto check = checkGradient(rosenbrock, x, wrong);
  EXPECT_FALSE(check.passed);
  EXPECT_GT(check.maxError, 1e-6);
  EXPECT_GT(check.normError, 1e-6);
  EXPECT_EQ(check.worstIndex, 2);
}

}  // namespace
}  // namespace hindsight
