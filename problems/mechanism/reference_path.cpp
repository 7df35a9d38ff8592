// The full-coordinate reference path and diagnostics (docs/design.md §10): R^T (M(z) z'' - Q) in all of
// z with the derivatives by dual numbers in every direction (the *ByProjection and *ByAutoDiff methods,
// which the tests hold the chord path to), z and z' of a state, and the energies and the drivers' power
// (the tests' energy balance). O(n^3) and more: nothing of an evaluation runs it.
#include <hindsight/problems/mechanism/detail/kinematics.h>
#include <hindsight/problems/mechanism/detail/member_forces.h>
#include <hindsight/problems/mechanism/detail/sensitivities.h>

#include <Eigen/LU>

#include <cmath>

namespace hindsight::mechanism::detail {

namespace {

template <typename T>
void loadInputs(const System& I, const View& P, Buffers<T>& B, ConstVectorRef y, ConstVectorRef v, int nd,
                bool seedState, bool seedB) {
  for (int i = 0; i < I.f; ++i) {
    B.y[i] = seedState ? Make<T>::variable(y(i), nd, i) : Make<T>::constant(y(i), nd);
    B.v[i] = seedState ? Make<T>::variable(v(i), nd, I.f + i) : Make<T>::constant(v(i), nd);
  }
  for (int i = 0; i < I.n; ++i)
    B.b[i] = seedB ? Make<T>::variable(P.b(i), nd, i) : Make<T>::constant(P.b(i), nd);
}

/// The reference path in full coordinates: positions from the chord system, kinematics of z.
void fullPass(const System& I, const System& C, const View& P, double t, ConstVectorRef y, ConstVectorRef v,
              Work& w) {
  chordInputs(I, P, y, v, nullptr, w);
  w.kinematicsValid = false;  // cd and the factorisations are overwritten below
  solvePositions(C, t, w.sigma, w);
  for (int i = 0; i < I.base + 3; ++i) w.zStar(i) = w.zChord(i);
  for (int i = 0; i < I.n; ++i) w.zStar(I.base + 3 + i) = y(I.nFree + i);
  loadInputs(I, P, w.d, y, v, 0, false, false);
  kinematics(I, t, w.d, w, w.zStar, 0);
}

template <typename T>
void stateJacobians(const System& I, const View& P, double t, ConstVectorRef y, ConstVectorRef v,
                    ConstVectorRef a, MatrixRef ry, MatrixRef rv, Buffers<T>& B, Work& w) {
  const int nd = 2 * I.f;
  loadInputs(I, P, B, y, v, nd, true, false);
  kinematics(I, t, B, w, w.zStar, nd);
  residualFromKinematics(I, P, B, a, nd);
  for (int i = 0; i < I.f; ++i) {
    const auto& d = B.r[i].derivatives();
    for (int j = 0; j < I.f; ++j) {
      ry(i, j) = d(j);
      rv(i, j) = d(I.f + j);
    }
  }
}

template <typename T>
void chordRowProduct(const System& I, const View& P, double t, ConstVectorRef y, ConstVectorRef v,
                     ConstVectorRef a, ConstVectorRef mu, VectorRef out, Buffers<T>& B, Work& w) {
  const int nd = I.n;
  loadInputs(I, P, B, y, v, nd, false, true);
  kinematics(I, t, B, w, w.zStar, nd);
  residualFromKinematics(I, P, B, a, nd);
  for (int i = 0; i < I.f; ++i) {
    const auto& d = B.r[i].derivatives();
    for (int j = 0; j < I.n; ++j) out(P.bOffset() + j) += mu(i) * d(j);
  }
}

}  // namespace

}  // namespace hindsight::mechanism::detail

