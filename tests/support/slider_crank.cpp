#include "support/slider_crank.h"

#include <hindsight/engine/deterministic_math.h>

#include <unsupported/Eigen/AutoDiff>

#include <array>
#include <vector>

namespace hindsight::rod {
namespace {

// Derivative vectors live on the stack (fixed capacity), so AD arithmetic allocates nothing. Every
// AD temporary copies its whole capacity, so a small-capacity type serves up to 12 modes (the common
// case) and the large one the rest.
template <int Capacity>
using DerivativesOf = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, Capacity, 1>;
template <int Capacity>
using ADOf = Eigen::AutoDiffScalar<DerivativesOf<Capacity>>;
constexpr int kSmallCapacity = 24;
constexpr int kLargeCapacity = 2 * SliderCrankProblem::kMaxModes;

/// Read-only view of the invariants inside p.
struct View {
  View(const SliderCrankLayout& layout, ConstVectorRef p) : n(layout.modes), p(p.data()), layout(layout) {}
  double mc(int k) const { return p[layout.massMoment() + k]; }
  double j0() const { return p[layout.polarMoment()]; }
  double c1(int k, int j) const { return p[layout.c1() + k + 2 * j]; }
  double c2(int i) const { return p[layout.c2() + i]; }
  double a0(int i) const { return p[layout.a0() + i]; }
  double ct(int i, int j) const { return p[layout.cTilde() + i + n * j]; }
  // M_ee enters through its symmetric part: the mass matrix must be symmetric (it is factorised by
  // Cholesky, which reads one triangle), and the gradient then splits evenly between (i, j) and (j, i).
  double mee(int i, int j) const { return 0.5 * (p[layout.mee() + i + n * j] + p[layout.mee() + j + n * i]); }
  double kee(int i, int j) const { return p[layout.kee() + i + n * j]; }
  double b(int i) const { return p[layout.b() + i]; }
  int n;
  const double* p;
  const SliderCrankLayout& layout;
};

/// The crank's state at one time: phi', phi'', sin(phi), cos(phi).
struct CrankState {
  double phiDot = 0.0, phiDdot = 0.0, sinPhi = 0.0, cosPhi = 0.0;
};

CrankState crankStateAt(const CrankMotion& crank, double t) {
  double phi;
  CrankState k;
  crank.at(t, phi, k.phiDot, k.phiDdot);
  dmath::sincos(phi, &k.sinPhi, &k.cosPhi);
  return k;
}

/// The frame's kinematics from the closure r sin(phi) + (L + c) sin(beta) = 0, c = b q:
/// sin(beta) = u = -r sin(phi) / (L + c), cos(beta) = sqrt(1 - u^2) (|beta| < pi/2 because r < L),
/// g = dbeta/dc, betaDot = beta_t + g c', betaC = beta'' - g c'' (the part without q''),
/// rho = R(beta)^T r_A''. beta itself is not needed: only its sine and cosine enter the residual.
template <typename T>
struct Frame {
  T g, betaDot, betaC, rho0, rho1;
};

template <typename T>
void frameKinematics(const CrankState& k, double r, double length, const T& c, const T& cDot, Frame<T>& out) {
  using std::sqrt;
  const double s = k.sinPhi, co = k.cosPhi, phiDot = k.phiDot, phiDdot = k.phiDdot;
  const T d = length + c;
  const T u = -r * s / d;
  const T cosBeta = sqrt(1.0 - u * u);
  const T w1 = 1.0 / cosBeta;     // asin'
  const T w2 = u * w1 * w1 * w1;  // asin''
  const T ut = -r * co * phiDot / d;
  const T uc = r * s / (d * d);
  const T utt = (r * s * phiDot * phiDot - r * co * phiDdot) / d;
  const T utc = r * co * phiDot / (d * d);
  const T ucc = -2.0 * r * s / (d * d * d);
  const T bt = w1 * ut;
  out.g = w1 * uc;
  const T btt = w2 * ut * ut + w1 * utt;
  const T btc = w2 * ut * uc + w1 * utc;
  const T bcc = w2 * uc * uc + w1 * ucc;
  out.betaDot = bt + out.g * cDot;
  out.betaC = btt + 2.0 * btc * cDot + bcc * cDot * cDot;
  // r_A'' = r phi'' (-sin, cos) - r phi'^2 (cos, sin), expressed in the body frame.
  const double ax = -r * phiDdot * s - r * phiDot * phiDot * co;
  const double ay = r * phiDdot * co - r * phiDot * phiDot * s;
  out.rho0 = cosBeta * ax + u * ay;
  out.rho1 = -u * ax + cosBeta * ay;
}

/// The residual r (see the header) for scalar type T. q, qd are length n; a is the acceleration;
/// ba = b . a. Scratch arrays A1, h of length n. Returns g * kappa (needed for d/db).
template <typename T>
T residualCore(const View& P, const Frame<T>& fr, const T* q, const T* qd, ConstVectorRef a, const T& ba,
               T* r, T* A1, T* h) {
  const int n = P.n;
  T jw = T(P.j0());
  T sw0 = T(P.mc(0)), sw1 = T(P.mc(1));
  for (int i = 0; i < n; ++i) {
    jw += 2.0 * P.c2(i) * q[i];
    sw0 += P.c1(0, i) * q[i];
    sw1 += P.c1(1, i) * q[i];
  }
  for (int j = 0; j < n; ++j) {
    T mq = T(0.0);
    T a1 = T(P.a0(j));
    for (int i = 0; i < n; ++i) {
      mq += P.mee(j, i) * q[i];
      a1 += q[i] * P.ct(i, j);
    }
    h[j] = P.c2(j) + mq;
    jw += q[j] * mq;
    A1[j] = a1;
  }
  const T betaA = fr.g * ba;
  T kappa = fr.betaDot * 0.0;
  T hqd = T(0.0);
  for (int j = 0; j < n; ++j) {
    kappa += A1[j] * a(j);
    hqd += h[j] * qd[j];
  }
  kappa += jw * (betaA + fr.betaC) + (-sw1 * fr.rho0 + sw0 * fr.rho1) + 2.0 * fr.betaDot * hqd;
  const T gKappa = fr.g * kappa;
  const T betaDot2 = fr.betaDot * fr.betaDot;
  for (int i = 0; i < n; ++i) {
    // Sums with constant coefficients first, so that products of two active scalars are O(n), not O(n^2).
    double meeA = 0.0;
    T keeQ = T(0.0), ctQd = T(0.0);
    for (int j = 0; j < n; ++j) {
      meeA += P.mee(i, j) * a(j);
      keeQ += P.kee(i, j) * q[j];
      ctQd += P.ct(i, j) * qd[j];
    }
    T ri = keeQ - 2.0 * fr.betaDot * ctQd + meeA;
    ri += A1[i] * (betaA + fr.betaC) + gKappa * P.b(i) + P.c1(0, i) * fr.rho0 + P.c1(1, i) * fr.rho1 -
          betaDot2 * h[i];
    r[i] = ri;
  }
  return gKappa;
}

template <int Capacity>
struct AdBuffers {
  explicit AdBuffers(int n) : q(n), qd(n), r(n), a1(n), h(n) {}
  std::vector<ADOf<Capacity>> q, qd, r, a1, h;
};

struct RodWorkspace final : ProblemWorkspace {
  explicit RodWorkspace(int n)
      : small(n),
        large(n),
        dq(n),
        dqd(n),
        dr(n),
        da1(n),
        dh(n),
        zero(Vector::Zero(n)),
        meeSym(n, n),
        a1(n),
        h(n),
        keeQ(n),
        ctV(n),
        gb(n),
        eta(n),
        alpha(n),
        meeQ(n),
        ctMu(n),
        ctA(n),
        meeMu(n),
        meeV(n) {}
  AdBuffers<kSmallCapacity> small;  // Jacobians up to 12 modes; the parameter product (3 directions)
  AdBuffers<kLargeCapacity> large;  // Jacobians beyond 12 modes
  std::vector<double> dq, dqd, dr, da1, dh;
  Vector zero;
  // The symmetric part of M_ee. A workspace made for a fixed p (createModelWorkspaceFor) computes it
  // once per solve; otherwise every call that needs it recomputes it from its own p.
  bool parametersFixed = false;
  Matrix meeSym;
  // The crank at the last two times asked for: an explicit Runge-Kutta step evaluates the rhs twice
  // at t + h/2 and at t + h, the next step's t, and the adjoint visits the same times.
  double crankTime[2] = {0.0, 0.0};
  CrankState crankState[2];
  bool crankValid[2] = {false, false};
  int crankNext = 0;
  // Scratch of the kernels.
  Vector a1, h, keeQ, ctV, gb, eta, alpha, meeQ, ctMu, ctA, meeMu, meeV;
};

RodWorkspace& workspaceOf(ProblemWorkspace* ws) {
  assert(ws != nullptr);
  return static_cast<RodWorkspace&>(*ws);
}

double dot(const View& P, ConstVectorRef x) {
  double s = 0.0;
  for (int i = 0; i < P.n; ++i) s += P.b(i) * x(i);
  return s;
}

void symmetricMee(const View& P, Matrix& out) {
  for (int j = 0; j < P.n; ++j) {
    for (int i = 0; i < P.n; ++i) out(i, j) = P.mee(i, j);
  }
}

/// The symmetric part of M_ee for this call's p.
const Matrix& meeOf(const View& P, RodWorkspace& w) {
  if (!w.parametersFixed) symmetricMee(P, w.meeSym);
  return w.meeSym;
}

const CrankState& crankOf(const CrankMotion& crank, double t, RodWorkspace& w) {
  for (int k = 0; k < 2; ++k) {
    if (w.crankValid[k] && w.crankTime[k] == t) return w.crankState[k];
  }
  const int k = w.crankNext;
  w.crankNext = 1 - k;
  w.crankTime[k] = t;
  w.crankState[k] = crankStateAt(crank, t);
  w.crankValid[k] = true;
  return w.crankState[k];
}

}  // namespace

SliderCrankProblem::SliderCrankProblem(int modeCount, double rodLength, const CrankMotion& crank)
    : length_(rodLength), crank_(crank) {
  if (modeCount < 1 || modeCount > kMaxModes) {
    throw std::invalid_argument("modeCount = " + std::to_string(modeCount) + " must be in [1, " +
                                std::to_string(kMaxModes) + "]");
  }
  if (!(rodLength > 0.0)) throw std::invalid_argument("rod length must be positive");
  if (!(crank.radius > 0.0) || !(crank.radius < rodLength)) {
    throw std::invalid_argument("crank radius = " + std::to_string(crank.radius) +
                                " must be in (0, rod length = " + std::to_string(rodLength) + ")");
  }
  if (!(crank.rampTime > 0.0)) throw std::invalid_argument("crank ramp time must be positive");
  layout_.modes = modeCount;
}

std::unique_ptr<ProblemWorkspace> SliderCrankProblem::createModelWorkspace() const {
  return std::make_unique<RodWorkspace>(layout_.modes);
}

std::unique_ptr<ProblemWorkspace> SliderCrankProblem::createModelWorkspaceFor(ConstVectorRef p) const {
  auto ws = std::make_unique<RodWorkspace>(layout_.modes);
  symmetricMee(View(layout_, p), ws->meeSym);
  ws->parametersFixed = true;
  return ws;
}

void SliderCrankProblem::initialCoordinates(ConstVectorRef, VectorRef y0, VectorRef v0) const {
  y0.setZero();
  v0.setZero();
}

double SliderCrankProblem::frameAngle(double t, ConstVectorRef q, ConstVectorRef p) const {
  const View P(layout_, p);
  double phi, phiDot, phiDdot;
  crank_.at(t, phi, phiDot, phiDdot);
  return dmath::asin(-crank_.radius * dmath::sin(phi) / (length_ + dot(P, q)));
}

namespace {

/// M(t, q) and f(t, q, q') = -r(t, q, q', 0) in one pass: one frame kinematics, each product of q and
/// q' with an invariant matrix once (docs/design.md §3; the header's compact residual at a = 0):
///   M = M_ee + beta_q^T A1 + A1^T beta_q + J_w beta_q^T beta_q,  beta_q = g b,
///   f = -(K_ee q - 2 beta' Ct q' + A1^T beta_c + g kappa b + C1^T rho - beta'^2 h),
///   kappa = J_w beta_c + (S s_w) . rho + 2 beta' h . q'.
/// Either output may be absent (nullptr).
void massAndForce(const SliderCrankLayout& layout, const CrankMotion& crank, double length, double t,
                  ConstVectorRef q, ConstVectorRef v, ConstVectorRef p, MatrixRef* mass, VectorRef* f,
                  RodWorkspace& w) {
  const View P(layout, p);
  const int n = layout.modes;
  const Matrix& mee = meeOf(P, w);
  Frame<double> fr;
  frameKinematics(crankOf(crank, t, w), crank.radius, length, dot(P, q), f != nullptr ? dot(P, v) : 0.0, fr);
  double jw = P.j0(), sw0 = P.mc(0), sw1 = P.mc(1);
  for (int i = 0; i < n; ++i) {
    jw += 2.0 * P.c2(i) * q(i);
    sw0 += P.c1(0, i) * q(i);
    sw1 += P.c1(1, i) * q(i);
  }
  // Column j of the symmetric M_ee and of Ct against q: h = c2 + M_ee q, A1 = a0 + Ct^T q.
  for (int j = 0; j < n; ++j) {
    double mq = 0.0, a1 = P.a0(j);
    for (int i = 0; i < n; ++i) {
      mq += mee(i, j) * q(i);
      a1 += P.ct(i, j) * q(i);
    }
    w.h(j) = P.c2(j) + mq;
    w.a1(j) = a1;
    jw += q(j) * mq;
  }
  const double g = fr.g;
  if (mass != nullptr) {
    MatrixRef m = *mass;
    for (int i = 0; i < n; ++i) w.gb(i) = g * P.b(i);
    for (int j = 0; j < n; ++j) {
      const double jwGb = jw * w.gb(j);
      for (int i = 0; i < n; ++i) m(i, j) = mee(i, j) + w.gb(i) * (w.a1(j) + jwGb) + w.a1(i) * w.gb(j);
    }
  }
  if (f == nullptr) return;
  // K_ee q and Ct q' column by column (axpy form).
  w.keeQ.setZero();
  w.ctV.setZero();
  for (int j = 0; j < n; ++j) {
    const double qj = q(j), vj = v(j);
    const double* kee = P.p + layout.kee() + n * j;
    const double* ct = P.p + layout.cTilde() + n * j;
    for (int i = 0; i < n; ++i) {
      w.keeQ(i) += kee[i] * qj;
      w.ctV(i) += ct[i] * vj;
    }
  }
  double hv = 0.0;
  for (int j = 0; j < n; ++j) hv += w.h(j) * v(j);
  const double bd = fr.betaDot, bc = fr.betaC;
  const double kappa = jw * bc + (-sw1 * fr.rho0 + sw0 * fr.rho1) + 2.0 * bd * hv;
  const double gKappa = g * kappa, bd2 = bd * bd;
  VectorRef out = *f;
  for (int i = 0; i < n; ++i) {
    out(i) = -(w.keeQ(i) - 2.0 * bd * w.ctV(i) + w.a1(i) * bc + gKappa * P.b(i) + P.c1(0, i) * fr.rho0 +
               P.c1(1, i) * fr.rho1 - bd2 * w.h(i));
  }
}

}  // namespace

void SliderCrankProblem::massMatrix(double t, ConstVectorRef q, ConstVectorRef p, MatrixRef mass,
                                    ProblemWorkspace* ws) const {
  auto& w = workspaceOf(ws);
  massAndForce(layout_, crank_, length_, t, q, w.zero, p, &mass, nullptr, w);
}

void SliderCrankProblem::force(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef p, VectorRef f,
                               ProblemWorkspace* ws) const {
  massAndForce(layout_, crank_, length_, t, q, v, p, nullptr, &f, workspaceOf(ws));
}

void SliderCrankProblem::massMatrixAndForce(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef p,
                                            MatrixRef mass, VectorRef f, ProblemWorkspace* ws) const {
  massAndForce(layout_, crank_, length_, t, q, v, p, &mass, &f, workspaceOf(ws));
}

void SliderCrankProblem::residual(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                                  ConstVectorRef p, VectorRef r, ProblemWorkspace* ws) const {
  auto& w = workspaceOf(ws);
  const View P(layout_, p);
  Frame<double> fr;
  frameKinematics(crankOf(crank_, t, w), crank_.radius, length_, dot(P, q), dot(P, v), fr);
  for (int i = 0; i < layout_.modes; ++i) {
    w.dq[i] = q(i);
    w.dqd[i] = v(i);
  }
  residualCore<double>(P, fr, w.dq.data(), w.dqd.data(), a, dot(P, a), w.dr.data(), w.da1.data(),
                       w.dh.data());
  for (int i = 0; i < layout_.modes; ++i) r(i) = w.dr[i];
}

namespace {

template <int Capacity>
void stateJacobians(const SliderCrankLayout& layout, const CrankState& crank, double radius, double length,
                    ConstVectorRef q, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p, MatrixRef rq,
                    MatrixRef rv, AdBuffers<Capacity>& w) {
  using ADC = ADOf<Capacity>;
  using DC = DerivativesOf<Capacity>;
  const View P(layout, p);
  const int n = layout.modes;
  // Seed q and q' with unit directions 0..n-1 and n..2n-1.
  ADC c(0.0, DC::Zero(2 * n)), cd(0.0, DC::Zero(2 * n));
  for (int i = 0; i < n; ++i) {
    w.q[i] = ADC(q(i), 2 * n, i);
    w.qd[i] = ADC(v(i), 2 * n, n + i);
    c += P.b(i) * w.q[i];
    cd += P.b(i) * w.qd[i];
  }
  Frame<ADC> fr;
  frameKinematics(crank, radius, length, c, cd, fr);
  const ADC ba(dot(P, a), DC::Zero(2 * n));
  residualCore<ADC>(P, fr, w.q.data(), w.qd.data(), a, ba, w.r.data(), w.a1.data(), w.h.data());
  for (int i = 0; i < n; ++i) {
    const DC& d = w.r[i].derivatives();
    for (int j = 0; j < n; ++j) {
      rq(i, j) = d(j);
      rv(i, j) = d(n + j);
    }
  }
}

}  // namespace

void SliderCrankProblem::residualJacobiansByAutoDiff(double t, ConstVectorRef q, ConstVectorRef v,
                                                     ConstVectorRef a, ConstVectorRef p, MatrixRef rq,
                                                     MatrixRef rv, ProblemWorkspace* ws) const {
  auto& w = workspaceOf(ws);
  const CrankState& crank = crankOf(crank_, t, w);
  if (2 * layout_.modes <= kSmallCapacity) {
    stateJacobians<kSmallCapacity>(layout_, crank, crank_.radius, length_, q, v, a, p, rq, rv, w.small);
  } else {
    stateJacobians<kLargeCapacity>(layout_, crank, crank_.radius, length_, q, v, a, p, rq, rv, w.large);
  }
}

namespace {

/// The scalars of mu . r (see the header) and their partials in the channels c = b q, c' = b q' and
/// b a, shared by the state product and the parameter product.
struct ProductScalars {
  double g, bd, bc, r0, r1;       // frame: dbeta/dc, beta', beta_c, rho
  double ba, s, jw, kappa;        // b a, beta_q a + beta_c, J_w, kappa
  double mb, muA1;                // mu . b, mu . A1
  double alongQ, alongV, alongA;  // d(mu . r)/dc, d/dc', d/d(b a) through the channels
};

/// Forward AD in the two channels c, c' (fixed size: no heap, no unused capacity copied).
using AD2 = Eigen::AutoDiffScalar<Eigen::Vector2d>;

/// The residual's scalars that do not depend on mu, with their partials in the channels c = b q (C) and
/// c' = b q' (Cd); also leaves h = c2 + M_ee q in w.h, M_ee q in w.meeQ, A1 = a0 + Ct^T q in w.a1 and
/// Ct q' in w.ctV. Shared by the products with mu and the Jacobians.
struct ChannelScalars {
  double g, gC, bd, bdC, bdCd, bc, r0, r1, r0C, r1C;  // frame: dbeta/dc, beta', beta_c, rho
  double ba, s, sC, sCd;                              // b a, beta_q a + beta_c
  double jw, sw0, sw1, hQd;                           // J_w, s_w, h . q'
  double kappa, kappaC, kappaCd;
};

ChannelScalars channelScalars(const View& P, const Matrix& mee, const CrankState& crank, double radius,
                              double length, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                              RodWorkspace& w) {
  const int n = P.n;
  ChannelScalars k;
  // Frame scalars and their partials in c (direction 0) and c' (direction 1).
  Frame<AD2> fr;
  frameKinematics(crank, radius, length, AD2(dot(P, q), 2, 0), AD2(dot(P, v), 2, 1), fr);
  k.g = fr.g.value();
  k.gC = fr.g.derivatives()(0);
  k.bd = fr.betaDot.value();
  k.bdC = fr.betaDot.derivatives()(0);
  k.bdCd = fr.betaDot.derivatives()(1);
  k.bc = fr.betaC.value();
  const double bcC = fr.betaC.derivatives()(0), bcCd = fr.betaC.derivatives()(1);
  k.r0 = fr.rho0.value();
  k.r1 = fr.rho1.value();
  k.r0C = fr.rho0.derivatives()(0);
  k.r1C = fr.rho1.derivatives()(0);
  k.ba = dot(P, a);
  k.s = k.g * k.ba + k.bc;  // beta_q a + beta_c and partials
  k.sC = k.gC * k.ba + bcC;
  k.sCd = bcCd;

  // The q-dependent quantities of the residual (see the header).
  k.jw = P.j0();
  k.sw0 = P.mc(0);
  k.sw1 = P.mc(1);
  for (int i = 0; i < n; ++i) {
    k.jw += 2.0 * P.c2(i) * q(i);
    k.sw0 += P.c1(0, i) * q(i);
    k.sw1 += P.c1(1, i) * q(i);
  }
  // Ct q' and M_ee q column by column (axpy form, vectorised through __restrict pointers); M_ee q so uses
  // that the symmetric M_ee is symmetric bit for bit, and sums each entry over i = 0..n-1 from 0, as the
  // dot product of column j does.
  {
    const double* __restrict qp = q.data();
    const double* __restrict vp = v.data();
    double* __restrict ctV = w.ctV.data();
    double* __restrict meeQ = w.meeQ.data();
    for (int i = 0; i < n; ++i) ctV[i] = meeQ[i] = 0.0;
    for (int j = 0; j < n; ++j) {
      const double* __restrict ct = P.p + P.layout.cTilde() + n * j;
      const double* __restrict m = mee.data() + static_cast<std::ptrdiff_t>(n) * j;
      const double vj = vp[j], qj = qp[j];
      for (int i = 0; i < n; ++i) {
        ctV[i] += ct[i] * vj;
        meeQ[i] += m[i] * qj;
      }
    }
  }
  double a1a = 0.0;
  k.hQd = 0.0;
  for (int j = 0; j < n; ++j) {
    double a1 = P.a0(j);
    for (int i = 0; i < n; ++i) a1 += P.ct(i, j) * q(i);
    const double mq = w.meeQ(j);
    const double h = P.c2(j) + mq;
    w.h(j) = h;
    w.a1(j) = a1;
    k.jw += q(j) * mq;
    a1a += a1 * a(j);
    k.hQd += h * v(j);
  }
  const double x = -k.sw1 * k.r0 + k.sw0 * k.r1, xC = -k.sw1 * k.r0C + k.sw0 * k.r1C;
  k.kappa = a1a + k.jw * k.s + x + 2.0 * k.bd * k.hQd;
  k.kappaC = k.jw * k.sC + xC + 2.0 * k.bdC * k.hQd;
  k.kappaCd = k.jw * k.sCd + 2.0 * k.bdCd * k.hQd;
  return k;
}

/// The product scalars; also leaves h, M_ee q, A1 and Ct q' in the workspace (channelScalars).
ProductScalars productScalars(const View& P, const Matrix& mee, const CrankState& crank, double radius,
                              double length, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                              ConstVectorRef mu, RodWorkspace& w) {
  const int n = P.n;
  const ChannelScalars k = channelScalars(P, mee, crank, radius, length, q, v, a, w);
  double muA1 = 0.0, muH = 0.0, muCtQd = 0.0, mb = 0.0, c1mu0 = 0.0, c1mu1 = 0.0;
  for (int j = 0; j < n; ++j) {
    muA1 += mu(j) * w.a1(j);
    muH += mu(j) * w.h(j);
    muCtQd += mu(j) * w.ctV(j);
    mb += mu(j) * P.b(j);
    c1mu0 += P.c1(0, j) * mu(j);
    c1mu1 += P.c1(1, j) * mu(j);
  }
  const double g = k.g, bd = k.bd;
  // Coefficients of b (dependence through c and c').
  const double alongQ = muA1 * k.sC + mb * (k.gC * k.kappa + g * k.kappaC) + (c1mu0 * k.r0C + c1mu1 * k.r1C) -
                        2.0 * bd * k.bdC * muH - 2.0 * k.bdC * muCtQd;
  const double alongV = muA1 * k.sCd + mb * g * k.kappaCd - 2.0 * bd * k.bdCd * muH - 2.0 * k.bdCd * muCtQd;
  return ProductScalars{g,    bd,      k.bc, k.r0, k.r1,   k.ba,   k.s,
                        k.jw, k.kappa, mb,   muA1, alongQ, alongV, g * (muA1 + mb * g * k.jw)};
}

/// r_q and r_q' in O(n^2): the transpose of stateProduct() written out for every mu at once,
///   r_q  = K_ee + s Ct^T - beta'^2 M_ee + g b kappa_q^T + u b^T,
///   r_q' = -2 beta' Ct + 2 g beta' b h^T + w b^T,
/// kappa_q = Ct a + s (2 c2 + 2 M_ee q) + C1^T (rho1, -rho0) + 2 beta' M_ee q', and u, w the partials
/// of r through the channels c, c' (the coefficients of b in stateProduct()).
void channelJacobians(const View& P, const Matrix& mee, const CrankState& crank, double radius, double length,
                      ConstVectorRef q, ConstVectorRef v, ConstVectorRef a, MatrixRef rq, MatrixRef rv,
                      RodWorkspace& w) {
  const int n = P.n;
  const ChannelScalars k = channelScalars(P, mee, crank, radius, length, q, v, a, w);
  const double g = k.g, bd = k.bd, s = k.s;
  // Ct a column by column (axpy form).
  w.ctA.setZero();
  for (int j = 0; j < n; ++j) {
    const double* ct = P.p + P.layout.cTilde() + n * j;
    for (int i = 0; i < n; ++i) w.ctA(i) += ct[i] * a(j);
  }
  const double alongB = k.gC * k.kappa + g * k.kappaC;
  for (int i = 0; i < n; ++i) {
    double meeQd = 0.0;
    for (int j = 0; j < n; ++j) meeQd += mee(j, i) * v(j);
    const double jwQ = 2.0 * P.c2(i) + 2.0 * w.meeQ(i);  // M_ee is used symmetric
    const double xQ = P.c1(0, i) * k.r1 - P.c1(1, i) * k.r0;
    w.eta(i) = g * (w.ctA(i) + s * jwQ + xQ + 2.0 * bd * meeQd);  // g kappa_q
    w.alpha(i) = w.a1(i) * k.sC + P.b(i) * alongB + (P.c1(0, i) * k.r0C + P.c1(1, i) * k.r1C) -
                 2.0 * bd * k.bdC * w.h(i) - 2.0 * k.bdC * w.ctV(i);  // u
    w.gb(i) =
        w.a1(i) * k.sCd + P.b(i) * g * k.kappaCd - 2.0 * bd * k.bdCd * w.h(i) - 2.0 * k.bdCd * w.ctV(i);  // w
  }
  const double bd2 = bd * bd, twoGbd = 2.0 * g * bd;
  for (int i = 0; i < n; ++i) {
    const double* kee = P.p + P.layout.kee() + n * i;
    const double* ct = P.p + P.layout.cTilde() + n * i;
    const double bi = P.b(i), etaI = w.eta(i), hI = twoGbd * w.h(i);
    for (int r = 0; r < n; ++r) {
      const double br = P.b(r);
      rq(r, i) = kee[r] + s * P.ct(i, r) - bd2 * mee(r, i) + br * etaI + w.alpha(r) * bi;
      rv(r, i) = -2.0 * bd * ct[r] + br * hI + w.gb(r) * bi;
    }
  }
}

/// out += (r_p)^T mu from the product scalars (h, A1 in the workspace).
///
/// The loops read q, v, a, mu and the workspace through __restrict pointers and write each block of `out`
/// in a loop of its own: the outputs overlap no input, and so the compiler vectorises the rank-one updates.
/// Every entry is the same expression evaluated in the same order as an entry-by-entry loop, so the bits
/// are those of one.
void parameterProduct(const SliderCrankLayout& L, const ProductScalars& k, ConstVectorRef qIn,
                      ConstVectorRef vIn, ConstVectorRef aIn, ConstVectorRef muIn, VectorRef out,
                      RodWorkspace& w) {
  const int n = L.modes;
  const double* __restrict q = qIn.data();
  const double* __restrict v = vIn.data();
  const double* __restrict a = aIn.data();
  const double* __restrict mu = muIn.data();
  double* __restrict etaOf = w.eta.data();
  double* __restrict alphaOf = w.alpha.data();
  const double gKappa = k.g * k.kappa;
  // Terms linear in the invariants (see the header for r and kappa).
  const double g = k.g, betaDot = k.bd, betaC = k.bc, rho0 = k.r0, rho1 = k.r1;
  const double betaA = g * k.ba;
  const double gmb = g * k.mb;
  const double zeta = gmb * (betaA + betaC);               // dF/dJ_w
  const double sigma0 = gmb * rho1, sigma1 = -gmb * rho0;  // dF/ds_w
  out(L.polarMoment()) += zeta;
  out(L.massMoment()) += sigma0;
  out(L.massMoment() + 1) += sigma1;
  for (int j = 0; j < n; ++j) {
    etaOf[j] = -betaDot * betaDot * mu[j] + 2.0 * gmb * betaDot * v[j];  // dF/dh_j
    alphaOf[j] = mu[j] * (betaA + betaC) + gmb * a[j];                   // dF/dA1_j
  }
  for (int j = 0; j < n; ++j) {
    const double qj = q[j], aj = a[j], muj = mu[j];
    out(L.c2() + j) += etaOf[j] + 2.0 * zeta * qj;
    out(L.a0() + j) += alphaOf[j];
    out(L.c1() + 2 * j) += sigma0 * qj + rho0 * muj;
    out(L.c1() + 1 + 2 * j) += sigma1 * qj + rho1 * muj;
    // b: through the channels and the explicit g kappa b term.
    out(L.b() + j) += k.alongQ * qj + k.alongV * v[j] + k.alongA * aj + gKappa * muj;
  }
  double* __restrict ct = out.data() + L.cTilde();
  for (int j = 0; j < n; ++j) {
    const double alpha = alphaOf[j], vj2 = -2.0 * betaDot * v[j];
    double* __restrict column = ct + n * j;
    for (int i = 0; i < n; ++i) column[i] += q[i] * alpha + mu[i] * vj2;
  }
  // M_ee enters through its symmetric part (View::mee), so its gradient is the symmetric part of
  // mu a^T + eta q^T, plus zeta q q^T (symmetric already).
  double* __restrict mee = out.data() + L.mee();
  for (int j = 0; j < n; ++j) {
    const double eta = etaOf[j], qj = q[j], aj = a[j], muj = mu[j], zq = zeta * qj;
    double* __restrict column = mee + n * j;
    for (int i = 0; i < n; ++i)
      column[i] += 0.5 * (mu[i] * aj + etaOf[i] * qj + muj * a[i] + eta * q[i]) + zq * q[i];
  }
  double* __restrict kee = out.data() + L.kee();
  for (int j = 0; j < n; ++j) {
    const double qj = q[j];
    double* __restrict column = kee + n * j;
    for (int i = 0; i < n; ++i) column[i] += mu[i] * qj;
  }
}

/// outQ = (r_q)^T mu, outV = (r_q')^T mu from the product scalars (h, M_ee q in the workspace).
///
/// Ct mu, Ct a, M_ee mu and M_ee q' column by column (axpy form, through __restrict pointers, so the compiler
/// vectorises them); K_ee^T mu and Ct^T mu as dot products. Each entry is summed over j = 0..n-1 from 0 in
/// either form, so the bits are those of dot products. M_ee mu by columns uses that the symmetric part of
/// M_ee (symmetricMee: 0.5 (p_ij + p_ji)) is symmetric bit for bit.
void stateProduct(const View& P, const Matrix& mee, const ProductScalars& k, ConstVectorRef vIn,
                  ConstVectorRef aIn, ConstVectorRef muIn, VectorRef outQ, VectorRef outV, RodWorkspace& w) {
  const int n = P.n;
  const double g = k.g, bd = k.bd, r0 = k.r0, r1 = k.r1, s = k.s, alongQ = k.alongQ, alongV = k.alongV;
  const double gmb = g * k.mb;
  const double* __restrict v = vIn.data();
  const double* __restrict a = aIn.data();
  const double* __restrict mu = muIn.data();
  double* __restrict ctMu = w.ctMu.data();
  double* __restrict ctA = w.ctA.data();
  double* __restrict meeMu = w.meeMu.data();
  double* __restrict meeV = w.meeV.data();
  for (int i = 0; i < n; ++i) ctMu[i] = ctA[i] = meeMu[i] = meeV[i] = 0.0;
  for (int j = 0; j < n; ++j) {
    const double* __restrict ct = P.p + P.layout.cTilde() + n * j;
    const double* __restrict m = mee.data() + static_cast<std::ptrdiff_t>(n) * j;
    const double muj = mu[j], aj = a[j], vj = v[j];
    for (int i = 0; i < n; ++i) {
      ctMu[i] += ct[i] * muj;
      ctA[i] += ct[i] * aj;
      meeMu[i] += m[i] * muj;
      meeV[i] += m[i] * vj;
    }
  }
  for (int i = 0; i < n; ++i) {
    // Column i of K_ee and Ct (for K_ee^T mu and Ct^T mu).
    const double* __restrict kee = P.p + P.layout.kee() + n * i;
    const double* __restrict ct = P.p + P.layout.cTilde() + n * i;
    double keeMu = 0.0, ctTMu = 0.0;
    for (int j = 0; j < n; ++j) {
      keeMu += kee[j] * mu[j];
      ctTMu += ct[j] * mu[j];
    }
    const double jwQ = 2.0 * P.c2(i) + 2.0 * w.meeQ(i);  // M_ee is used symmetric
    const double xQ = P.c1(0, i) * r1 - P.c1(1, i) * r0;
    const double kappaQ = ctA[i] + s * jwQ + xQ + 2.0 * bd * meeV[i];
    outQ(i) = keeMu + s * ctMu[i] + gmb * kappaQ - bd * bd * meeMu[i] + P.b(i) * alongQ;
    outV(i) = gmb * 2.0 * bd * w.h(i) - 2.0 * bd * ctTMu + P.b(i) * alongV;
  }
}

// The residual's products with mu from one evaluation of the frame scalars, which both need: the state's
// into *outQ, *outV and the parameters' added to *gradient, each when given (residualStateVjp,
// addResidualParameterVjp and the fused residualVjps).
void residualProducts(const SliderCrankLayout& layout, const CrankMotion& crank, double length, double t,
                      ConstVectorRef q, ConstVectorRef v, ConstVectorRef a, ConstVectorRef p,
                      ConstVectorRef mu, VectorRef* outQ, VectorRef* outV, VectorRef* gradient,
                      RodWorkspace& w) {
  const View P(layout, p);
  const Matrix& mee = meeOf(P, w);
  // F = mu . r depends on b nonlinearly only through the channels c = b q, c' = b q' and b a; their
  // partials and the frame scalars are the state product's too.
  const ProductScalars k = productScalars(P, mee, crankOf(crank, t, w), crank.radius, length, q, v, a, mu, w);
  if (outQ != nullptr) stateProduct(P, mee, k, v, a, mu, *outQ, *outV, w);
  if (gradient != nullptr) parameterProduct(layout, k, q, v, a, mu, *gradient, w);
}

}  // namespace

void SliderCrankProblem::addResidualParameterVjp(double t, ConstVectorRef q, ConstVectorRef v,
                                                 ConstVectorRef a, ConstVectorRef p, ConstVectorRef mu,
                                                 VectorRef out, ProblemWorkspace* ws) const {
  residualProducts(layout_, crank_, length_, t, q, v, a, p, mu, nullptr, nullptr, &out, workspaceOf(ws));
}

void SliderCrankProblem::residualStateVjp(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                                          ConstVectorRef p, ConstVectorRef mu, VectorRef outQ, VectorRef outV,
                                          ProblemWorkspace* ws) const {
  residualProducts(layout_, crank_, length_, t, q, v, a, p, mu, &outQ, &outV, nullptr, workspaceOf(ws));
}

void SliderCrankProblem::residualVjps(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                                      ConstVectorRef p, ConstVectorRef mu, VectorRef outQ, VectorRef outV,
                                      VectorRef gradient, ProblemWorkspace* ws) const {
  residualProducts(layout_, crank_, length_, t, q, v, a, p, mu, &outQ, &outV, &gradient, workspaceOf(ws));
}

void SliderCrankProblem::residualJacobians(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                                           ConstVectorRef p, MatrixRef rq, MatrixRef rv,
                                           ProblemWorkspace* ws) const {
  auto& w = workspaceOf(ws);
  const View P(layout_, p);
  channelJacobians(P, meeOf(P, w), crankOf(crank_, t, w), crank_.radius, length_, q, v, a, rq, rv, w);
}

double SliderCrankProblem::integrand(double, ConstVectorRef q, ConstVectorRef, ConstVectorRef p,
                                     ProblemWorkspace*) const {
  const View P(layout_, p);
  double s = 0.0;
  for (int i = 0; i < layout_.modes; ++i) {
    for (int j = 0; j < layout_.modes; ++j) s += q(i) * P.kee(i, j) * q(j);
  }
  return s;
}

void SliderCrankProblem::addIntegrandStateGradient(double, ConstVectorRef q, ConstVectorRef, ConstVectorRef p,
                                                   double scale, VectorRef gq, VectorRef,
                                                   ProblemWorkspace*) const {
  const View P(layout_, p);
  // Entry i summed in a register over j = 0..n-1 from gq(i): the order of a sum into gq(i) itself.
  for (int i = 0; i < layout_.modes; ++i) {
    double sum = gq(i);
    for (int j = 0; j < layout_.modes; ++j) sum += scale * (P.kee(i, j) + P.kee(j, i)) * q(j);
    gq(i) = sum;
  }
}

void SliderCrankProblem::addIntegrandParameterGradient(double, ConstVectorRef q, ConstVectorRef,
                                                       ConstVectorRef, double scale, VectorRef gp,
                                                       ProblemWorkspace*) const {
  const int n = layout_.modes;
  // Through __restrict pointers (gp does not overlap q), so the compiler vectorises the columns.
  const double* __restrict qp = q.data();
  for (int j = 0; j < n; ++j) {
    double* __restrict column = gp.data() + layout_.kee() + static_cast<std::ptrdiff_t>(n) * j;
    const double qj = qp[j];
    for (int i = 0; i < n; ++i) column[i] += scale * qp[i] * qj;
  }
}

}  // namespace hindsight::rod
