#include <hindsight/problems/rod/slider_crank.h>

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

/// The frame angle's kinematics from the closure r sin(phi) + (L + c) sin(beta) = 0, c = b q:
/// beta = asin(u), u = -r sin(phi) / (L + c). g = dbeta/dc, betaDot = beta_t + g c',
/// betaC = beta'' - g c'' (the part without q''), rho = R(beta)^T r_A''.
template <typename T>
struct Frame {
  T beta, g, betaDot, betaC, rho0, rho1;
};

template <typename T>
void frameKinematics(const CrankMotion& crank, double length, double t, const T& c, const T& cDot,
                     Frame<T>& out) {
  using std::sqrt;
  double phi, phiDot, phiDdot;
  crank.at(t, phi, phiDot, phiDdot);
  const double r = crank.radius, s = dmath::sin(phi), co = dmath::cos(phi);
  const T d = length + c;
  const T u = -r * s / d;
  const T w1 = 1.0 / sqrt(1.0 - u * u);  // asin'
  const T w2 = u * w1 * w1 * w1;         // asin''
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
  out.beta = dmath::asin(u);
  out.betaDot = bt + out.g * cDot;
  out.betaC = btt + 2.0 * btc * cDot + bcc * cDot * cDot;
  // r_A'' = r phi'' (-sin, cos) - r phi'^2 (cos, sin), expressed in the body frame.
  const double ax = -r * phiDdot * s - r * phiDot * phiDot * co;
  const double ay = r * phiDdot * co - r * phiDot * phiDot * s;
  const T cb = dmath::cos(out.beta), sb = dmath::sin(out.beta);
  out.rho0 = cb * ax + sb * ay;
  out.rho1 = -sb * ax + cb * ay;
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
      : small(n), large(n), dq(n), dqd(n), dr(n), da1(n), dh(n), zero(Vector::Zero(n)) {}
  AdBuffers<kSmallCapacity> small;  // Jacobians up to 12 modes; the parameter product (3 directions)
  AdBuffers<kLargeCapacity> large;  // Jacobians beyond 12 modes
  std::vector<double> dq, dqd, dr, da1, dh;
  Vector zero;
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

}  // namespace

void CrankMotion::at(double t, double& phi, double& phiDot, double& phiDdot) const {
  if (t < rampTime) {
    const double tau = t / rampTime;
    const double twoPi = 2.0 * M_PI;
    double sine, cosine;
    dmath::sincos(twoPi * tau, &sine, &cosine);
    phiDot = omega * (tau - sine / twoPi);
    phiDdot = omega / rampTime * (1.0 - cosine);
    phi = omega * rampTime * (tau * tau / 2.0 + (cosine - 1.0) / (twoPi * twoPi));
  } else {
    phiDot = omega;
    phiDdot = 0.0;
    phi = omega * rampTime / 2.0 + omega * (t - rampTime);
  }
}

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

void SliderCrankProblem::initialCoordinates(ConstVectorRef, VectorRef y0, VectorRef v0) const {
  y0.setZero();
  v0.setZero();
}

double SliderCrankProblem::frameAngle(double t, ConstVectorRef q, ConstVectorRef p) const {
  const View P(layout_, p);
  Frame<double> fr;
  frameKinematics(crank_, length_, t, dot(P, q), 0.0, fr);
  return fr.beta;
}

void SliderCrankProblem::massMatrix(double t, ConstVectorRef q, ConstVectorRef p, MatrixRef mass,
                                    ProblemWorkspace*) const {
  const View P(layout_, p);
  const int n = layout_.modes;
  Frame<double> fr;
  frameKinematics(crank_, length_, t, dot(P, q), 0.0, fr);
  double jw = P.j0();
  for (int i = 0; i < n; ++i) {
    jw += 2.0 * P.c2(i) * q(i);
    for (int j = 0; j < n; ++j) jw += q(i) * P.mee(i, j) * q(j);
  }
  const double g = fr.g;
  // A1 = a0 + q^T Ct once; M = M_ee + A1^T beta_q + beta_q^T A1 + J_w beta_q^T beta_q, beta_q = g b.
  std::array<double, kMaxModes> a1;
  for (int j = 0; j < n; ++j) {
    a1[j] = P.a0(j);
    for (int i = 0; i < n; ++i) a1[j] += q(i) * P.ct(i, j);
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      // Same operation order as before the refactoring, so the bits are unchanged.
      mass(i, j) = (P.mee(i, j) + jw * g * g * P.b(i) * P.b(j) + g * P.b(i) * a1[j]) + a1[i] * g * P.b(j);
    }
  }
}

void SliderCrankProblem::residual(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                                  ConstVectorRef p, VectorRef r, ProblemWorkspace* ws) const {
  auto& w = workspaceOf(ws);
  const View P(layout_, p);
  Frame<double> fr;
  frameKinematics(crank_, length_, t, dot(P, q), dot(P, v), fr);
  for (int i = 0; i < layout_.modes; ++i) {
    w.dq[i] = q(i);
    w.dqd[i] = v(i);
  }
  residualCore<double>(P, fr, w.dq.data(), w.dqd.data(), a, dot(P, a), w.dr.data(), w.da1.data(),
                       w.dh.data());
  for (int i = 0; i < layout_.modes; ++i) r(i) = w.dr[i];
}

