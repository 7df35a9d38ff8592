#include "problems/gradient_check.h"

#include <gtest/gtest.h>

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

TEST(GradientCheck, AcceptsTheRightGradient) {
  const Vector x = (Vector(4) << -1.2, 1.0, 0.3, 2.5).finished();
  const auto check = testing::checkGradient(rosenbrock, x, rosenbrockGradient(x));
  EXPECT_LT(check.normError, 1e-8);
  EXPECT_LT(check.componentError, 1e-7);
}

TEST(GradientCheck, RejectsAGradientWithOneWrongTerm) {
  const Vector x = (Vector(4) << -1.2, 1.0, 0.3, 2.5).finished();
  Vector wrong = rosenbrockGradient(x);
  wrong(2) *= 1.0 + 1e-4;  // a small relative slip in one component
  const auto check = testing::checkGradient(rosenbrock, x, wrong);
  EXPECT_GT(check.componentError, 1e-6);
  EXPECT_EQ(check.worstComponent, 2);
}

}  // namespace
}  // namespace hindsight
