#include <hindsight/problems/classic/classic_problems.h>

#include <hindsight/engine/deterministic_math.h>

#include <cmath>

namespace hindsight {

// ---- Pendulum: r = m L^2 a + m g L sin(th) + c v. ----

void Pendulum::initialCoordinates(ConstVectorRef p, VectorRef y0, VectorRef v0) const {
  y0(0) = p(3);
  v0(0) = 0.0;
}

void Pendulum::addInitialCoordinatesVjp(ConstVectorRef, ConstVectorRef lambdaY, ConstVectorRef,
                                        VectorRef gradient) const {
  gradient(3) += lambdaY(0);
}

void Pendulum::massMatrix(double, ConstVectorRef, ConstVectorRef p, MatrixRef mass, ProblemWorkspace*) const {
  mass(0, 0) = p(0) * p(1) * p(1);
}

void Pendulum::force(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef f,
                     ProblemWorkspace*) const {
  f(0) = -p(0) * kGravity * p(1) * dmath::sin(y(0)) - p(2) * v(0);
}

void Pendulum::residualJacobians(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef, ConstVectorRef p,
                                 MatrixRef ry, MatrixRef rv, ProblemWorkspace*) const {
  ry(0, 0) = p(0) * kGravity * p(1) * dmath::cos(y(0));
  rv(0, 0) = p(2);
}

void Pendulum::addResidualParameterVjp(double, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                       ConstVectorRef p, ConstVectorRef mu, VectorRef out,
                                       ProblemWorkspace*) const {
  const double m = p(0), length = p(1);
  out(0) += (length * length * a(0) + kGravity * length * dmath::sin(y(0))) * mu(0);
  out(1) += (2.0 * m * length * a(0) + m * kGravity * dmath::sin(y(0))) * mu(0);
  out(2) += v(0) * mu(0);
}

double Pendulum::integrand(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef,
                           ProblemWorkspace*) const {
  return y(0) * y(0);
}

void Pendulum::addIntegrandStateGradient(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef,
                                         double scale, VectorRef gy, VectorRef, ProblemWorkspace*) const {
  gy(0) += scale * 2.0 * y(0);
}

void Pendulum::addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, ConstVectorRef, double,
                                             VectorRef, ProblemWorkspace*) const {}

double Pendulum::terminal(ConstVectorRef z, ConstVectorRef) const { return 0.5 * z(1) * z(1); }

void Pendulum::addTerminalGradient(ConstVectorRef z, ConstVectorRef, VectorRef gz, VectorRef) const {
  gz(1) += z(1);
}

// ---- Robertson ----

void Robertson::initialState(ConstVectorRef, VectorRef z0) const { z0 << 1.0, 0.0, 0.0; }

void Robertson::rhs(double, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const {
  const double r1 = p(0) * z(0), r2 = p(1) * z(1) * z(1), r3 = p(2) * z(1) * z(2);
  f(0) = -r1 + r3;
  f(1) = r1 - r2 - r3;
  f(2) = r2;
}

void Robertson::rhsJacobian(double, ConstVectorRef z, ConstVectorRef p, MatrixRef j,
                            ProblemWorkspace*) const {
  j << -p(0), p(2) * z(2), p(2) * z(1),                      //
      p(0), -2.0 * p(1) * z(1) - p(2) * z(2), -p(2) * z(1),  //
      0.0, 2.0 * p(1) * z(1), 0.0;
}

void Robertson::addRhsParameterVjp(double, ConstVectorRef z, ConstVectorRef, ConstVectorRef w, VectorRef out,
                                   ProblemWorkspace*) const {
  // dF/dk1 = (-y1, y1, 0), dF/dk2 = (0, -y2^2, y2^2), dF/dk3 = (y2 y3, -y2 y3, 0).
  out(0) += z(0) * (w(1) - w(0));
  out(1) += z(1) * z(1) * (w(2) - w(1));
  out(2) += z(1) * z(2) * (w(0) - w(1));
}

double Robertson::integrand(double, ConstVectorRef z, ConstVectorRef, ProblemWorkspace*) const {
  return z(2) / horizon_;
}

void Robertson::addIntegrandStateGradient(double, ConstVectorRef, ConstVectorRef, double scale, VectorRef out,
                                          ProblemWorkspace*) const {
  out(2) += scale / horizon_;
}

void Robertson::addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                              ProblemWorkspace*) const {}

}  // namespace hindsight
