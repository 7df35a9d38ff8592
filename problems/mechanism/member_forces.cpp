// The flexible member's floating-frame-of-reference terms (docs/design.md §3, §10, §11): the mass matrix
// and quadratic-velocity (centrifugal, Coriolis) terms of the member written with its invariants, the rigid
// bodies, gravity and the springs, as M(z) z'' - Q in full coordinates (the tests' reference) and on the
// chord system with the member's frame rows through nine moments (the production path), and the products
// of q, q', a with the invariant matrices kept for the point last evaluated. The member is only its
// invariants here (detail/member_invariants.h): a plate and a solid take the same code.
#include <hindsight/problems/mechanism/detail/kinematics.h>
#include <hindsight/problems/mechanism/detail/member_forces.h>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace hindsight::mechanism::detail {

namespace {

// Springs and dampers: tension k (l - l0) + d l' pulls point1 towards point2; their generalised forces are
// added to `out`. One code for the full-coordinate reference and the chord path (both after kinematics).
template <typename T>
void addSpringForces(const System& I, Buffers<T>& B, T* out, const T& zero) {
  T cc, ccd;
  I.chord(B, true, cc, ccd, zero);
  Pt<T> a, b;
  for (const SpringRef& sp : I.springs) {
    I.point(sp.p1, B, true, cc, ccd, zero, a);
    I.point(sp.p2, B, true, cc, ccd, zero, b);
    const T d0 = b.P[0] - a.P[0], d1 = b.P[1] - a.P[1];
    using std::sqrt;
    const T l = sqrt(d0 * d0 + d1 * d1);
    if (!(valueOf(l) > 0.0))
      throw NumericalError("a spring's two points coincide (its direction is undefined)", 0.0);
    const T e0 = d0 / l, e1 = d1 / l;
    const T ld = e0 * (b.Pd[0] - a.Pd[0]) + e1 * (b.Pd[1] - a.Pd[1]);
    const T tension = sp.stiffness * (l - sp.restLength) + sp.damping * ld;
    const T f0 = tension * e0, f1 = tension * e1;
    I.addJT(sp.p1, a, f0, f1, -1.0, B, out, 1);
    I.addJT(sp.p2, b, f0, f1, 1.0, B, out, 1);
  }
}

/// Whether x[0, n) has the bits kept in key (kept: a workspace made for a fixed p).
bool keptBits(const double* x, const Vector& key, bool kept) {
  return kept && std::memcmp(x, key.data(), sizeof(double) * key.size()) == 0;
}

/// The chord system's generalised force out = M z'' - Q (x = z'') on the rigid coordinates and c: the
/// rigid bodies, gravity, the springs, and the member's frame rows written with its moments (the same
/// terms as generalizedForce()); the modal rows are modalRow()'s. phi = (rho0, rho1, beta'', beta'), the
/// frame scalars the modal rows depend on.
template <typename T>
void chordForce(const System& C, const View& P, Buffers<T>& B, const T* x, const T* mom, T* out, T* phi,
                const T& zero) {
  const Vec2 g = C.gravity;
  for (int k = 0; k < C.nr; ++k) {
    out[3 * k] = C.mass[k] * (x[3 * k] - g(0));
    out[3 * k + 1] = C.mass[k] * (x[3 * k + 1] - g(1));
    out[3 * k + 2] = C.inertia[k] * x[3 * k + 2];
  }
  const int o = C.base;
  const T* zd = B.zd.data() + o;
  const T* xm = x + o;
  const T& s = B.sn[C.nr];
  const T& c = B.cs[C.nr];
  const T gx0 = xm[0] - g(0), gx1 = xm[1] - g(1);
  const T rho0 = c * gx0 + s * gx1, rho1 = -s * gx0 + c * gx1;
  const T& thdd = xm[2];
  const T& thd = zd[2];
  const T thd2 = thd * thd;
  const T aR0 = P.mass() * rho0 - mom[kSw1] * thdd + mom[kC1a0] - mom[kSw0] * thd2 - 2.0 * thd * mom[kC1v1];
  const T aR1 = P.mass() * rho1 + mom[kSw0] * thdd + mom[kC1a1] - mom[kSw1] * thd2 + 2.0 * thd * mom[kC1v0];
  out[o] = c * aR0 - s * aR1;
  out[o + 1] = s * aR0 + c * aR1;
  out[o + 2] = -mom[kSw1] * rho0 + mom[kSw0] * rho1 + mom[kJw] * thdd + mom[kA1a] + 2.0 * thd * mom[kHv];
  out[o + 3] = zero;
  phi[0] = rho0;
  phi[1] = rho1;
  phi[2] = thdd;
  phi[3] = thd;
  addSpringForces(C, B, out, zero);
}

}  // namespace