void SliderCrankProblem::force(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef p, VectorRef f,
                               ProblemWorkspace* ws) const {
  residual(t, q, v, workspaceOf(ws).zero, p, f, ws);
  f = -f;
}

namespace {

template <int Capacity>
void stateJacobians(const SliderCrankLayout& layout, const CrankMotion& crank, double length, double t,
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
  frameKinematics(crank, length, t, c, cd, fr);
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

void SliderCrankProblem::residualJacobians(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                                           ConstVectorRef p, MatrixRef rq, MatrixRef rv,
                                           ProblemWorkspace* ws) const {
  auto& w = workspaceOf(ws);
  if (2 * layout_.modes <= kSmallCapacity) {
    stateJacobians<kSmallCapacity>(layout_, crank_, length_, t, q, v, a, p, rq, rv, w.small);
  } else {
    stateJacobians<kLargeCapacity>(layout_, crank_, length_, t, q, v, a, p, rq, rv, w.large);
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

ProductScalars productScalars(const View& P, const CrankMotion& crank_, double length_, double t,
                              ConstVectorRef q, ConstVectorRef v, ConstVectorRef a, ConstVectorRef mu) {
  const int n = P.n;
  using ADS = ADOf<kSmallCapacity>;
  // Frame scalars and their partials in c (direction 0) and c' (direction 1).
  Frame<ADS> fr;
  frameKinematics(crank_, length_, t, ADS(dot(P, q), 2, 0), ADS(dot(P, v), 2, 1), fr);
  const double g = fr.g.value(), gC = fr.g.derivatives()(0);
  const double bd = fr.betaDot.value(), bdC = fr.betaDot.derivatives()(0), bdCd = fr.betaDot.derivatives()(1);
  const double bc = fr.betaC.value(), bcC = fr.betaC.derivatives()(0), bcCd = fr.betaC.derivatives()(1);
  const double r0 = fr.rho0.value(), r1 = fr.rho1.value();
  const double r0C = fr.rho0.derivatives()(0), r1C = fr.rho1.derivatives()(0);
  const double ba = dot(P, a);
  const double s = g * ba + bc, sC = gC * ba + bcC, sCd = bcCd;  // beta_q a + beta_c and partials

  // The q-dependent quantities of the residual (see the header).
  double jw = P.j0(), sw0 = P.mc(0), sw1 = P.mc(1);
  for (int i = 0; i < n; ++i) {
    jw += 2.0 * P.c2(i) * q(i);
    sw0 += P.c1(0, i) * q(i);
    sw1 += P.c1(1, i) * q(i);
  }
  double a1a = 0.0, muA1 = 0.0, hQd = 0.0, muH = 0.0, muCtQd = 0.0, mb = 0.0, c1mu0 = 0.0, c1mu1 = 0.0;
  for (int j = 0; j < n; ++j) {
    double a1 = P.a0(j), h = P.c2(j), ctQd = 0.0;
    for (int i = 0; i < n; ++i) {
      a1 += q(i) * P.ct(i, j);
      h += P.mee(j, i) * q(i);
      ctQd += P.ct(j, i) * v(i);
    }
    jw += q(j) * (h - P.c2(j));
    a1a += a1 * a(j);
    muA1 += mu(j) * a1;
    hQd += h * v(j);
    muH += mu(j) * h;
    muCtQd += mu(j) * ctQd;
    mb += mu(j) * P.b(j);
    c1mu0 += P.c1(0, j) * mu(j);
    c1mu1 += P.c1(1, j) * mu(j);
  }
  const double x = -sw1 * r0 + sw0 * r1, xC = -sw1 * r0C + sw0 * r1C;
  const double kappa = a1a + jw * s + x + 2.0 * bd * hQd;
  const double kappaC = jw * sC + xC + 2.0 * bdC * hQd;
  const double kappaCd = jw * sCd + 2.0 * bdCd * hQd;

  // Coefficients of b (dependence through c and c').
  const double alongQ = muA1 * sC + mb * (gC * kappa + g * kappaC) + (c1mu0 * r0C + c1mu1 * r1C) -
                        2.0 * bd * bdC * muH - 2.0 * bdC * muCtQd;
  const double alongV = muA1 * sCd + mb * g * kappaCd - 2.0 * bd * bdCd * muH - 2.0 * bdCd * muCtQd;
  return ProductScalars{g,  bd,    bc, r0,   r1,     ba,     s,
                        jw, kappa, mb, muA1, alongQ, alongV, g * (muA1 + mb * g * jw)};
}

}  // namespace

void SliderCrankProblem::addResidualParameterVjp(double t, ConstVectorRef q, ConstVectorRef v,
                                                 ConstVectorRef a, ConstVectorRef p, ConstVectorRef mu,
                                                 VectorRef out, ProblemWorkspace*) const {
  const View P(layout_, p);
  const SliderCrankLayout& L = layout_;
  const int n = L.modes;
  // F = mu . r depends on b nonlinearly only through the channels c = b q, c' = b q' and b a; their
  // partials and the frame scalars come from the same helper as the state product.
  const ProductScalars k = productScalars(P, crank_, length_, t, q, v, a, mu);
  const double channels[3] = {k.alongQ, k.alongV, k.alongA};
  const double gKappa = k.g * k.kappa;

  // Terms linear in the invariants (see the header for r and kappa).
  const double g = k.g, betaDot = k.bd, betaC = k.bc, rho0 = k.r0, rho1 = k.r1;
  const double betaA = g * k.ba;
  const double mb = k.mb;
  const double zeta = g * mb * (betaA + betaC);                  // dF/dJ_w
  const double sigma0 = g * mb * rho1, sigma1 = -g * mb * rho0;  // dF/ds_w
  out(L.polarMoment()) += zeta;
  out(L.massMoment()) += sigma0;
  out(L.massMoment() + 1) += sigma1;
  for (int j = 0; j < n; ++j) {
    const double eta = -betaDot * betaDot * mu(j) + 2.0 * g * mb * betaDot * v(j);  // dF/dh_j
    const double alpha = mu(j) * (betaA + betaC) + g * mb * a(j);                   // dF/dA1_j
    out(L.c2() + j) += eta + 2.0 * zeta * q(j);
    out(L.a0() + j) += alpha;
    out(L.c1() + 2 * j) += sigma0 * q(j) + rho0 * mu(j);
    out(L.c1() + 1 + 2 * j) += sigma1 * q(j) + rho1 * mu(j);
    for (int i = 0; i < n; ++i) {
      const double etaI = -betaDot * betaDot * mu(i) + 2.0 * g * mb * betaDot * v(i);
      out(L.cTilde() + i + n * j) += q(i) * alpha - 2.0 * betaDot * mu(i) * v(j);
      const double etaJ = -betaDot * betaDot * mu(j) + 2.0 * g * mb * betaDot * v(j);
      out(L.mee() + i + n * j) +=
          0.5 * (mu(i) * a(j) + etaI * q(j) + mu(j) * a(i) + etaJ * q(i)) + zeta * q(i) * q(j);
      out(L.kee() + i + n * j) += mu(i) * q(j);
    }
    // b: through the channels and the explicit g kappa b term.
    out(L.b() + j) += channels[0] * q(j) + channels[1] * v(j) + channels[2] * a(j) + gKappa * mu(j);
  }
}

void SliderCrankProblem::residualStateVjp(double t, ConstVectorRef q, ConstVectorRef v, ConstVectorRef a,
                                          ConstVectorRef p, ConstVectorRef mu, VectorRef outQ, VectorRef outV,
                                          ProblemWorkspace*) const {
  const View P(layout_, p);
  const int n = layout_.modes;
  const ProductScalars k = productScalars(P, crank_, length_, t, q, v, a, mu);
  const double g = k.g, bd = k.bd, r0 = k.r0, r1 = k.r1, s = k.s, alongQ = k.alongQ, alongV = k.alongV;
  const double mb = k.mb;
  const double gmb = g * mb;
  for (int i = 0; i < n; ++i) {
    double keeMu = 0.0, ctMu = 0.0, ctA = 0.0, meeMu = 0.0, meeQ = 0.0, meeQd = 0.0, ctTMu = 0.0;
    for (int j = 0; j < n; ++j) {
      keeMu += P.kee(j, i) * mu(j);
      ctMu += P.ct(i, j) * mu(j);
      ctA += P.ct(i, j) * a(j);
      meeMu += P.mee(i, j) * mu(j);
      meeQ += P.mee(i, j) * q(j);
      meeQd += P.mee(i, j) * v(j);
      ctTMu += P.ct(j, i) * mu(j);
    }
    const double jwQ = 2.0 * P.c2(i) + 2.0 * meeQ;  // M_ee is used symmetric
    const double xQ = P.c1(0, i) * r1 - P.c1(1, i) * r0;
    const double kappaQ = ctA + s * jwQ + xQ + 2.0 * bd * meeQd;
    outQ(i) = keeMu + s * ctMu + gmb * kappaQ - bd * bd * meeMu + P.b(i) * alongQ;
    const double hI = P.c2(i) + meeQ;
    outV(i) = gmb * 2.0 * bd * hI - 2.0 * bd * ctTMu + P.b(i) * alongV;
  }
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
  for (int i = 0; i < layout_.modes; ++i) {
    for (int j = 0; j < layout_.modes; ++j) gq(i) += scale * (P.kee(i, j) + P.kee(j, i)) * q(j);
  }
}

void SliderCrankProblem::addIntegrandParameterGradient(double, ConstVectorRef q, ConstVectorRef,
                                                       ConstVectorRef, double scale, VectorRef gp,
                                                       ProblemWorkspace*) const {
  const int n = layout_.modes;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) gp(layout_.kee() + i + n * j) += scale * q(i) * q(j);
  }
}

}  // namespace hindsight::rod
