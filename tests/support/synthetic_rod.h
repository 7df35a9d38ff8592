// A small synthetic flexible body for testing the slider-crank equations independently of the FE
// model: nodes on a rectangle, a node-wise isotropic SPD mass matrix M = m (x) I2 (as a consistent
// plane mass matrix is), reference coordinates X, random shape functions Phi that vanish at the pin
// A (both directions) and in y at the roller B, and a random SPD modal stiffness. The invariants are
// computed straight from the docs/design.md §3 table, so the test does not share code with the model.
#pragma once

#include "support/slider_crank.h"

#include <random>

namespace hindsight::testing {

struct SyntheticRod {
  int nodes = 0;
  int nodeA = 0, nodeB = 0;
  Matrix mass;  // 2N x 2N
  Vector X;     // 2N
  Matrix phi;   // 2N x n
  Matrix kee;   // n x n
  Vector ex, ey;

  /// Node-wise S = [[0,-1],[1,0]] applied to a 2N vector or to each column of a 2N x k matrix.
  static Matrix rotateNodewise(const Matrix& v) {
    Matrix out(v.rows(), v.cols());
    for (Eigen::Index k = 0; k < v.rows() / 2; ++k) {
      out.row(2 * k) = -v.row(2 * k + 1);
      out.row(2 * k + 1) = v.row(2 * k);
    }
    return out;
  }

  SyntheticRod(int modes, double length, unsigned seed, double shapeScale = 0.05) {
    const int nx = 6, ny = 3;  // nodes along and across; the middle row holds A and B
    nodes = nx * ny;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    X.resize(2 * nodes);
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        const int k = j * nx + i;
        X(2 * k) = length * i / (nx - 1);
        X(2 * k + 1) = 0.06 * (j - (ny - 1) / 2.0) / (ny - 1);
      }
    }
    nodeA = (ny / 2) * nx;
    nodeB = (ny / 2) * nx + nx - 1;
    Matrix m(nodes, nodes);
    for (int i = 0; i < nodes; ++i)
      for (int j = 0; j < nodes; ++j) m(i, j) = 0.02 * uniform(rng);
    m = (m * m.transpose()).eval();
    m.diagonal().array() += 0.5;
    mass = Matrix::Zero(2 * nodes, 2 * nodes);
    for (int i = 0; i < nodes; ++i)
      for (int j = 0; j < nodes; ++j) mass(2 * i, 2 * j) = mass(2 * i + 1, 2 * j + 1) = m(i, j);
    phi.resize(2 * nodes, modes);
    for (int r = 0; r < phi.rows(); ++r)
      for (int c = 0; c < modes; ++c) phi(r, c) = shapeScale * uniform(rng);
    phi.row(2 * nodeA).setZero();
    phi.row(2 * nodeA + 1).setZero();
    phi.row(2 * nodeB + 1).setZero();
    Matrix k(modes, modes);
    for (int i = 0; i < modes; ++i)
      for (int j = 0; j < modes; ++j) k(i, j) = uniform(rng);
    kee = k * k.transpose() * 1e3;
    kee.diagonal().array() += 1e4;
    ex = Vector::Zero(2 * nodes);
    ey = Vector::Zero(2 * nodes);
    for (int i = 0; i < nodes; ++i) {
      ex(2 * i) = 1.0;
      ey(2 * i + 1) = 1.0;
    }
  }

  /// The invariants of docs/design.md §3, packed in rod::SliderCrankLayout order.
  Vector invariants() const {
    const int n = static_cast<int>(phi.cols());
    rod::SliderCrankLayout layout{n};
    Vector p = Vector::Zero(layout.size());
    const Matrix E = (Matrix(2 * nodes, 2) << ex, ey).finished();
    p(layout.mass()) = ex.dot(mass * ex);
    p.segment(layout.massMoment(), 2) = E.transpose() * mass * X;
    p(layout.polarMoment()) = X.dot(mass * X);
    const Matrix c1 = E.transpose() * mass * phi;
    p.segment(layout.c1(), 2 * n) = Eigen::Map<const Vector>(c1.data(), 2 * n);
    p.segment(layout.c2(), n) = phi.transpose() * mass * X;
    p.segment(layout.a0(), n) = (rotateNodewise(X).transpose() * mass * phi).transpose();
    const Matrix ct = phi.transpose() * mass * (-rotateNodewise(phi));  // S^T = -S
    p.segment(layout.cTilde(), n * n) = Eigen::Map<const Vector>(ct.data(), n * n);
    const Matrix mee = phi.transpose() * mass * phi;
    p.segment(layout.mee(), n * n) = Eigen::Map<const Vector>(mee.data(), n * n);
    p.segment(layout.kee(), n * n) = Eigen::Map<const Vector>(kee.data(), n * n);
    p.segment(layout.b(), n) = phi.row(2 * nodeB).transpose();
    return p;
  }

  /// Kinetic energy (1/2) W^T M W from nodal velocities in the body frame,
  /// W = E R^T r_A' + beta' S w + Phi q', w = X + Phi q, beta from the closure (time derivative
  /// by the chain rule on the closure, independent of the model's formulas).
  double kineticEnergy(const rod::CrankMotion& crank, double length, double t, const Vector& q,
                       const Vector& qd) const {
    double phiAngle, phiDot, phiDdot;
    crank.at(t, phiAngle, phiDot, phiDdot);
    const double c = phi.row(2 * nodeB).dot(q);
    const double cd = phi.row(2 * nodeB).dot(qd);
    const double d = length + c;
    const double s = -crank.radius * std::sin(phiAngle) / d;
    const double beta = std::asin(s);
    // d/dt of sin(beta) (L + c) = -r sin(phi): cos(beta) beta' d + sin(beta) c' = -r cos(phi) phi'.
    const double betaDot =
        (-crank.radius * std::cos(phiAngle) * phiDot - std::sin(beta) * cd) / (std::cos(beta) * d);
    const Eigen::Vector2d rAdot(-crank.radius * phiDot * std::sin(phiAngle),
                                crank.radius * phiDot * std::cos(phiAngle));
    const Eigen::Vector2d local(std::cos(beta) * rAdot(0) + std::sin(beta) * rAdot(1),
                                -std::sin(beta) * rAdot(0) + std::cos(beta) * rAdot(1));
    const Vector w = X + phi * q;
    const Vector W = ex * local(0) + ey * local(1) + betaDot * rotateNodewise(w) + phi * qd;
    return 0.5 * W.dot(mass * W);
  }
};

}  // namespace hindsight::testing