template <typename T>
void generalizedForce(const System& I, const View& P, Buffers<T>& B, const T* x, bool rest, T* out,
                      const T& zero) {
  const int n = I.n;
  const Vec2 g = rest ? I.gravity : Vec2::Zero();
  for (int k = 0; k < I.nr; ++k) {
    out[3 * k] = I.mass[k] * (x[3 * k] - g(0));
    out[3 * k + 1] = I.mass[k] * (x[3 * k + 1] - g(1));
    out[3 * k + 2] = I.inertia[k] * x[3 * k + 2];
  }
  // The member (docs/design.md §3 in the frame of its own rigid coordinates).
  const int o = I.base;
  const T* z = B.z.data() + o;
  const T* zd = B.zd.data() + o;
  const T* xm = x + o;
  T* F = out + o;
  const T& s = B.sn[I.nr];
  const T& c = B.cs[I.nr];
  T sw0 = zero + P.mc(0), sw1 = zero + P.mc(1), jw = zero + P.j0();
  for (int i = 0; i < n; ++i) {
    sw0 += P.c1(0, i) * z[3 + i];
    sw1 += P.c1(1, i) * z[3 + i];
    jw += 2.0 * P.c2(i) * z[3 + i];
  }
  for (int j = 0; j < n; ++j) {
    T mq = zero, a1 = zero + P.a0(j);
    for (int i = 0; i < n; ++i) {
      mq += P.meeRotation(j, i) * z[3 + i];
      a1 += z[3 + i] * P.ct(i, j);
    }
    B.mq[j] = mq;
    B.h[j] = P.c2(j) + mq;
    B.a1[j] = a1;
    jw += z[3 + j] * mq;
  }
  // rho = A^T (R'' - g) (the gravity acts like a frame acceleration).
  const T gx0 = xm[0] - g(0), gx1 = xm[1] - g(1);
  const T rho0 = c * gx0 + s * gx1, rho1 = -s * gx0 + c * gx1;
  const T& thdd = xm[2];
  T cq0 = zero, cq1 = zero;
  for (int i = 0; i < n; ++i) {
    cq0 += P.c1(0, i) * xm[3 + i];
    cq1 += P.c1(1, i) * xm[3 + i];
  }
  // Body-frame force on the frame origin: m rho + S s_w theta'' + C1 q'' - s_w theta'^2 + 2 theta' S C1 q'.
  T aR0 = P.mass() * rho0 - sw1 * thdd + cq0;
  T aR1 = P.mass() * rho1 + sw0 * thdd + cq1;
  T ftheta = -sw1 * rho0 + sw0 * rho1 + jw * thdd;
  for (int j = 0; j < n; ++j) ftheta += B.a1[j] * xm[3 + j];
  const T& thd = zd[2];
  if (rest) {
    T cqd0 = zero, cqd1 = zero, hqd = zero;
    for (int i = 0; i < n; ++i) {
      cqd0 += P.c1(0, i) * zd[3 + i];
      cqd1 += P.c1(1, i) * zd[3 + i];
      hqd += B.h[i] * zd[3 + i];
    }
    const T thd2 = thd * thd;
    aR0 += -sw0 * thd2 - 2.0 * thd * cqd1;
    aR1 += -sw1 * thd2 + 2.0 * thd * cqd0;
    ftheta += 2.0 * thd * hqd;
  }
  F[0] = c * aR0 - s * aR1;
  F[1] = s * aR0 + c * aR1;
  F[2] = ftheta;
  for (int i = 0; i < n; ++i) {
    T fi = P.c1(0, i) * rho0 + P.c1(1, i) * rho1 + B.a1[i] * thdd;
    T mx = zero;
    for (int j = 0; j < n; ++j) mx += P.mee(i, j) * xm[3 + j];
    fi += mx;
    if (rest) {
      T ctqd = zero, keeq = zero;
      for (int j = 0; j < n; ++j) {
        ctqd += P.ct(i, j) * zd[3 + j];
        keeq += P.kee(i, j) * z[3 + j];
      }
      fi += keeq - 2.0 * thd * ctqd - B.h[i] * (thd * thd);
    }
    F[3 + i] = fi;
  }
  if (!rest) return;
  addSpringForces(I, B, out, zero);
}

