// The residual, mass matrix, force and Jacobians that the integrators and the adjoints ask for
// (docs/design.md §5, §10; mechanism_problem.h, "The chord path"): the chord path's mass matrix and force
// (the residual's linear part in sigma'' and the moments of a), r_y and r_y' by dual numbers in the chord
// system's few directions chained to q, q' through the moments' gradients, and their transposed products
// r_y^T mu, r_y'^T mu for an explicit adjoint stage. The parameter product is design_sensitivities.cpp's.
#include <hindsight/problems/mechanism/detail/kinematics.h>
#include <hindsight/problems/mechanism/detail/member_forces.h>
#include <hindsight/problems/mechanism/detail/sensitivities.h>

#include <cassert>
#include <type_traits>

namespace hindsight::mechanism::detail {

namespace {

/// Widens the dual numbers of the chord system's kinematics from `from` to `to` directions (the
/// kinematics depend on sigma and sigma' only, so they run in fewer directions than the residual).
void widen(const System& C, Buffers<ADS>& B, int from, int to) {
  auto pad = [&](ADS& x) {
    DerivativesOf<kSmall> d = DerivativesOf<kSmall>::Zero(to);
    d.head(from) = x.derivatives();
    x.derivatives() = d;
  };
  for (int i = 0; i < C.nz; ++i) {
    pad(B.z[i]);
    pad(B.zd[i]);
    pad(B.zeta[i]);
  }
  for (int i = 0; i < C.nz * C.f; ++i) pad(B.R[i]);
  for (int i = 0; i <= C.nr; ++i) {
    pad(B.sn[i]);
    pad(B.cs[i]);
  }
  pad(B.b[0]);
}

/// The derivatives of the chord residual rho (dRho[i + k e]) and of phi (dPhi[4 e + i]) in the
/// directions e = sigma''_j (j < k), A1 . a (k), C1 a (k + 1, k + 2): the acceleration part of
/// chordForce() (no gravity, velocity or spring terms), linear, at the kinematics of w.cd.
void accelerationDerivatives(const System& C, const View& P, Work& w, const double* mom, double* dRho,
                             double* dPhi) {
  const Buffers<double>& B = w.cd;
  double* F = w.cd.x.data();
  const int k = C.f, o = C.base;
  const double s = B.sn[C.nr], c = B.cs[C.nr];
  for (int e = 0; e < k + 3; ++e) {
    for (int i = 0; i < C.nz; ++i) F[i] = 0.0;
    double* phi = dPhi + 4 * e;
    phi[0] = phi[1] = phi[2] = phi[3] = 0.0;
    if (e < k) {
      const double* x = B.R.data() + C.nz * e;  // d z''/d sigma''_e
      for (int b = 0; b < C.nr; ++b) {
        F[3 * b] = C.mass[b] * x[3 * b];
        F[3 * b + 1] = C.mass[b] * x[3 * b + 1];
        F[3 * b + 2] = C.inertia[b] * x[3 * b + 2];
      }
      const double rho0 = c * x[o] + s * x[o + 1], rho1 = -s * x[o] + c * x[o + 1], thdd = x[o + 2];
      const double aR0 = P.mass() * rho0 - mom[kSw1] * thdd, aR1 = P.mass() * rho1 + mom[kSw0] * thdd;
      F[o] = c * aR0 - s * aR1;
      F[o + 1] = s * aR0 + c * aR1;
      F[o + 2] = -mom[kSw1] * rho0 + mom[kSw0] * rho1 + mom[kJw] * thdd;
      phi[0] = rho0;
      phi[1] = rho1;
      phi[2] = thdd;
    } else if (e == k) {
      F[o + 2] = 1.0;  // A1 . a in the frame angle's row
    } else {
      // C1 a in the body-frame force on the frame origin, rotated to the global axes.
      F[o] = e == k + 1 ? c : -s;
      F[o + 1] = e == k + 1 ? s : c;
    }
    for (int j = 0; j < k; ++j) {
      double sum = 0.0;
      for (int i = 0; i < C.nz; ++i) sum += B.R[i + C.nz * j] * F[i];
      dRho[j + k * e] = sum;
    }
  }
}

/// The mass matrix and (unless massOnly) the force of the chord path.
void massAndForce(const System& I, const System& C, double t, ConstVectorRef y, ConstVectorRef v,
                  ConstVectorRef p, MatrixRef mass, VectorRef f, Work& w, bool massOnly) {
  const View P(I.n, p.data(), I.spatial);
  const int n = I.n, nf = I.nFree, k = C.f, ci = nf;
  chordInputs(I, P, y, v, nullptr, w);
  chordKinematics(C, t, w, massOnly);
  const Matrix& mee = meeOf(P, w);
  double mom[kMoments];
  modalProducts(P, mee, meeRotationOf(P, w), y.data() + nf, v.data() + nf, nullptr, false, w, mom);
  if (!massOnly) {
    // The force: the residual at a = 0 (chordInputs() set sigma'' = 0, modalProducts() the moments of a).
    double phi[4];
    chordResidual<double>(C, P, w.cd, w.sigmaDdot.data(), mom, phi, 0.0);
    for (int i = 0; i < nf; ++i) f(i) = -w.cd.r[i];
    for (int l = 0; l < n; ++l) f(nf + l) = -(modalRow(P, w, phi, l) + P.b(l) * w.cd.r[ci]);
  }
  // The mass matrix: the residual is linear in sigma'' and in the moments A1 . a, C1 a; its
  // derivatives in these k + 3 directions are the acceleration part of chordResidual(), in double.
  const int nd = k + 3;
  double dRho[(MechanismProblem::kMaxFree + 1) * (MechanismProblem::kMaxFree + 4)];
  double dPhi[4 * (MechanismProblem::kMaxFree + 4)];
  accelerationDerivatives(C, P, w, mom, dRho, dPhi);
  // d/da_j of a chord scalar with derivatives d: through c'' = b a and the moments.
  auto modal = [&](const double* d, int j) {
    return d[ci] * P.b(j) + d[k] * w.a1(j) + d[k + 1] * P.c1(0, j) + d[k + 2] * P.c1(1, j);
  };
  double rowOf[MechanismProblem::kMaxFree + 4];
  for (int i = 0; i < nf; ++i) {
    for (int e = 0; e < nd; ++e) rowOf[e] = dRho[i + k * e];
    for (int j = 0; j < nf; ++j) mass(i, j) = rowOf[j];
    for (int j = 0; j < n; ++j) mass(i, nf + j) = modal(rowOf, j);
  }
  for (int e = 0; e < nd; ++e) rowOf[e] = dRho[ci + k * e];
  for (int j = 0; j < n; ++j) w.along(j) = modal(rowOf, j);
  for (int l = 0; l < n; ++l) {
    double u[4];
    modalRowPhi(P, w, 0.0, l, u);  // beta' does not depend on the acceleration (dPhi of beta' = 0)
    const double bl = P.b(l);
    auto uphi = [&](int e) {
      return u[0] * dPhi[4 * e] + u[1] * dPhi[4 * e + 1] + u[2] * dPhi[4 * e + 2] + u[3] * dPhi[4 * e + 3];
    };
    for (int j = 0; j < nf; ++j) mass(nf + l, j) = uphi(j) + bl * dRho[ci + k * j];
    w.uq(l) = uphi(ci);
  }
  // The modal block column by column (contiguous, so that it vectorises); w.uq holds uphi(c) by row.
  const double* b = P.p + P.bOffset();
  for (int j = 0; j < n; ++j) {
    const double bj = b[j], aj = w.along(j);
    const double* meeColumn = mee.data() + n * j;
    double* column = &mass(nf, nf + j);
    for (int l = 0; l < n; ++l) column[l] = meeColumn[l] + w.uq(l) * bj + b[l] * aj;
  }
  const int fc = I.f;
  for (int j = 0; j < fc; ++j) {
    for (int i = 0; i < j; ++i) {
      const double s = 0.5 * (mass(i, j) + mass(j, i));
      mass(i, j) = s;
      mass(j, i) = s;
    }
  }
}

/// The directions of the chord path's dual pass (dualChordResidual()): sigma (k), sigma' (k), then the
/// seven moments that depend on q or q', whatever the number of modes.
struct ChordDirections {
  int k, nd, dSw0, dSw1, dJw, dA1a, dC1v0, dC1v1, dHv;
  explicit ChordDirections(int chordCount)
      : k(chordCount),
        nd(2 * chordCount + 7),
        dSw0(2 * chordCount),
        dSw1(dSw0 + 1),
        dJw(dSw0 + 2),
        dA1a(dSw0 + 3),
        dC1v0(dSw0 + 4),
        dC1v1(dSw0 + 5),
        dHv(dSw0 + 6) {}
};

/// The chord residual B.r and the frame scalars phi in the 2k + 7 directions of ChordDirections, after
/// chordKinematics() and modalProducts() (mom) at the point, with dual numbers of type ADT (AD9 without
/// free coordinates, ADS with them). Both r_y, r_y' (chordJacobians()) and their products with a mu
/// (chordStateVjp()) chain these few directions to q, q' through the moments' gradients.
template <typename ADT>
void dualChordResidual(const System& C, const View& P, double t, const double* mom, Work& w, Buffers<ADT>& B,
                       ADT* phi) {
  const ChordDirections D(C.f);
  const int k = D.k, nd = D.nd;
  if constexpr (std::is_same_v<ADT, ADS>) {
    for (int i = 0; i < k; ++i) {
      B.y[i] = Make<ADS>::variable(w.sigma(i), 2 * k, i);
      B.v[i] = Make<ADS>::variable(w.sigmaDot(i), 2 * k, k + i);
    }
    B.b[0] = Make<ADS>::constant(1.0, 2 * k);
    kinematics(C, t, B, w, w.zChord, 2 * k, Part::All, &w.cd);
    widen(C, B, 2 * k, nd);
  } else {
    static_assert(std::is_same_v<ADT, AD9>, "fixed-size Jacobians are for k = 1 (2 k + 7 = 9 directions)");
    assert(k == 1);
    twoDirectionKinematics(C, t, w, 0, nd, 0, 1, B);
  }
  ADT seedDdot[MechanismProblem::kMaxFree + 1];
  for (int j = 0; j < k; ++j) seedDdot[j] = Make<ADT>::constant(w.sigmaDdot(j), nd);
  ADT m[kMoments];
  constants(mom, kMoments, nd, m);
  m[kSw0] = Make<ADT>::variable(mom[kSw0], nd, D.dSw0);
  m[kSw1] = Make<ADT>::variable(mom[kSw1], nd, D.dSw1);
  m[kJw] = Make<ADT>::variable(mom[kJw], nd, D.dJw);
  m[kA1a] = Make<ADT>::variable(mom[kA1a], nd, D.dA1a);
  m[kC1v0] = Make<ADT>::variable(mom[kC1v0], nd, D.dC1v0);
  m[kC1v1] = Make<ADT>::variable(mom[kC1v1], nd, D.dC1v1);
  m[kHv] = Make<ADT>::variable(mom[kHv], nd, D.dHv);
  chordResidual<ADT>(C, P, B, seedDdot, m, phi, Make<ADT>::constant(0.0, nd));
}

/// The chord path's r_y, r_y' after chordKinematics() and modalProducts() (mom) at the point.
template <typename ADT>
void chordJacobians(const System& I, const System& C, const View& P, double t, const double* mom,
                    const Matrix& mee, MatrixRef ry, MatrixRef rv, Work& w, Buffers<ADT>& B) {
  const int n = I.n, nf = I.nFree, k = C.f, ci = nf;
  const ChordDirections D(k);
  const int dSw0 = D.dSw0, dSw1 = D.dSw1, dJw = D.dJw, dA1a = D.dA1a, dC1v0 = D.dC1v0, dC1v1 = D.dC1v1,
            dHv = D.dHv;
  ADT phi[4];
  dualChordResidual(C, P, t, mom, w, B, phi);
  const double thdd = phi[2].value(), thd = phi[3].value();
  // d/dq_j and d/dq'_j of a chord scalar: through c = b q, c' = b q' and the moments' gradients
  // (s_w: C1, J_w: 2 h, A1 . a: Ct a, h . q': M_ee q' and h, C1 q': C1).
  auto dq = [&](const ADT& x, int j) {
    const auto& d = x.derivatives();
    return d(ci) * P.b(j) + d(dSw0) * P.c1(0, j) + d(dSw1) * P.c1(1, j) + d(dJw) * 2.0 * w.h(j) +
           d(dA1a) * w.ctA(j) + d(dHv) * w.meeV(j);
  };
  auto dv = [&](const ADT& x, int j) {
    const auto& d = x.derivatives();
    return d(k + ci) * P.b(j) + d(dC1v0) * P.c1(0, j) + d(dC1v1) * P.c1(1, j) + d(dHv) * w.h(j);
  };
  for (int i = 0; i < nf; ++i) {
    const auto& d = B.r[i].derivatives();
    for (int j = 0; j < nf; ++j) {
      ry(i, j) = d(j);
      rv(i, j) = d(k + j);
    }
    for (int j = 0; j < n; ++j) {
      ry(i, nf + j) = dq(B.r[i], j);
      rv(i, nf + j) = dv(B.r[i], j);
    }
  }
  for (int j = 0; j < n; ++j) {
    w.along(j) = dq(B.r[ci], j);
    w.vel(j) = dv(B.r[ci], j);
  }
  const auto& drc = B.r[ci].derivatives();
  const double* ct = P.p + P.ctOffset();
  const double* kee = P.p + P.keeOffset();
  for (int l = 0; l < n; ++l) {
    double u[4];
    modalRowPhi(P, w, thd, l, u);
    const double bl = P.b(l);
    auto uphi = [&](int direction) {
      return u[0] * phi[0].derivatives()(direction) + u[1] * phi[1].derivatives()(direction) +
             u[2] * phi[2].derivatives()(direction) + u[3] * phi[3].derivatives()(direction);
    };
    for (int j = 0; j < nf; ++j) {
      ry(nf + l, j) = uphi(j) + bl * drc(j);
      rv(nf + l, j) = uphi(k + j) + bl * drc(k + j);
    }
    const double uq = uphi(ci), uv = uphi(k + ci);
    // The direct terms: A1_l beta'' (dA1_l/dq_j = Ct_jl), K_ee q, -beta'^2 h, -2 beta' Ct q'.
    for (int j = 0; j < n; ++j) {
      ry(nf + l, nf + j) =
          thdd * ct[j + n * l] + kee[l + n * j] - thd * thd * mee(l, j) + uq * P.b(j) + bl * w.along(j);
      rv(nf + l, nf + j) = -2.0 * thd * ct[l + n * j] + uv * P.b(j) + bl * w.vel(j);
    }
  }
}

/// outY = r_y^T mu, outV = r_y'^T mu after chordKinematics() and modalProducts() (mom, with the
/// Jacobian products) at the point: the transposed form of chordJacobians(), term by term, without
/// forming r_y or r_y'. The chord scalars' derivatives are combined with mu first (S = sum_i mu_i r_i over
/// the free rows, plus (b . mu_q) r_c, plus the modal rows' phi terms), so the chain to q, q' runs once
/// instead of once per row, and the direct terms of the modal rows are four products of mu_q with the
/// invariant matrices: O(n^2) instead of the Jacobians' 2 (f^2 + f^3) (forming, then M^{-1} r_y, M^{-1}
/// r_y' in the adapter).
template <typename ADT>
void chordStateVjp(const System& I, const System& C, const View& P, double t, const double* mom,
                   const Matrix& mee, ConstVectorRef mu, VectorRef outY, VectorRef outV, Work& w,
                   Buffers<ADT>& B) {
  const int n = I.n, nf = I.nFree, k = C.f, ci = nf;
  const ChordDirections D(k);
  ADT phi[4];
  dualChordResidual(C, P, t, mom, w, B, phi);
  const double thdd = phi[2].value(), thd = phi[3].value();
  // mb = b . mu_q (the modal rows' b rho_c) and muU = sum_l mu_l dF_q,l/dphi.
  double mb = 0.0, muU[4] = {0.0, 0.0, 0.0, 0.0};
  for (int l = 0; l < n; ++l) {
    double u[4];
    modalRowPhi(P, w, thd, l, u);
    const double ml = mu(nf + l);
    mb += P.b(l) * ml;
    for (int e = 0; e < 4; ++e) muU[e] += ml * u[e];
  }
  constexpr int kMaxDirections = 2 * (MechanismProblem::kMaxFree + 1) + 7;
  double S[kMaxDirections], U[kMaxDirections];
  for (int d = 0; d < D.nd; ++d) {
    double s = mb * B.r[ci].derivatives()(d);
    for (int i = 0; i < nf; ++i) s += mu(i) * B.r[i].derivatives()(d);
    S[d] = s;
    U[d] = muU[0] * phi[0].derivatives()(d) + muU[1] * phi[1].derivatives()(d) +
           muU[2] * phi[2].derivatives()(d) + muU[3] * phi[3].derivatives()(d);
  }
  for (int j = 0; j < nf; ++j) {
    outY(j) = S[j] + U[j];
    outV(j) = S[k + j] + U[k + j];
  }
  const Eigen::Map<const Matrix> ct(P.p + P.ctOffset(), n, n), kee(P.p + P.keeOffset(), n, n);
  const auto muQ = mu.segment(nf, n);
  w.muCt.noalias() = ct * muQ;
  w.muCtT.noalias() = ct.transpose() * muQ;
  w.muKee.noalias() = kee.transpose() * muQ;
  w.muMee.noalias() = mee.transpose() * muQ;
  // d/dq_j, d/dq'_j of S as chordJacobians()'s dq, dv; phi enters the modal rows' Jacobians through c
  // and c' only (uq b_j, uv b_j there).
  const double uq = U[ci], uv = U[k + ci];
  for (int j = 0; j < n; ++j) {
    const double bj = P.b(j);
    outY(nf + j) = S[ci] * bj + S[D.dSw0] * P.c1(0, j) + S[D.dSw1] * P.c1(1, j) + S[D.dJw] * 2.0 * w.h(j) +
                   S[D.dA1a] * w.ctA(j) + S[D.dHv] * w.meeV(j) + uq * bj + thdd * w.muCt(j) + w.muKee(j) -
                   thd * thd * w.muMee(j);
    outV(nf + j) = S[k + ci] * bj + S[D.dC1v0] * P.c1(0, j) + S[D.dC1v1] * P.c1(1, j) + S[D.dHv] * w.h(j) +
                   uv * bj - 2.0 * thd * w.muCtT(j);
  }
}

/// chordStateVjp() with the dual numbers of the chord system's size.
void stateVjp(const System& I, const System& C, const View& P, double t, const double* mom, const Matrix& mee,
              ConstVectorRef mu, VectorRef outY, VectorRef outV, Work& w) {
  if (C.f == 1) {
    chordStateVjp(I, C, P, t, mom, mee, mu, outY, outV, w, w.c9);
  } else {
    chordStateVjp(I, C, P, t, mom, mee, mu, outY, outV, w, w.cs);
  }
}

}  // namespace

}  // namespace hindsight::mechanism::detail

