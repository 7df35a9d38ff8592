// Svanberg's published test problems with known optima, shared by the MMA and GCMMA tests
// (tests/problems/topopt/mma_test.cpp, gcmma_test.cpp).
#pragma once

#include <hindsight/engine/types.h>

#include <functional>

namespace hindsight::testing {

/// A test problem: evaluates f0, its gradient, the constraints and their Jacobian at x; the gradients
/// may be null (values only, as GCMMA's trial evaluations ask).
struct OptimizationProblem {
  int n = 0;
  int m = 0;
  Vector xmin, xmax, x0;
  std::function<void(const Vector& x, double* f0, Vector* df0, Vector* f, Matrix* df)> evaluate;
};

// Svanberg (1987), sec. 6: cantilever beam of five hollow square segments, wall thickness fixed,
// x_j the outer side of segment j. Minimize the weight 0.0624 sum x_j subject to the tip deflection
// 61/x1^3 + 37/x2^3 + 19/x3^3 + 7/x4^3 + 1/x5^3 <= 1, with 1 <= x_j <= 10 and x_j = 5 at the start
// (on the constraint: f1(x0) = 0).
inline constexpr double kBeamWeight = 0.0624;
inline constexpr double kBeamCompliance[5] = {61.0, 37.0, 19.0, 7.0, 1.0};

inline OptimizationProblem CantileverBeam() {
  OptimizationProblem p;
  p.n = 5;
  p.m = 1;
  p.xmin = Vector::Constant(5, 1.0);
  p.xmax = Vector::Constant(5, 10.0);
  p.x0 = Vector::Constant(5, 5.0);
  p.evaluate = [](const Vector& x, double* f0, Vector* df0, Vector* f, Matrix* df) {
    *f0 = kBeamWeight * x.sum();
    if (df0 != nullptr) df0->setConstant(kBeamWeight);
    (*f)(0) = -1.0;
    for (int j = 0; j < 5; ++j) {
      (*f)(0) += kBeamCompliance[j] / (x(j) * x(j) * x(j));
      if (df != nullptr) (*df)(0, j) = -3.0 * kBeamCompliance[j] / (x(j) * x(j) * x(j) * x(j));
    }
  };
  return p;
}

// Svanberg (2007), the toy problem of the note: minimize x1^2 + x2^2 + x3^2 subject to
// (x1-5)^2 + (x2-2)^2 + (x3-1)^2 <= 9 and (x1-3)^2 + (x2-4)^2 + (x3-3)^2 <= 9, 0 <= x_j <= 5,
// starting from x = (4, 3, 2). Both constraints are active at the optimum (2.0175, 1.7800, 1.2375).
inline constexpr double kSphereCenters[2][3] = {{5.0, 2.0, 1.0}, {3.0, 4.0, 3.0}};

inline OptimizationProblem TwoSpheres() {
  OptimizationProblem p;
  p.n = 3;
  p.m = 2;
  p.xmin = Vector::Zero(3);
  p.xmax = Vector::Constant(3, 5.0);
  p.x0 = (Vector(3) << 4.0, 3.0, 2.0).finished();
  p.evaluate = [](const Vector& x, double* f0, Vector* df0, Vector* f, Matrix* df) {
    *f0 = x.squaredNorm();
    if (df0 != nullptr) *df0 = 2.0 * x;
    for (int i = 0; i < 2; ++i) {
      (*f)(i) = -9.0;
      for (int j = 0; j < 3; ++j) {
        (*f)(i) += (x(j) - kSphereCenters[i][j]) * (x(j) - kSphereCenters[i][j]);
        if (df != nullptr) (*df)(i, j) = 2.0 * (x(j) - kSphereCenters[i][j]);
      }
    }
  };
  return p;
}

}  // namespace hindsight::testing