template <typename T>
void residualFromKinematics(const System& I, const View& P, Buffers<T>& B, ConstVectorRef a, int nd) {
  const T zero = Make<T>::constant(0.0, nd);
  for (int i = 0; i < I.nz; ++i) {
    T s = B.zeta[i];
    for (int j = 0; j < I.f; ++j) s += B.R[i + I.nz * j] * a(j);
    B.zdd[i] = s;
  }
  generalizedForce(I, P, B, B.zdd.data(), true, B.F.data(), zero);
  for (int j = 0; j < I.f; ++j) {
    T s = zero;
    for (int i = 0; i < I.nz; ++i) s += B.R[i + I.nz * j] * B.F[i];
    B.r[j] = s;
  }
}

const Matrix& meeOf(const View& P, Work& w) {
  if (!w.parametersFixed) {
    for (int j = 0; j < P.n; ++j) {
      for (int i = 0; i < P.n; ++i) w.meeSym(i, j) = P.mee(i, j);
    }
    if (P.spatial) {
      w.meeRotationSym.resize(P.n, P.n);
      for (int j = 0; j < P.n; ++j) {
        for (int i = 0; i < P.n; ++i) w.meeRotationSym(i, j) = P.meeRotation(i, j);
      }
    }
  }
  return w.meeSym;
}

void modalProducts(const View& P, const Matrix& mee, const Matrix& rotation, const double* q, const double* v,
                   const double* a, bool jacobian, Work& w, double* moments) {
  const int n = P.n;
  const bool keep = w.parametersFixed;
  const Eigen::Map<const Vector> Q(q, n), V(v, n);
  const Eigen::Map<const Matrix> ct(P.p + P.ctOffset(), n, n), kee(P.p + P.keeOffset(), n, n);
  if (!keptBits(q, w.qKey, keep && w.qKept)) {
    w.meeQ.noalias() = rotation * Q;
    w.a1.noalias() = ct.transpose() * Q;
    w.keeQ.noalias() = kee * Q;
    double sw0 = P.mc(0), sw1 = P.mc(1), jw = P.j0();
    for (int i = 0; i < n; ++i) {
      w.h(i) = P.c2(i) + w.meeQ(i);
      w.a1(i) += P.a0(i);
      sw0 += P.c1(0, i) * q[i];
      sw1 += P.c1(1, i) * q[i];
      jw += (2.0 * P.c2(i) + w.meeQ(i)) * q[i];
    }
    w.moments[kSw0] = sw0;
    w.moments[kSw1] = sw1;
    w.moments[kJw] = jw;
    std::memcpy(w.qKey.data(), q, sizeof(double) * n);
    w.qKept = keep;
    w.vKept = w.aKept = false;  // their moments use h and A1
  }
  if (!(keptBits(v, w.vKey, keep && w.vKept) && (w.vJacobian || !jacobian))) {
    w.ctV.noalias() = ct * V;
    double c1v0 = 0.0, c1v1 = 0.0, hv = 0.0;
    for (int i = 0; i < n; ++i) {
      c1v0 += P.c1(0, i) * v[i];
      c1v1 += P.c1(1, i) * v[i];
      hv += w.h(i) * v[i];
    }
    if (jacobian) w.meeV.noalias() = rotation * V;
    w.moments[kC1v0] = c1v0;
    w.moments[kC1v1] = c1v1;
    w.moments[kHv] = hv;
    std::memcpy(w.vKey.data(), v, sizeof(double) * n);
    w.vKept = keep;
    w.vJacobian = jacobian;
  }
  const bool aSame =
      a == nullptr ? (keep && w.aKept && w.aZero) : (!w.aZero && keptBits(a, w.aKey, keep && w.aKept));
  if (!(aSame && (w.aJacobian || !jacobian))) {
    double a1a = 0.0, c1a0 = 0.0, c1a1 = 0.0;
    if (a != nullptr) {
      const Eigen::Map<const Vector> A(a, n);
      w.meeA.noalias() = mee * A;
      for (int i = 0; i < n; ++i) {
        a1a += w.a1(i) * a[i];
        c1a0 += P.c1(0, i) * a[i];
        c1a1 += P.c1(1, i) * a[i];
      }
      if (jacobian) w.ctA.noalias() = ct * A;
      std::memcpy(w.aKey.data(), a, sizeof(double) * n);
    } else {
      w.meeA.setZero();
      if (jacobian) w.ctA.setZero();
    }
    w.moments[kA1a] = a1a;
    w.moments[kC1a0] = c1a0;
    w.moments[kC1a1] = c1a1;
    w.aKept = keep;
    w.aZero = a == nullptr;
    w.aJacobian = jacobian;
  }
  std::copy(w.moments, w.moments + kMoments, moments);
}