namespace hindsight::mechanism {

using namespace detail;

void MechanismProblem::massMatrixAndForce(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p,
                                          MatrixRef mass, VectorRef f, ProblemWorkspace* ws) const {
  massAndForce(*impl_, *chord_, t, y, v, p, mass, f, workOf(ws), false);
}

void MechanismProblem::massMatrix(double t, ConstVectorRef y, ConstVectorRef p, MatrixRef mass,
                                  ProblemWorkspace* ws) const {
  Work& w = workOf(ws);
  w.mu.setZero();
  massAndForce(*impl_, *chord_, t, y, w.mu, p, mass, w.fScratch, w, true);
}

void MechanismProblem::force(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, VectorRef f,
                             ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  const Impl& C = *chord_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  const int n = I.n, nf = I.nFree;
  chordInputs(I, P, y, v, nullptr, w);
  chordKinematics(C, t, w);
  double mom[kMoments], phi[4];
  const Matrix& mee = meeOf(P, w);
  modalProducts(P, mee, meeRotationOf(P, w), y.data() + nf, v.data() + nf, nullptr, false, w, mom);
  chordResidual<double>(C, P, w.cd, w.sigmaDdot.data(), mom, phi, 0.0);
  for (int i = 0; i < nf; ++i) f(i) = -w.cd.r[i];
  for (int l = 0; l < n; ++l) f(nf + l) = -(modalRow(P, w, phi, l) + P.b(l) * w.cd.r[nf]);
}

void MechanismProblem::residual(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                ConstVectorRef p, VectorRef r, ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  const Impl& C = *chord_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  const int n = I.n, nf = I.nFree;
  chordInputs(I, P, y, v, a.data(), w);
  chordKinematics(C, t, w);
  double mom[kMoments], phi[4];
  const Matrix& mee = meeOf(P, w);
  modalProducts(P, mee, meeRotationOf(P, w), y.data() + nf, v.data() + nf, a.data() + nf, false, w, mom);
  chordResidual<double>(C, P, w.cd, w.sigmaDdot.data(), mom, phi, 0.0);
  for (int i = 0; i < nf; ++i) r(i) = w.cd.r[i];
  for (int l = 0; l < n; ++l) r(nf + l) = modalRow(P, w, phi, l) + P.b(l) * w.cd.r[nf];
}

void MechanismProblem::residualJacobians(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                         ConstVectorRef p, MatrixRef ry, MatrixRef rv,
                                         ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  const Impl& C = *chord_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  double mom[kMoments];
  const Matrix& mee = productPoint(I, C, P, t, y, v, a, true, w, mom);
  if (C.f == 1) {
    chordJacobians(I, C, P, t, mom, mee, ry, rv, w, w.c9);
  } else {
    chordJacobians(I, C, P, t, mom, mee, ry, rv, w, w.cs);
  }
}

void MechanismProblem::residualStateVjp(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                        ConstVectorRef p, ConstVectorRef mu, VectorRef outY, VectorRef outV,
                                        ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  const Impl& C = *chord_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  double mom[kMoments];
  const Matrix& mee = productPoint(I, C, P, t, y, v, a, true, w, mom);
  stateVjp(I, C, P, t, mom, mee, mu, outY, outV, w);
}

void MechanismProblem::residualVjps(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                    ConstVectorRef p, ConstVectorRef mu, VectorRef outY, VectorRef outV,
                                    VectorRef gradient, ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  const Impl& C = *chord_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  // One set of positions, kinematics and modal products for both products.
  double mom[kMoments];
  const Matrix& mee = productPoint(I, C, P, t, y, v, a, true, w, mom);
  stateVjp(I, C, P, t, mom, mee, mu, outY, outV, w);
  parameterProduct(I, C, P, t, y, v, a, mu, mom, w, gradient);
}

}  // namespace hindsight::mechanism