namespace hindsight::mechanism {

using namespace detail;

void MechanismProblem::massMatrixAndForceByProjection(double t, ConstVectorRef y, ConstVectorRef v,
                                                      ConstVectorRef p, MatrixRef mass, VectorRef f,
                                                      ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  fullPass(I, *chord_, P, t, y, v, w);
  Buffers<double>& B = w.d;
  // f = -R^T (M zeta - Q).
  generalizedForce(I, P, B, B.zeta.data(), true, B.F.data(), 0.0);
  for (int j = 0; j < I.f; ++j) {
    double s = 0.0;
    for (int i = 0; i < I.nz; ++i) s += B.R[i + I.nz * j] * B.F[i];
    f(j) = -s;
  }
  // M = R^T M(z) R, column by column, symmetrised.
  for (int j = 0; j < I.f; ++j) {
    generalizedForce(I, P, B, B.R.data() + I.nz * j, false, B.x.data(), 0.0);
    for (int i = 0; i < I.f; ++i) {
      double s = 0.0;
      for (int k = 0; k < I.nz; ++k) s += B.R[k + I.nz * i] * B.x[k];
      mass(i, j) = s;
    }
  }
  for (int j = 0; j < I.f; ++j) {
    for (int i = 0; i < j; ++i) {
      const double s = 0.5 * (mass(i, j) + mass(j, i));
      mass(i, j) = s;
      mass(j, i) = s;
    }
  }
}

void MechanismProblem::residualByProjection(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                            ConstVectorRef p, VectorRef r, ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  fullPass(I, *chord_, P, t, y, v, w);
  residualFromKinematics(I, P, w.d, a, 0);
  for (int i = 0; i < I.f; ++i) r(i) = w.d.r[i];
}

void MechanismProblem::residualJacobiansByAutoDiff(double t, ConstVectorRef y, ConstVectorRef v,
                                                   ConstVectorRef a, ConstVectorRef p, MatrixRef ry,
                                                   MatrixRef rv, ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  fullPass(I, *chord_, P, t, y, v, w);
  if (2 * I.f <= kSmall) {
    stateJacobians(I, P, t, y, v, a, ry, rv, w.s, w);
  } else {
    stateJacobians(I, P, t, y, v, a, ry, rv, w.l, w);
  }
}

void MechanismProblem::addResidualParameterVjpByAutoDiff(double t, ConstVectorRef y, ConstVectorRef v,
                                                         ConstVectorRef a, ConstVectorRef p,
                                                         ConstVectorRef mu, VectorRef out,
                                                         ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  fullPass(I, *chord_, P, t, y, v, w);
  Buffers<double>& B = w.d;
  residualFromKinematics(I, P, B, a, 0);
  const int o = I.base;
  for (int i = 0; i < 3 + I.n; ++i) {
    double s = 0.0;
    for (int j = 0; j < I.f; ++j) s += B.R[o + i + I.nz * j] * mu(j);
    w.nu(i) = s;
  }
  memberParameterProduct(I, P, B.z.data() + o, B.zd.data() + o, B.zdd.data() + o, B.z.data() + o + 3,
                         B.zd.data() + o + 3, B.zdd.data() + o + 3, w.nu, out);
  // b: through the member's B (position, Jacobian, kinematics), by dual numbers in b.
  if (I.n <= kSmall) {
    chordRowProduct(I, P, t, y, v, a, mu, out, w.s, w);
  } else {
    chordRowProduct(I, P, t, y, v, a, mu, out, w.l, w);
  }
}

void MechanismProblem::coordinates(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                   VectorRef z, VectorRef zDot, ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  Work& w = workOf(ws);
  fullPass(I, *chord_, View(I.n, p.data(), I.spatial), t, y, v, w);
  for (int i = 0; i < I.nz; ++i) {
    z(i) = w.d.z[i];
    zDot(i) = w.d.zd[i];
  }
}

MechanismProblem::Energies MechanismProblem::energies(double t, ConstVectorRef y, ConstVectorRef v,
                                                      ConstVectorRef a, ConstVectorRef p,
                                                      ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  fullPass(I, *chord_, P, t, y, v, w);
  Buffers<double>& B = w.d;
  Energies e;
  // Kinetic: 1/2 z'^T M(z) z'.
  generalizedForce(I, P, B, B.zd.data(), false, B.x.data(), 0.0);
  for (int i = 0; i < I.nz; ++i) e.kinetic += 0.5 * B.zd[i] * B.x[i];
  // Potential: strain, gravity (-m g . position of the centre of mass), springs.
  const int o = I.base;
  for (int i = 0; i < I.n; ++i) {
    for (int j = 0; j < I.n; ++j) e.potential += 0.5 * B.z[o + 3 + i] * P.kee(i, j) * B.z[o + 3 + j];
  }
  for (int k = 0; k < I.nr; ++k)
    e.potential -= I.mass[k] * (I.gravity(0) * B.z[3 * k] + I.gravity(1) * B.z[3 * k + 1]);
  {
    double s, c;
    dmath::sincos(B.z[o + 2], &s, &c);
    double sw0 = P.mc(0), sw1 = P.mc(1);
    for (int i = 0; i < I.n; ++i) {
      sw0 += P.c1(0, i) * B.z[o + 3 + i];
      sw1 += P.c1(1, i) * B.z[o + 3 + i];
    }
    // int rho (R + A w) . g = m R . g + (A s_w) . g
    e.potential -= P.mass() * (I.gravity(0) * B.z[o] + I.gravity(1) * B.z[o + 1]) +
                   (c * sw0 - s * sw1) * I.gravity(0) + (s * sw0 + c * sw1) * I.gravity(1);
  }
  double cc, ccd;
  I.chord(B, true, cc, ccd, 0.0);
  Pt<double> pa, pb;
  for (const SpringRef& sp : I.springs) {
    I.point(sp.p1, B, true, cc, ccd, 0.0, pa);
    I.point(sp.p2, B, true, cc, ccd, 0.0, pb);
    const double d0 = pb.P[0] - pa.P[0], d1 = pb.P[1] - pa.P[1];
    const double l = std::sqrt(d0 * d0 + d1 * d1);
    const double ld = (d0 * (pb.Pd[0] - pa.Pd[0]) + d1 * (pb.Pd[1] - pa.Pd[1])) / l;
    e.potential += 0.5 * sp.stiffness * (l - sp.restLength) * (l - sp.restLength);
    e.dissipation += sp.damping * ld * ld;
  }
  // The constraint forces: F + Phi_z^T lambda = 0 on the dependent rows gives lambda; their power is
  // -z'^T Phi_z^T lambda = lambda^T Phi_t (only drivers have Phi_t).
  residualFromKinematics(I, P, B, a, 0);
  // Phi_u^T lambda = -F_u: solve with the transpose of the LU (small; form Phi_u^T explicitly).
  Matrix phiU(I.m, I.m);
  for (int j = 0; j < I.m; ++j) {
    for (int i = 0; i < I.m; ++i) phiU(i, j) = B.jac[i + I.m * I.dependent[j]];
  }
  Vector rhs(I.m);
  for (int i = 0; i < I.m; ++i) rhs(i) = -B.F[I.dependent[i]];
  const Vector lam = phiU.transpose().partialPivLu().solve(rhs);
  for (int i = 0; i < I.m; ++i) e.drivePower += lam(i) * B.phit[i];
  return e;
}

}  // namespace hindsight::mechanism