template <typename T>
void chordResidual(const System& C, const View& P, Buffers<T>& B, const T* sigmaDdot, const T* mom, T* phi,
                   const T& zero) {
  for (int i = 0; i < C.nz; ++i) {
    T s = B.zeta[i];
    for (int j = 0; j < C.f; ++j) s += B.R[i + C.nz * j] * sigmaDdot[j];
    B.zdd[i] = s;
  }
  chordForce(C, P, B, B.zdd.data(), mom, B.F.data(), phi, zero);
  for (int j = 0; j < C.f; ++j) {
    T s = zero;
    for (int i = 0; i < C.nz; ++i) s += B.R[i + C.nz * j] * B.F[i];
    B.r[j] = s;
  }
}

const Matrix& productPoint(const System& I, const System& C, const View& P, double t, ConstVectorRef y,
                           ConstVectorRef v, ConstVectorRef a, bool jacobian, Work& w, double* mom) {
  const int nf = I.nFree;
  chordInputs(I, P, y, v, a.data(), w);
  chordKinematics(C, t, w);
  const Matrix& mee = meeOf(P, w);
  modalProducts(P, mee, meeRotationOf(P, w), y.data() + nf, v.data() + nf, a.data() + nf, jacobian, w, mom);
  return meeRotationOf(P, w);
}

// The scalar types of the passes (kinematics.cpp): the full-coordinate reference in double, ADS and ADL;
// the chord path in double, ADS (with free coordinates), AD9 (without) and AD3 (the parameter product).
template void generalizedForce<double>(const System&, const View&, Buffers<double>&, const double*, bool,
                                       double*, const double&);
template void residualFromKinematics<double>(const System&, const View&, Buffers<double>&, ConstVectorRef,
                                             int);
template void residualFromKinematics<ADS>(const System&, const View&, Buffers<ADS>&, ConstVectorRef, int);
template void residualFromKinematics<ADL>(const System&, const View&, Buffers<ADL>&, ConstVectorRef, int);
template void chordResidual<double>(const System&, const View&, Buffers<double>&, const double*,
                                    const double*, double*, const double&);
template void chordResidual<ADS>(const System&, const View&, Buffers<ADS>&, const ADS*, const ADS*, ADS*,
                                 const ADS&);
template void chordResidual<AD9>(const System&, const View&, Buffers<AD9>&, const AD9*, const AD9*, AD9*,
                                 const AD9&);
template void chordResidual<AD3>(const System&, const View&, Buffers<AD3>&, const AD3*, const AD3*, AD3*,
                                 const AD3&);

}  // namespace hindsight::mechanism::detail
