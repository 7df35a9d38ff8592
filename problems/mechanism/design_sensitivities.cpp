// The design sensitivities of a described mechanism (docs/design.md §4, §10): (r_p)^T mu for the member's
// invariants p. r is linear in every invariant but b, so their part is written out at fixed kinematics
// (memberParameterProduct()); b moves the member's B along its chord and enters through c = b q, c' = b q',
// c'' = b a, by dual numbers in these three. problems/rod/design_gradient.h chains the result through the
// modal basis to the element densities.
#include <hindsight/problems/mechanism/detail/kinematics.h>
#include <hindsight/problems/mechanism/detail/member_forces.h>
#include <hindsight/problems/mechanism/detail/sensitivities.h>

namespace hindsight::mechanism::detail {

void memberParameterProduct(const System& I, const View& P, const double* zf, const double* zdf,
                            const double* xf, const double* q, const double* qd, const double* qdd,
                            const Vector& nuv, VectorRef out) {
  const int n = I.n;
  double s, c;
  dmath::sincos(zf[2], &s, &c);
  const double g0 = xf[0] - I.gravity(0), g1 = xf[1] - I.gravity(1);
  const double rho0 = c * g0 + s * g1, rho1 = -s * g0 + c * g1;                // A^T (R'' - g)
  const double nb0 = c * nuv(0) + s * nuv(1), nb1 = -s * nuv(0) + c * nuv(1);  // A^T nu_R
  const double nth = nuv(2), thd = zdf[2], thdd = xf[2];
  auto nq = [&](int i) { return nuv(3 + i); };
  // m: nu_R . m (R'' - g).
  out(0) += nb0 * rho0 + nb1 * rho1;
  // s_w = m c + C1 q enters as S s_w theta'' - s_w theta'^2 (force on the frame) and (S s_w) . rho.
  // d/ds_w of nb . (S s_w thdd - s_w thd^2) + nth (S s_w) . rho, with S^T x = (x1, -x0).
  const double sig0 = thdd * nb1 - thd * thd * nb0 + nth * rho1;
  const double sig1 = -thdd * nb0 - thd * thd * nb1 - nth * rho0;
  out(1) += sig0;
  out(2) += sig1;
  // J_w = J0 + 2 C2 q + q^T M_ee^xy q multiplies theta'' in the theta row.
  const double zeta = nth * thdd;
  out(3) += zeta;
  // C1 directly: nb . (C1 q'' + 2 thd S C1 q') + nq . C1^T rho.
  for (int j = 0; j < n; ++j) {
    out(P.c1Offset() + 2 * j) += sig0 * q[j] + nb0 * qdd[j] + 2.0 * thd * nb1 * qd[j] + rho0 * nq(j);
    out(P.c1Offset() + 1 + 2 * j) += sig1 * q[j] + nb1 * qdd[j] - 2.0 * thd * nb0 * qd[j] + rho1 * nq(j);
  }
  // h = C2 + M_ee^xy q: 2 thd h . q' (theta row) and -h thd^2 (q rows). A1 = a0 + Ct^T q: A1 . q''
  // (theta row) and A1 thdd (q rows).
  double* ct = out.data() + P.ctOffset();
  double* mee = out.data() + P.meeOffset();
  double* rotation = out.data() + P.meeRotationOffset();
  double* kee = out.data() + P.keeOffset();
  // eta once per entry, not once per (i, j): the same expression, so the same bits.
  double eta[MechanismProblem::kMaxModes];
  for (int i = 0; i < n; ++i) eta[i] = 2.0 * thd * nth * qd[i] - thd * thd * nq(i);
  for (int j = 0; j < n; ++j) {
    const double etaJ = eta[j];
    const double alphaJ = nth * qdd[j] + thdd * nq(j);
    out(P.c2Offset() + j) += etaJ + 2.0 * zeta * q[j];
    out(P.a0Offset() + j) += alphaJ;
    for (int i = 0; i < n; ++i) {
      const double etaI = eta[i];
      // Ct: A1_j = a0_j + sum_i q_i Ct_ij, and -2 thd Ct q' in the q rows.
      ct[i + n * j] += q[i] * alphaJ - 2.0 * thd * nq(i) * qd[j];
      // M_ee (symmetric part): zeta q q^T + eta q^T + nq q''^T, symmetrised; of a spatial member's
      // the first two are M_ee^xy's (J_w and h), the last M_ee's (the modal mass).
      if (P.spatial) {
        rotation[i + n * j] += zeta * q[i] * q[j] + 0.5 * (etaI * q[j] + etaJ * q[i]);
        mee[i + n * j] += 0.5 * (nq(i) * qdd[j] + nq(j) * qdd[i]);
      } else {
        mee[i + n * j] +=
            zeta * q[i] * q[j] + 0.5 * (etaI * q[j] + etaJ * q[i] + nq(i) * qdd[j] + nq(j) * qdd[i]);
      }
      kee[i + n * j] += nq(i) * q[j];
    }
  }
}

void parameterProduct(const System& I, const System& C, const View& P, double t, ConstVectorRef y,
                      ConstVectorRef v, ConstVectorRef a, ConstVectorRef mu, const double* mom, Work& w,
                      VectorRef out) {
  constexpr int kMaxFree = MechanismProblem::kMaxFree;
  const int n = I.n, nf = I.nFree, k = C.f, ci = nf, o = I.base;
  // The invariants other than b at fixed kinematics: nu = R mu on the member (frame rows from the chord
  // system's R with mu_c = b . mu_q, modal rows mu_q).
  double mb = 0.0;
  for (int l = 0; l < n; ++l) mb += P.b(l) * mu(nf + l);
  const Buffers<double>& D = w.cd;
  double xf[3];
  for (int i = 0; i < 3; ++i) {
    double s = 0.0, x = D.zeta[o + i];
    for (int j = 0; j < k; ++j) {
      const double rij = D.R[o + i + C.nz * j];
      s += rij * (j == ci ? mb : mu(j));
      x += rij * w.sigmaDdot(j);
    }
    w.nu(i) = s;
    xf[i] = x;
  }
  for (int l = 0; l < n; ++l) w.nu(3 + l) = mu(nf + l);
  memberParameterProduct(I, P, D.z.data() + o, D.zd.data() + o, xf, y.data() + nf, v.data() + nf,
                         a.data() + nf, w.nu, out);
  // b: through c = b q, c' = b q', c'' = b a (dual numbers in these three) and the explicit b rho_c of
  // the modal rows.
  const int nd = 3;
  Buffers<AD3>& B = w.c3;
  AD3 seedDdot[kMaxFree + 1];
  for (int i = 0; i < k; ++i) {
    seedDdot[i] =
        i == ci ? Make<AD3>::variable(w.sigmaDdot(i), nd, 2) : Make<AD3>::constant(w.sigmaDdot(i), nd);
  }
  twoDirectionKinematics(C, t, w, ci, nd, 0, 1, B);
  AD3 m[kMoments], phi[4];
  constants(mom, kMoments, nd, m);
  chordResidual<AD3>(C, P, B, seedDdot, m, phi, Make<AD3>::constant(0.0, nd));
  // mu . r = mu_f . r_f + mu_q . F_q + (mu_q . b) r_c; F_q depends on c through phi.
  double muU[4] = {0.0, 0.0, 0.0, 0.0};
  for (int l = 0; l < n; ++l) {
    double u[4];
    modalRowPhi(P, w, phi[3].value(), l, u);
    for (int e = 0; e < 4; ++e) muU[e] += mu(nf + l) * u[e];
  }
  double g[3];
  for (int x = 0; x < 3; ++x) {
    double s = mb * B.r[ci].derivatives()(x);
    for (int i = 0; i < nf; ++i) s += mu(i) * B.r[i].derivatives()(x);
    for (int e = 0; e < 4; ++e) s += muU[e] * phi[e].derivatives()(x);
    g[x] = s;
  }
  const double rc = B.r[ci].value();
  for (int j = 0; j < n; ++j) {
    out(P.bOffset() + j) += g[0] * y(nf + j) + g[1] * v(nf + j) + g[2] * a(nf + j) + mu(nf + j) * rc;
  }
}

}  // namespace hindsight::mechanism::detail

namespace hindsight::mechanism {

using namespace detail;

void MechanismProblem::addResidualParameterVjp(double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a,
                                               ConstVectorRef p, ConstVectorRef mu, VectorRef out,
                                               ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  const Impl& C = *chord_;
  Work& w = workOf(ws);
  const View P(I.n, p.data(), I.spatial);
  double mom[kMoments];
  productPoint(I, C, P, t, y, v, a, false, w, mom);
  parameterProduct(I, C, P, t, y, v, a, mu, mom, w, out);
}

}  // namespace hindsight::mechanism
