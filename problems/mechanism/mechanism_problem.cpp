#include <hindsight/problems/mechanism/mechanism_problem.h>

#include <hindsight/engine/deterministic_math.h>

#include <Eigen/LU>
#include <unsupported/Eigen/AutoDiff>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

namespace hindsight::mechanism {
namespace {

// Dual numbers with derivative vectors on the stack (fixed capacity): arithmetic allocates nothing.
// A small capacity serves up to 12 minimal coordinates (the common case), the large one the rest.
template <int Capacity>
using DerivativesOf = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, Capacity, 1>;
template <int Capacity>
using ADOf = Eigen::AutoDiffScalar<DerivativesOf<Capacity>>;
constexpr int kSmall = 24;
constexpr int kLarge = 2 * (MechanismProblem::kMaxModes + MechanismProblem::kMaxFree);
using ADS = ADOf<kSmall>;
using ADL = ADOf<kLarge>;
/// Fixed numbers of directions: no loop over a dynamic derivative vector. AD2: the chord kinematics in
/// (sigma_j, sigma'_j); AD9: the residual's Jacobians of a mechanism without free coordinates (c, c'
/// and the seven moments); AD3: the parameter product's (c, c', c'').
template <int N>
using ADFixed = Eigen::AutoDiffScalar<Eigen::Matrix<double, N, 1>>;
using AD2 = ADFixed<2>;
using AD3 = ADFixed<3>;
using AD9 = ADFixed<9>;

inline double valueOf(double x) { return x; }
template <typename D>
double valueOf(const Eigen::AutoDiffScalar<D>& x) {
  return x.value();
}

/// Constants and seeded variables with derivative vectors of the pass's width.
template <typename T>
struct Make;
template <>
struct Make<double> {
  static double constant(double v, int) { return v; }
  static double variable(double v, int, int) { return v; }
  /// A value with the derivatives of d (the implicit-function step).
  static double withDerivatives(double v, double) { return v; }
};
template <int N>
struct Make<ADFixed<N>> {
  using D = Eigen::Matrix<double, N, 1>;
  static ADFixed<N> constant(double v, int) { return ADFixed<N>(v, D::Zero()); }
  static ADFixed<N> variable(double v, int, int i) { return ADFixed<N>(v, N, i); }
  static ADFixed<N> withDerivatives(double v, const ADFixed<N>& d) { return ADFixed<N>(v, d.derivatives()); }
};
template <int C>
struct Make<ADOf<C>> {
  static ADOf<C> constant(double v, int nd) { return ADOf<C>(v, DerivativesOf<C>::Zero(nd)); }
  static ADOf<C> variable(double v, int nd, int i) { return ADOf<C>(v, nd, i); }
  static ADOf<C> withDerivatives(double v, const ADOf<C>& d) { return ADOf<C>(v, d.derivatives()); }
};

/// The member's invariants inside p (the order of problems/rod/invariants.h).
struct View {
  View(int modes, const double* p, bool spatial) : n(modes), p(p), spatial(spatial) {}
  int n;
  const double* p;
  /// A member that deforms in 3-D (problems/rod/invariants.h): the rotation about z sees the modal mass
  /// of the in-plane components, M_ee^xy, a block of its own after b; for a plate it is M_ee itself.
  bool spatial;
  double mass() const { return p[0]; }
  double mc(int k) const { return p[1 + k]; }
  double j0() const { return p[3]; }
  int c1Offset() const { return 4; }
  int c2Offset() const { return 4 + 2 * n; }
  int a0Offset() const { return 4 + 3 * n; }
  int ctOffset() const { return 4 + 4 * n; }
  int meeOffset() const { return 4 + 4 * n + n * n; }
  int keeOffset() const { return 4 + 4 * n + 2 * n * n; }
  int bOffset() const { return 4 + 4 * n + 3 * n * n; }
  double c1(int k, int j) const { return p[c1Offset() + k + 2 * j]; }
  double c2(int i) const { return p[c2Offset() + i]; }
  double a0(int i) const { return p[a0Offset() + i]; }
  double ct(int i, int j) const { return p[ctOffset() + i + n * j]; }
  // M_ee enters through its symmetric part, as in problems/rod/slider_crank.cpp: the reduced mass
  // matrix must be symmetric, and the gradient splits evenly between (i, j) and (j, i).
  double mee(int i, int j) const { return 0.5 * (p[meeOffset() + i + n * j] + p[meeOffset() + j + n * i]); }
  /// M_ee^xy, the modal mass the rotation about z sees (J_w and h; docs/design.md, "The solid member in
  /// the mechanism"): M_ee for a plate, its own block for a spatial member. Symmetric part, as mee().
  int meeRotationOffset() const { return spatial ? 4 + 4 * n + 3 * n * n + n : meeOffset(); }
  double meeRotation(int i, int j) const {
    return 0.5 * (p[meeRotationOffset() + i + n * j] + p[meeRotationOffset() + j + n * i]);
  }
  double kee(int i, int j) const { return p[keeOffset() + i + n * j]; }
  double b(int i) const { return p[bOffset() + i]; }
};

constexpr int kGround = -1;

/// The member's moments: the scalars through which its frame rows depend on q, q' and a
/// (chordForce()): s_w = m c + C1 q (2), J_w = J0 + 2 C2 q + q^T M_ee^xy q, A1 . a, C1 a (2), C1 q' (2),
/// h . q' (h = C2 + M_ee^xy q; M_ee^xy = M_ee for a plate, View::meeRotation).
enum Moment { kSw0, kSw1, kJw, kA1a, kC1a0, kC1a1, kC1v0, kC1v1, kHv, kMoments };

struct PointRef {
  int body = kGround;  ///< kGround, a rigid body's index, or the member (index = rigid body count)
  Vec2 local = Vec2::Zero();
  bool atB = false;  ///< the member's B: local (L + b q, 0)
};

struct Row {
  enum Kind { Revolute, Angle, Line, DriveAngle, DriveLine };
  Kind kind = Revolute;
  PointRef p1, p2;
  int body1 = kGround, body2 = kGround;
  Vec2 axis = Vec2(1.0, 0.0);
  double offset = 0.0;
  DriverLaw law;
  std::string name;  ///< the joint's or driver's (constraintBlocks())
};

struct SpringRef {
  PointRef p1, p2;
  double stiffness, restLength, damping;
};

/// The pieces of one point's motion: position P, velocity P', the part of P'' without z'' (quad), and
/// A s, S A s (for the Jacobian), sin and cos of its body's angle.
template <typename T>
struct Pt {
  T P[2], Pd[2], Q[2], As[2], ASs[2], s, c;
};

template <typename T>
struct Buffers {
  Buffers(int nz, int m, int f, int n)
      : z(nz),
        zd(nz),
        zdd(nz),
        F(nz),
        zeta(nz),
        phi(m),
        phit(m),
        quad(m),
        rhs(m),
        jac(m * nz),
        lu(m * m),
        piv(m),
        R(nz * f),
        r(f),
        b(n),
        y(f),
        v(f),
        mq(n),
        h(n),
        a1(n),
        x(nz),
        sn((nz - n) / 3),
        cs((nz - n) / 3),
        trigAngle((nz - n) / 3, std::numeric_limits<double>::quiet_NaN()),
        driveTime(m, std::numeric_limits<double>::quiet_NaN()),
        drive(3 * m) {}
  std::vector<T> z, zd, zdd, F, zeta, phi, phit, quad, rhs, jac, lu;
  std::vector<int> piv;
  std::vector<T> R, r, b, y, v, mq, h, a1, x;
  // sin and cos of every body's angle (the member last) at z: one evaluation per constraint pass
  // instead of one per point.
  std::vector<T> sn, cs;
  // In double: the angles sn, cs were evaluated at (NaN: none yet). Newton's iterations move few
  // angles (a driven crank's is exact after the first, a prismatic slider's never moves), and a sine
  // of the same bits has the same bits.
  std::vector<double> trigAngle;
  // A driver's s, s', s'' (drive[3 i ...]) for constraint row i at driveTime[i] (NaN: none yet): Newton
  // evaluates the constraints many times at one time, and the ramp's law costs a sine and a cosine.
  std::vector<double> driveTime, drive;
  /// jac, phi, phit, quad at zero with nd derivative directions: a dual pass with a row mask
  /// (Impl::constraints()) writes only its rows, and dual numbers start uninitialised.
  void clear(int nd) {
    const T zero = Make<T>::constant(0.0, nd);
    for (auto* v : {&jac, &phi, &phit, &quad}) std::fill(v->begin(), v->end(), zero);
  }
};

inline void sinCos(double x, double& s, double& c) { dmath::sincos(x, &s, &c); }
template <int N>
void sinCos(const ADFixed<N>& x, ADFixed<N>& s, ADFixed<N>& c) {
  double sv, cv;
  dmath::sincos(x.value(), &sv, &cv);
  s = ADFixed<N>(sv, cv * x.derivatives());
  c = ADFixed<N>(cv, -sv * x.derivatives());
}
template <int C>
void sinCos(const ADOf<C>& x, ADOf<C>& s, ADOf<C>& c) {
  double sv, cv;
  dmath::sincos(x.value(), &sv, &cv);
  s = ADOf<C>(sv, cv * x.derivatives());
  c = ADOf<C>(cv, -sv * x.derivatives());
}

/// In-place LU with partial pivoting (column-major m x m); false if a pivot is exactly zero. The pivot
/// is chosen by value, so every scalar type takes the same row swaps.
template <typename T>
bool luFactor(T* a, int* piv, int m) {
  for (int k = 0; k < m; ++k) {
    int p = k;
    double best = std::abs(valueOf(a[k + m * k]));
    for (int i = k + 1; i < m; ++i) {
      const double v = std::abs(valueOf(a[i + m * k]));
      if (v > best) {
        best = v;
        p = i;
      }
    }
    piv[k] = p;
    if (best == 0.0) return false;
    if (p != k) {
      for (int j = 0; j < m; ++j) std::swap(a[k + m * j], a[p + m * j]);
    }
    const T inv = 1.0 / a[k + m * k];
    for (int i = k + 1; i < m; ++i) a[i + m * k] *= inv;
    for (int j = k + 1; j < m; ++j) {
      const T akj = a[k + m * j];
      // Constraint Jacobians are sparse: a zero of U's row k changes nothing in its column.
      if constexpr (std::is_same_v<T, double>) {
        if (akj == 0.0) continue;
      }
      for (int i = k + 1; i < m; ++i) a[i + m * j] -= a[i + m * k] * akj;
    }
  }
  return true;
}

template <typename S, typename T>
void luSolve(const S* a, const int* piv, int m, T* x) {
  for (int k = 0; k < m; ++k) {
    if (piv[k] != k) std::swap(x[k], x[piv[k]]);
  }
  // x[k] is read into a local: the compiler cannot tell that the stores to x[i] (i != k) leave it alone,
  // and would load it again in every iteration instead of vectorising the column update.
  for (int k = 0; k < m; ++k) {
    const T xk = x[k];
    if constexpr (std::is_same_v<T, double>) {
      if (xk == 0.0) continue;
    }
    const S* column = a + m * k;
    for (int i = k + 1; i < m; ++i) x[i] -= column[i] * xk;
  }
  for (int k = m - 1; k >= 0; --k) {
    x[k] /= a[k + m * k];
    const T xk = x[k];
    if constexpr (std::is_same_v<T, double>) {
      if (xk == 0.0) continue;
    }
    const S* column = a + m * k;
    for (int i = 0; i < k; ++i) x[i] -= column[i] * xk;
  }
}

}  // namespace

struct MechanismProblem::Impl {
  int nr = 0;    ///< rigid bodies
  int n = 0;     ///< modes
  int nz = 0;    ///< full coordinates
  int m = 0;     ///< constraints
  int f = 0;     ///< minimal coordinates
  int base = 0;  ///< member offset in z
  int nFree = 0;
  bool spatial = false;  ///< the member deforms in 3-D: p carries M_ee^xy (View::spatial)
  double length = 1.0;
  Vec2 gravity = Vec2::Zero();
  std::vector<double> mass, inertia;
  std::vector<int> independent;  ///< y index -> z index
  std::vector<int> dependent;    ///< u index -> z index
  std::vector<Row> rows;         ///< one entry per joint part (Revolute = 2 equations)
  std::vector<int> rowFirst;     ///< row -> its first equation
  std::vector<int> rowOf;        ///< equation -> its row
  std::vector<std::string> equationNames, coordinateNames;  ///< constraintBlocks()
  std::vector<SpringRef> springs;
  /// The chord system's coordinates and constraint rows that depend on sigma (Blocks::active): a dual
  /// pass in sigma, sigma' evaluates only these rows, since the others' derivatives are exactly zero.
  std::vector<char> zActive, rowActive;
  std::vector<int> inactiveEquations;  ///< the equations of the rows rowActive leaves out
  std::vector<int> inactiveJacIndex;   ///< their structural entries in the m x nz Jacobian

  /// What depends on time alone (the inactive blocks and rows), kept in a workspace with the bits of the
  /// time it was computed at: the engine evaluates several points at one time (a step's predictor and
  /// its Newton iterates), and these parts are the same at all of them.
  struct TimeCache {
    double tPositions = std::numeric_limits<double>::quiet_NaN();
    double tJacobian = std::numeric_limits<double>::quiet_NaN();
    double tQuadratic = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> positions;   ///< by unknown (the inactive blocks' polished solution)
    std::vector<double> jac;         ///< by inactiveJacIndex
    std::vector<double> phit, quad;  ///< by equation
  };
  static bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

  /// The block-triangular (BLT) form of Phi_u, the chord system's only (the full-coordinate reference
  /// keeps the dense solves): equations and unknowns (indices into `dependent`) by position in solve
  /// order, block b at positions [start[b], start[b + 1]). Each equation's structural entries in the
  /// unknowns as (index into the m x nz Jacobian, unknown), the earlier blocks' apart (`off`) from all
  /// (`all`); each block's constraint rows; whether Phi is affine in its block's unknowns.
  struct Blocks {
    std::vector<int> eq, unk, start;
    std::vector<int> allStart, allIndex, allUnk, offStart, offIndex, offUnk;
    std::vector<int> rowStart, rowList;
    std::vector<int> luOffset, pivOffset;  ///< a block's LU and pivots in the factor arrays
    std::vector<char> affine;
    /// Blocks whose Jacobian is constant (every coefficient +-1 or a ground guide's direction), factorised
    /// once at construction.
    std::vector<char> constant;
    std::vector<double> constantLu;
    std::vector<int> constantPiv;
    std::vector<int> touchStart, touchList;  ///< per equation: every z index its Jacobian row touches
    /// Blocks whose unknowns depend on the independent coordinates (sigma); the others are functions of
    /// time alone (a driven crank and what it carries), and the dual passes skip them.
    std::vector<char> active;
    std::vector<int> activeList;        ///< the active blocks in solve order
    std::vector<int> inactiveUnknowns;  ///< the other blocks' unknowns
    int luSize = 0, pivSize = 0, maxSize = 0;
    int count() const { return static_cast<int>(start.size()) - 1; }
    /// The index arrays as raw pointers, for the solves' loops: in locals, the stores to a solve's output
    /// cannot be taken for changes of the index arrays.
    struct Raw {
      const int *start, *eq, *unk, *offStart, *offIndex, *offUnk;
    };
    Raw raw() const {
      return {start.data(), eq.data(), unk.data(), offStart.data(), offIndex.data(), offUnk.data()};
    }
    bool empty() const { return start.empty(); }
  } blocks;
  Vector zInitial;  ///< assembled at t = 0, q = 0
  Vector yInitial, vInitial;

  int bodyOffset(int body) const { return body == nr ? base : 3 * body; }

  PointRef pointRef(const Mechanism& mech, const std::string& body, const std::string& point) const {
    PointRef r;
    if (body == "ground") {
      r.body = kGround;
      r.local = mech.groundPoints.at(point);
      return r;
    }
    if (body == mech.member.name) {
      r.body = nr;
      r.atB = point == "B";
      r.local = r.atB ? Vec2(length, 0.0) : Vec2::Zero();
      return r;
    }
    for (int k = 0; k < nr; ++k) {
      if (mech.rigidBodies[k].name == body) {
        r.body = k;
        r.local = mech.rigidBodies[k].points.at(point);
      }
    }
    return r;
  }

  int bodyIndex(const Mechanism& mech, const std::string& body) const {
    if (body == "ground") return kGround;
    if (body == mech.member.name) return nr;
    for (int k = 0; k < nr; ++k) {
      if (mech.rigidBodies[k].name == body) return k;
    }
    return kGround;
  }

  template <typename T>
  T angle(int body, const std::vector<T>& z, const T& zero) const {
    return body == kGround ? zero : z[bodyOffset(body) + 2];
  }

  /// c = b q and c' = b q' (the member's B moves along its chord by c).
  template <typename T>
  void chord(const Buffers<T>& B, bool velocity, T& c, T& cd, const T& zero) const {
    c = zero;
    cd = zero;
    for (int i = 0; i < n; ++i) {
      c += B.b[i] * B.z[base + 3 + i];
      if (velocity) cd += B.b[i] * B.zd[base + 3 + i];
    }
  }

  template <typename T>
  void point(const PointRef& r, const Buffers<T>& B, bool velocity, const T& c, const T& cd, const T& zero,
             Pt<T>& out) const {
    if (r.body == kGround) {
      for (int k = 0; k < 2; ++k) {
        out.P[k] = zero + r.local(k);
        out.Pd[k] = zero;
        out.Q[k] = zero;
        out.As[k] = zero;
        out.ASs[k] = zero;
      }
      out.s = zero;
      out.c = zero + 1.0;
      return;
    }
    const int o = bodyOffset(r.body);
    out.s = B.sn[r.body];
    out.c = B.cs[r.body];
    const T sb0 = r.atB ? T(c + r.local(0)) : T(zero + r.local(0));
    const double sb1 = r.local(1);
    out.As[0] = out.c * sb0 - out.s * sb1;
    out.As[1] = out.s * sb0 + out.c * sb1;
    out.ASs[0] = -out.As[1];
    out.ASs[1] = out.As[0];
    out.P[0] = B.z[o] + out.As[0];
    out.P[1] = B.z[o + 1] + out.As[1];
    if (!velocity) return;
    const T& td = B.zd[o + 2];
    out.Pd[0] = B.zd[o] + out.ASs[0] * td;
    out.Pd[1] = B.zd[o + 1] + out.ASs[1] * td;
    const T td2 = td * td;
    out.Q[0] = -out.As[0] * td2;
    out.Q[1] = -out.As[1] * td2;
    if (r.atB) {
      out.Pd[0] += out.c * cd;
      out.Pd[1] += out.s * cd;
      const T k = 2.0 * td * cd;
      out.Q[0] -= out.s * k;
      out.Q[1] += out.c * k;
    }
  }

  /// row[0..nz) += sign * w^T dP/dz.
  template <typename T>
  void addJT(const PointRef& r, const Pt<T>& pt, const T& w0, const T& w1, double sign, const Buffers<T>& B,
             T* row, int stride) const {
    if (r.body == kGround) return;
    const int o = bodyOffset(r.body);
    row[stride * o] += sign * w0;
    row[stride * (o + 1)] += sign * w1;
    row[stride * (o + 2)] += sign * (w0 * pt.ASs[0] + w1 * pt.ASs[1]);
    if (r.atB) {
      const T along = sign * (w0 * pt.c + w1 * pt.s);
      for (int j = 0; j < n; ++j) row[stride * (base + 3 + j)] += along * B.b[j];
    }
  }

  /// s, s', s'' of row i's driver at t, kept in B with the bits of t.
  template <typename T>
  static void driverAt(const Row& row, double t, int i, Buffers<T>& B, double& s, double& sd, double& sdd) {
    double* d = B.drive.data() + 3 * i;
    if (std::memcmp(&t, &B.driveTime[i], sizeof t) != 0) {
      row.law.at(t, d[0], d[1], d[2]);
      B.driveTime[i] = t;
    }
    s = d[0];
    sd = d[1];
    sdd = d[2];
  }

  /// B.sn, B.cs at B.z.
  template <typename T>
  void updateTrig(Buffers<T>& B) const {
    for (int k = 0; k <= nr; ++k) updateTrigOf(B, k);
  }

  /// B.sn[k], B.cs[k] at B.z (k a body, kGround: nothing).
  template <typename T>
  void updateTrigOf(Buffers<T>& B, int k) const {
    if (k == kGround) return;
    if constexpr (std::is_same_v<T, double>) {
      const double angle = B.z[bodyOffset(k) + 2];
      if (std::memcmp(&angle, &B.trigAngle[k], sizeof angle) == 0) return;  // bitwise (-0 is not 0)
      B.trigAngle[k] = angle;
    }
    sinCos(B.z[bodyOffset(k) + 2], B.sn[k], B.cs[k]);
  }

  /// Phi (and with `jacobian` Phi_z, Phi_t; with `quadratic` gamma, which needs B.zd) at B.z, time t;
  /// also B.sn, B.cs at B.z, which the forces after it use.
  /// With rowMask (rowActive), only the rows it marks; the other rows' entries are left as they are: a
  /// dual pass never reads them (they stay at the zeros of Buffers::clear()), and constraintsCached()
  /// restores them in double.
  template <typename T>
  void constraints(double t, Buffers<T>& B, bool jacobian, bool quadratic, const T& zero, bool trig = true,
                   const char* rowMask = nullptr) const {
    if (trig) updateTrig(B);
    T c, cd;
    chord(B, quadratic, c, cd, zero);
    const int rowCount = static_cast<int>(rows.size());
    if (jacobian) {
      if (rowMask == nullptr) {
        for (auto& x : B.jac) x = zero;
      } else {
        // The touched entries of the marked rows (evaluateRow() adds exact zeros elsewhere).
        for (int r = 0; r < rowCount; ++r) {
          if (!rowMask[r]) continue;
          const int last = r + 1 < rowCount ? rowFirst[r + 1] : m;
          for (int i = rowFirst[r]; i < last; ++i) {
            for (int x = blocks.touchStart[i]; x < blocks.touchStart[i + 1]; ++x)
              B.jac[blocks.touchList[x]] = zero;
          }
        }
      }
    }
    for (int r = 0; r < rowCount; ++r) {
      if (rowMask == nullptr || rowMask[r]) evaluateRow(t, B, r, jacobian, quadratic, c, cd, zero);
    }
  }

  /// constraints() in double for the chord system's kinematics (one of jacobian, quadratic), with the
  /// rows that depend on time alone taken from `cache` when it holds them at the bits of t (they are a
  /// function of t, so the bits are those a new evaluation would give). Their Phi is left as it was: the
  /// kinematics read only the Jacobian, Phi_t and gamma (Newton evaluates its own rows).
  void constraintsCached(double t, Buffers<double>& B, bool jacobian, bool quadratic, bool trig,
                         TimeCache& cache) const {
    double& key = jacobian ? cache.tJacobian : cache.tQuadratic;
    if (!sameBits(t, key)) {
      constraints(t, B, jacobian, quadratic, 0.0, trig);
      for (std::size_t k = 0; k < inactiveJacIndex.size() && jacobian; ++k)
        cache.jac[k] = B.jac[inactiveJacIndex[k]];
      for (int e : inactiveEquations) {
        if (jacobian) cache.phit[e] = B.phit[e];
        if (quadratic) cache.quad[e] = B.quad[e];
      }
      key = t;
      return;
    }
    constraints(t, B, jacobian, quadratic, 0.0, trig, rowActive.data());
    for (std::size_t k = 0; k < inactiveJacIndex.size() && jacobian; ++k)
      B.jac[inactiveJacIndex[k]] = cache.jac[k];
    for (int e : inactiveEquations) {
      if (jacobian) B.phit[e] = cache.phit[e];
      if (quadratic) B.quad[e] = cache.quad[e];
    }
  }

  /// Constraint row r's equations (from rowFirst[r] on): Phi, with `jacobian` its Jacobian added into
  /// B.jac (the caller zeroes it) and Phi_t, with `quadratic` gamma. Needs B.sn, B.cs at B.z and c, c'.
  template <typename T>
  void evaluateRow(double t, Buffers<T>& B, int r, bool jacobian, bool quadratic, const T& c, const T& cd,
                   const T& zero) const {
    const Row& row = rows[r];
    const int i = rowFirst[r];
    T* jrow = B.jac.data() + i;  // row i of the column-major m x nz matrix: stride m
    const int mm = m;
    Pt<T> a, b;
    switch (row.kind) {
      case Row::Revolute: {
        point(row.p1, B, quadratic, c, cd, zero, a);
        point(row.p2, B, quadratic, c, cd, zero, b);
        B.phi[i] = a.P[0] - b.P[0];
        B.phi[i + 1] = a.P[1] - b.P[1];
        if (jacobian) {
          const T one = zero + 1.0;
          addJT(row.p1, a, one, zero, 1.0, B, jrow, mm);
          addJT(row.p2, b, one, zero, -1.0, B, jrow, mm);
          addJT(row.p1, a, zero, one, 1.0, B, jrow + 1, mm);
          addJT(row.p2, b, zero, one, -1.0, B, jrow + 1, mm);
          B.phit[i] = zero;
          B.phit[i + 1] = zero;
        }
        if (quadratic) {
          B.quad[i] = a.Q[0] - b.Q[0];
          B.quad[i + 1] = a.Q[1] - b.Q[1];
        }
        break;
      }
      case Row::Angle:
      case Row::DriveAngle: {
        double s = 0.0, sd = 0.0, sdd = 0.0;
        if (row.kind == Row::DriveAngle) driverAt(row, t, i, B, s, sd, sdd);
        B.phi[i] = angle(row.body2, B.z, zero) - angle(row.body1, B.z, zero) - (row.offset + s);
        if (jacobian) {
          if (row.body2 != kGround) jrow[mm * (bodyOffset(row.body2) + 2)] += 1.0;
          if (row.body1 != kGround) jrow[mm * (bodyOffset(row.body1) + 2)] -= 1.0;
          B.phit[i] = zero - sd;
        }
        if (quadratic) B.quad[i] = zero - sdd;
        break;
      }
      case Row::Line:
      case Row::DriveLine: {
        point(row.p1, B, quadratic, c, cd, zero, a);
        point(row.p2, B, quadratic, c, cd, zero, b);
        T s1 = zero, c1 = zero + 1.0, w1 = zero;
        if (row.body1 != kGround) {
          const int o = bodyOffset(row.body1);
          s1 = B.sn[row.body1];
          c1 = B.cs[row.body1];
          if (quadratic) w1 = B.zd[o + 2];
        }
        // e1 = A1 axis, n1 = S e1; d = P2 - P1.
        const T e0 = c1 * row.axis(0) - s1 * row.axis(1), e1 = s1 * row.axis(0) + c1 * row.axis(1);
        const T n0 = -e1, n1 = e0;
        const T d0 = b.P[0] - a.P[0], d1 = b.P[1] - a.P[1];
        const bool drive = row.kind == Row::DriveLine;
        double s = 0.0, sd = 0.0, sdd = 0.0;
        if (drive) driverAt(row, t, i, B, s, sd, sdd);
        // Line: n1 . d = 0. DriveLine: e1 . d = offset + s(t).
        const T& u0 = drive ? e0 : n0;
        const T& u1 = drive ? e1 : n1;
        const T du0 = drive ? n0 : T(-e0), du1 = drive ? n1 : T(-e1);  // d(u)/d(theta1)
        B.phi[i] = u0 * d0 + u1 * d1 - (drive ? row.offset + s : 0.0);
        if (jacobian) {
          addJT(row.p2, b, u0, u1, 1.0, B, jrow, mm);
          addJT(row.p1, a, u0, u1, -1.0, B, jrow, mm);
          if (row.body1 != kGround) jrow[mm * (bodyOffset(row.body1) + 2)] += du0 * d0 + du1 * d1;
          B.phit[i] = zero - (drive ? sd : 0.0);
        }
        if (quadratic) {
          // d/dt of u is du w1, d^2/dt^2 is -u w1^2 + du w1' (the w1' part is in the Jacobian).
          const T dd0 = b.Pd[0] - a.Pd[0], dd1 = b.Pd[1] - a.Pd[1];
          B.quad[i] = u0 * (b.Q[0] - a.Q[0]) + u1 * (b.Q[1] - a.Q[1]) + 2.0 * w1 * (du0 * dd0 + du1 * dd1) -
                      w1 * w1 * (u0 * d0 + u1 * d1) - (drive ? sdd : 0.0);
        }
        break;
      }
    }
  }

  /// Newton's method on the dependent coordinates of B.z (double), the independent ones held fixed.
  /// Returns the last step's size; `iterations` < 0: until the step is below tol (throws after 50).
  /// With `quadratic` also when the convergence is quadratic and predicts the next step below
  /// 1e-16: e_(k+1) ~ C s_k^2 with C ~ s_k / s_(k-1)^2 (one factorisation fewer than waiting for it).
  double newton(double t, Buffers<double>& B, int iterations, double tol, bool quadratic = false) const {
    double step = 0.0, previous = 0.0;
    for (int it = 0; iterations < 0 ? it < 50 : it < iterations; ++it) {
      constraints(t, B, true, false, 0.0);
      for (int j = 0; j < m; ++j) {
        for (int i = 0; i < m; ++i) B.lu[i + m * j] = B.jac[i + m * dependent[j]];
      }
      if (!luFactor(B.lu.data(), B.piv.data(), m)) {
        throw NumericalError("the mechanism's constraints are singular (a lock-up or a redundant joint)", t);
      }
      for (int i = 0; i < m; ++i) B.rhs[i] = B.phi[i];
      luSolve(B.lu.data(), B.piv.data(), m, B.rhs.data());
      step = 0.0;
      for (int i = 0; i < m; ++i) {
        B.z[dependent[i]] -= B.rhs[i];
        step = std::max(step, std::abs(B.rhs[i]));
      }
      if (!std::isfinite(step)) break;
      if (iterations < 0 && step <= tol) return step;
      if (quadratic && it >= 1 && step <= 1e-7 && step < previous &&
          step * step * step <= 1e-16 * previous * previous)
        return step;
      previous = step;
    }
    if (iterations < 0 || !std::isfinite(step)) {
      throw NumericalError("the mechanism cannot be assembled (Newton on the constraints did not converge)",
                           t);
    }
    return step;
  }

  double driverDistance(double t0, double t1) const {
    double d = 0.0;
    for (const Row& r : rows) {
      if (r.kind != Row::DriveAngle && r.kind != Row::DriveLine) continue;
      // For t >= 0 both laws have |s'| <= |speed|: a short step needs no evaluation of the ramp (its
      // sine and cosine) to know that it stays below the continuation's 0.25.
      const double bound = std::abs(r.law.speed) * std::abs(t1 - t0);
      if (t0 >= 0.0 && t1 >= 0.0 && bound <= 0.25) {
        d = std::max(d, bound);
        continue;
      }
      double s0, s1, x, y;
      r.law.at(t0, s0, x, y);
      r.law.at(t1, s1, x, y);
      d = std::max(d, std::abs(s1 - s0));
    }
    return d;
  }
  // ---- The block-triangular form of the position constraints (the chord system). ----

  /// One structural entry of an equation: a coordinate it depends on and the coordinates its
  /// coefficient (the Jacobian entry) depends on.
  struct Entry {
    int z;
    std::vector<int> coefficient;
  };

  /// The structural entries of every equation, read off the rows' formulas: a point's position depends
  /// on its body's x or y (coefficient 1) and, off the body's origin or at the member's B, on its angle
  /// (and the modal coordinates at B); a line's direction depends on body1's angle, and a component
  /// that is exactly zero for a line fixed to the ground drops out (a slider on a guide along x does not
  /// move in x by the guide's equation).
  std::vector<std::vector<Entry>> structure() const {
    std::vector<std::vector<Entry>> eqs(m);
    auto add = [&](int e, int z, std::vector<int> coefficient) {
      for (Entry& x : eqs[e]) {
        if (x.z == z) {
          x.coefficient.insert(x.coefficient.end(), coefficient.begin(), coefficient.end());
          return;
        }
      }
      eqs[e].push_back(Entry{z, std::move(coefficient)});
    };
    // Component k of a point's position; `with` the coordinates that multiply it (a line's direction).
    auto pointTerms = [&](int e, const PointRef& r, int k, bool translation, const std::vector<int>& with) {
      if (r.body == kGround) return;
      const int o = bodyOffset(r.body);
      if (translation) add(e, o + k, with);
      std::vector<int> rotating = with;
      rotating.push_back(o + 2);
      if (r.atB || r.local != Vec2::Zero()) add(e, o + 2, rotating);
      if (r.atB) {
        for (int j = 0; j < n; ++j) add(e, base + 3 + j, rotating);
      }
    };
    for (int r = 0; r < static_cast<int>(rows.size()); ++r) {
      const Row& row = rows[r];
      const int i = rowFirst[r];
      switch (row.kind) {
        case Row::Revolute:
          for (int k = 0; k < 2; ++k) {
            pointTerms(i + k, row.p1, k, true, {});
            pointTerms(i + k, row.p2, k, true, {});
          }
          break;
        case Row::Angle:
        case Row::DriveAngle:
          if (row.body2 != kGround) add(i, bodyOffset(row.body2) + 2, {});
          if (row.body1 != kGround) add(i, bodyOffset(row.body1) + 2, {});
          break;
        case Row::Line:
        case Row::DriveLine: {
          const bool drive = row.kind == Row::DriveLine;
          // The direction u: the axis (drive) or its normal, in body1's frame.
          const double u[2] = {drive ? row.axis(0) : -row.axis(1), drive ? row.axis(1) : row.axis(0)};
          std::vector<int> direction, all;
          for (int body : {row.body1, row.body2}) {
            if (body == kGround) continue;
            for (int k = 0; k < 3; ++k) all.push_back(bodyOffset(body) + k);
          }
          if (row.body1 != kGround) direction.push_back(bodyOffset(row.body1) + 2);
          for (int k = 0; k < 2; ++k) {
            // Constant and exactly zero: the component drops out.
            const bool present = row.body1 != kGround || u[k] != 0.0;
            pointTerms(i, row.p2, k, present, direction);
            pointTerms(i, row.p1, k, present, direction);
          }
          // body1's angle turns the direction: its coefficient depends on the whole row.
          if (row.body1 != kGround) add(i, bodyOffset(row.body1) + 2, all);
          break;
        }
      }
    }
    return eqs;
  }

  /// Matching of equations to unknowns (augmenting paths) on the sparsity pattern of Phi_u, then
  /// Tarjan's strongly connected components of the graph "equation needs the unknown matched to
  /// another": the Dulmage-Mendelsohn (BLT) order, blocks in the order they can be solved. Throws
  /// std::invalid_argument when the pattern has no perfect matching (redundant or missing constraints).
  void buildBlocks() {
    const std::vector<std::vector<Entry>> eqs = structure();
    std::vector<int> unknownOf(nz, -1);
    for (int j = 0; j < m; ++j) unknownOf[dependent[j]] = j;
    std::vector<std::vector<int>> adj(m);
    for (int e = 0; e < m; ++e) {
      for (const Entry& x : eqs[e]) {
        if (unknownOf[x.z] >= 0) adj[e].push_back(unknownOf[x.z]);
      }
      std::sort(adj[e].begin(), adj[e].end());
    }
    std::vector<int> eqOfUnknown(m, -1), unknownOfEq(m, -1);
    for (int e = 0; e < m; ++e) {
      std::vector<char> seen(m, 0);
      // Kuhn's augmenting path from equation e (m is at most a few hundred).
      std::function<bool(int)> augment = [&](int q) {
        for (int j : adj[q]) {
          if (seen[j]) continue;
          seen[j] = 1;
          if (eqOfUnknown[j] < 0 || augment(eqOfUnknown[j])) {
            eqOfUnknown[j] = q;
            unknownOfEq[q] = j;
            return true;
          }
        }
        return false;
      };
      if (!augment(e)) {
        throw std::invalid_argument(
            "mechanism: the constraints are structurally singular (no equation can fix some coordinate; a "
            "redundant joint or a coordinate no joint constrains)");
      }
    }
    // Tarjan: an equation's component is emitted after every component it needs.
    std::vector<int> index(m, -1), low(m, 0), stack;
    std::vector<char> onStack(m, 0);
    int counter = 0;
    Blocks& bl = blocks;
    bl = Blocks();
    std::function<void(int)> visit = [&](int e) {
      index[e] = low[e] = counter++;
      stack.push_back(e);
      onStack[e] = 1;
      for (int j : adj[e]) {
        const int q = eqOfUnknown[j];
        if (q == e) continue;
        if (index[q] < 0) {
          visit(q);
          low[e] = std::min(low[e], low[q]);
        } else if (onStack[q]) {
          low[e] = std::min(low[e], index[q]);
        }
      }
      if (low[e] != index[e]) return;
      std::vector<int> component;
      for (;;) {
        const int q = stack.back();
        stack.pop_back();
        onStack[q] = 0;
        component.push_back(q);
        if (q == e) break;
      }
      std::sort(component.begin(), component.end());
      bl.start.push_back(static_cast<int>(bl.eq.size()));
      for (int q : component) {
        bl.eq.push_back(q);
        bl.unk.push_back(unknownOfEq[q]);
      }
    };
    for (int e = 0; e < m; ++e) {
      if (index[e] < 0) visit(e);
    }
    bl.start.push_back(m);
    std::vector<int> blockOf(m);
    for (int b = 0; b < bl.count(); ++b) {
      for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) blockOf[bl.unk[p]] = b;
    }
    std::vector<int> rowOfEq(m);
    for (int r = 0; r < static_cast<int>(rows.size()); ++r) {
      for (int i = rowFirst[r]; i < (r + 1 < static_cast<int>(rows.size()) ? rowFirst[r + 1] : m); ++i)
        rowOfEq[i] = r;
    }
    for (int b = 0; b < bl.count(); ++b) {
      const int s = bl.start[b + 1] - bl.start[b];
      bl.luOffset.push_back(bl.luSize);
      bl.pivOffset.push_back(bl.pivSize);
      bl.luSize += s * s;
      bl.pivSize += s;
      bl.maxSize = std::max(bl.maxSize, s);
      std::vector<int> blockZ;
      for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) blockZ.push_back(dependent[bl.unk[p]]);
      bool affine = true, constant = true;
      bl.rowStart.push_back(static_cast<int>(bl.rowList.size()));
      for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) {
        const int e = bl.eq[p];
        if (std::find(bl.rowList.begin() + bl.rowStart[b], bl.rowList.end(), rowOfEq[e]) == bl.rowList.end())
          bl.rowList.push_back(rowOfEq[e]);
        bl.allStart.push_back(static_cast<int>(bl.allIndex.size()));
        bl.offStart.push_back(static_cast<int>(bl.offIndex.size()));
        for (const Entry& x : eqs[e]) {
          const int j = unknownOf[x.z];
          if (j < 0) continue;
          bl.allIndex.push_back(e + m * x.z);
          bl.allUnk.push_back(j);
          if (blockOf[j] != b) {
            assert(blockOf[j] < b);
            bl.offIndex.push_back(e + m * x.z);
            bl.offUnk.push_back(j);
          } else {
            if (!x.coefficient.empty()) constant = false;
            for (int z : x.coefficient) {
              if (std::find(blockZ.begin(), blockZ.end(), z) != blockZ.end()) affine = false;
            }
          }
        }
      }
      bl.affine.push_back(affine ? 1 : 0);
      bl.constant.push_back(constant ? 1 : 0);
    }
    bl.rowStart.push_back(static_cast<int>(bl.rowList.size()));
    bl.allStart.push_back(static_cast<int>(bl.allIndex.size()));
    bl.offStart.push_back(static_cast<int>(bl.offIndex.size()));
    for (int e = 0; e < m; ++e) {
      bl.touchStart.push_back(static_cast<int>(bl.touchList.size()));
      for (const Entry& x : eqs[e]) bl.touchList.push_back(e + m * x.z);
    }
    bl.touchStart.push_back(static_cast<int>(bl.touchList.size()));
    // Activity: a block is a function of time alone when its equations (their values and their
    // Jacobian coefficients) touch only its own unknowns and those of earlier blocks that are; the
    // block-triangular order lets one pass decide it. The independent coordinates start it.
    zActive.assign(nz, 0);
    for (int i : independent) zActive[i] = 1;
    bl.active.assign(bl.count(), 0);
    std::vector<char> eqActive(m, 0);
    for (int b = 0; b < bl.count(); ++b) {
      bool active = false;
      for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) {
        for (const Entry& x : eqs[bl.eq[p]]) {
          active = active || zActive[x.z];
          for (int z : x.coefficient) active = active || zActive[z];
        }
      }
      if (!active) continue;
      bl.active[b] = 1;
      for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) {
        zActive[dependent[bl.unk[p]]] = 1;
        eqActive[bl.eq[p]] = 1;
      }
    }
    for (int b = 0; b < bl.count(); ++b) {
      if (bl.active[b]) {
        bl.activeList.push_back(b);
      } else {
        for (int p = bl.start[b]; p < bl.start[b + 1]; ++p) bl.inactiveUnknowns.push_back(bl.unk[p]);
      }
    }
    rowActive.assign(rows.size(), 0);
    for (int e = 0; e < m; ++e) {
      if (eqActive[e]) rowActive[rowOf[e]] = 1;
    }
    for (int e = 0; e < m; ++e) {
      if (rowActive[rowOf[e]]) continue;
      inactiveEquations.push_back(e);
      for (int x = bl.touchStart[e]; x < bl.touchStart[e + 1]; ++x)
        inactiveJacIndex.push_back(bl.touchList[x]);
    }
    // The constant blocks' factors, from the Jacobian at the initial positions (any point would do).
    bl.constantLu.assign(bl.luSize, 0.0);
    bl.constantPiv.assign(bl.pivSize, 0);
    Buffers<double> B(nz, m, f, n);
    for (int i = 0; i < nz; ++i) B.z[i] = zInitial(i);
    for (int i = 0; i < n; ++i) B.b[i] = 1.0;
    for (int b = 0; b < bl.count(); ++b) {
      if (!bl.constant[b]) continue;
      evaluateBlock(0.0, B, b, true);
      try {
        factorBlock(0.0, B.jac.data(), b, bl.constantLu.data() + bl.luOffset[b],
                    bl.constantPiv.data() + bl.pivOffset[b]);
      } catch (const NumericalError&) {
        throw std::invalid_argument(
            "mechanism: the constraints are singular (a redundant joint or a coordinate no joint "
            "constrains)");
      }
    }
  }

  /// Phi and (with `jacobian`) the Jacobian rows of block b's equations at B.z (their other equations'
  /// too, which the block's rows compute alongside). The sines and cosines of the rows' bodies only:
  /// an angle row needs none.
  void evaluateBlock(double t, Buffers<double>& B, int b, bool jacobian) const {
    double c, cd;
    chord(B, false, c, cd, 0.0);
    for (int k = blocks.rowStart[b]; k < blocks.rowStart[b + 1]; ++k) {
      const int r = blocks.rowList[k];
      const Row& row = rows[r];
      if (row.kind != Row::Angle && row.kind != Row::DriveAngle) {
        updateTrigOf(B, row.p1.body);
        updateTrigOf(B, row.p2.body);
        updateTrigOf(B, row.body1);
      }
      if (jacobian) {
        const int last = r + 1 < static_cast<int>(rows.size()) ? rowFirst[r + 1] : m;
        for (int i = rowFirst[r]; i < last; ++i) {
          for (int x = blocks.touchStart[i]; x < blocks.touchStart[i + 1]; ++x)
            B.jac[blocks.touchList[x]] = 0.0;
        }
      }
      evaluateRow(t, B, r, jacobian, false, c, cd, 0.0);
    }
  }

  /// Block b's Jacobian (its rows of Phi_u in its unknowns, s x s column-major) into lu, factorised
  /// (piv); from B.jac.
  void factorBlock(double t, const double* jac, int b, double* lu, int* piv) const {
    const int p0 = blocks.start[b], s = blocks.start[b + 1] - p0;
    for (int j = 0; j < s; ++j) {
      for (int i = 0; i < s; ++i) lu[i + s * j] = jac[blocks.eq[p0 + i] + m * dependent[blocks.unk[p0 + j]]];
    }
    if (s == 1 ? lu[0] == 0.0 : !luFactor(lu, piv, s)) {
      throw NumericalError("the mechanism's constraints are singular (a lock-up or a redundant joint)", t);
    }
  }

  /// One Newton step on block b (the earlier blocks' unknowns and the independent coordinates fixed):
  /// returns the step's size. lu, piv, x: scratch of the largest block.
  double blockStep(double t, Buffers<double>& B, int b, double* lu, int* piv, double* x) const {
    const int p0 = blocks.start[b], s = blocks.start[b + 1] - p0;
    const double* l = lu;
    const int* lp = piv;
    if (blocks.constant[b]) {
      // The block's Jacobian has the same bits everywhere: factorised once (buildBlocks()).
      evaluateBlock(t, B, b, false);
      l = blocks.constantLu.data() + blocks.luOffset[b];
      lp = blocks.constantPiv.data() + blocks.pivOffset[b];
    } else {
      evaluateBlock(t, B, b, true);
      factorBlock(t, B.jac.data(), b, lu, piv);
    }
    for (int i = 0; i < s; ++i) x[i] = B.phi[blocks.eq[p0 + i]];
    if (s == 1) {
      x[0] /= l[0];
    } else {
      luSolve(l, lp, s, x);
    }
    double step = 0.0;
    for (int i = 0; i < s; ++i) {
      B.z[dependent[blocks.unk[p0 + i]]] -= x[i];
      step = std::max(step, std::abs(x[i]));
    }
    return step;
  }

  /// Component k of a point's position at B.z (the operations of point()).
  double pointComponent(const PointRef& r, Buffers<double>& B, double c, int k) const {
    if (r.body == kGround) return r.local(k);
    updateTrigOf(B, r.body);
    const double s = B.sn[r.body], cs = B.cs[r.body];
    const double sb0 = r.atB ? c + r.local(0) : 0.0 + r.local(0), sb1 = r.local(1);
    return B.z[bodyOffset(r.body) + k] + (k == 0 ? cs * sb0 - s * sb1 : s * sb0 + cs * sb1);
  }

  /// d/dz of component k of a point's position at B.z after pointComponent() (which updated its body's
  /// sine and cosine): the entry addJT() adds, with its bits.
  double pointDerivative(const PointRef& r, const Buffers<double>& B, double c, int k, int z) const {
    if (r.body == kGround) return 0.0;
    const int o = bodyOffset(r.body);
    if (z == o + k) return 1.0;
    if (z != o + 2) return 0.0;
    const double s = B.sn[r.body], cs = B.cs[r.body];
    const double sb0 = r.atB ? c + r.local(0) : 0.0 + r.local(0), sb1 = r.local(1);
    return k == 0 ? -(s * sb0 + cs * sb1) : cs * sb0 - s * sb1;
  }

  /// Equation e's value alone at B.z, with the bits evaluateRow() gives it (c: the chord).
  double equationValue(double t, Buffers<double>& B, int e, double c) const {
    const int r = rowOf[e];
    const Row& row = rows[r];
    switch (row.kind) {
      case Row::Revolute: {
        const int k = e - rowFirst[r];
        return pointComponent(row.p1, B, c, k) - pointComponent(row.p2, B, c, k);
      }
      case Row::Angle:
      case Row::DriveAngle: {
        double s = 0.0, sd = 0.0, sdd = 0.0;
        if (row.kind == Row::DriveAngle) driverAt(row, t, e, B, s, sd, sdd);
        return angle(row.body2, B.z, 0.0) - angle(row.body1, B.z, 0.0) - (row.offset + s);
      }
      default: {
        double s1 = 0.0, c1 = 1.0;
        if (row.body1 != kGround) {
          updateTrigOf(B, row.body1);
          s1 = B.sn[row.body1];
          c1 = B.cs[row.body1];
        }
        const double e0 = c1 * row.axis(0) - s1 * row.axis(1), e1 = s1 * row.axis(0) + c1 * row.axis(1);
        const double d0 = pointComponent(row.p2, B, c, 0) - pointComponent(row.p1, B, c, 0);
        const double d1 = pointComponent(row.p2, B, c, 1) - pointComponent(row.p1, B, c, 1);
        if (row.kind == Row::Line) return -e1 * d0 + e0 * d1 - 0.0;
        double s = 0.0, sd = 0.0, sdd = 0.0;
        driverAt(row, t, e, B, s, sd, sdd);
        return e0 * d0 + e1 * d1 - (row.offset + s);
      }
    }
  }

  /// The dependent coordinates of B.z solved block by block at time t (independent ones fixed). A block
  /// affine in its unknowns is solved by one step from zero, exactly, and its result is a function of
  /// the earlier blocks and sigma alone. Any other block: Newton from B.z until the step is below 1e-11
  /// or the quadratic convergence predicts the next below 1e-16; with `polish`, its unknowns are then
  /// rounded to a grid of 2^-20 and Newton runs again from the grid point (two or three steps reach
  /// round-off), so that its result is a function of the grid point, the earlier blocks and sigma (see
  /// the header). lu, piv, x: scratch of the largest block.
  /// With `cache` (polished solves), the blocks that depend on time alone are taken from it when it holds
  /// them at the bits of t, and kept in it otherwise.
  void solveBlocks(double t, Buffers<double>& B, bool polish, double* lu, int* piv, double* x,
                   TimeCache* cache = nullptr) const {
    double c, cd;
    chord(B, false, c, cd, 0.0);
    if (!polish) cache = nullptr;
    const bool cached = cache != nullptr && sameBits(t, cache->tPositions);
    for (int b = 0; b < blocks.count(); ++b) {
      const int p0 = blocks.start[b], p1 = blocks.start[b + 1];
      if (cached && !blocks.active[b]) {
        for (int p = p0; p < p1; ++p) B.z[dependent[blocks.unk[p]]] = cache->positions[blocks.unk[p]];
        continue;
      }
      if (blocks.constant[b] && p1 == p0 + 1) {
        // One equation with a constant coefficient (a pin's x or y, a driven angle, a ground guide):
        // its value at zero and the kept coefficient, the operations of blockStep().
        double& u = B.z[dependent[blocks.unk[p0]]];
        u = 0.0;
        u -= equationValue(t, B, blocks.eq[p0], c) / blocks.constantLu[blocks.luOffset[b]];
        if (!std::isfinite(u)) {
          throw NumericalError("the mechanism cannot be assembled (its constraints give no finite position)",
                               t);
        }
        continue;
      }
      if (blocks.affine[b]) {
        for (int p = p0; p < p1; ++p) B.z[dependent[blocks.unk[p]]] = 0.0;
        if (!std::isfinite(blockStep(t, B, b, lu, piv, x))) {
          throw NumericalError("the mechanism cannot be assembled (its constraints give no finite position)",
                               t);
        }
        continue;
      }
      // One Newton step; a single revolute equation (a loop's closure through a pin) by its value and
      // derivative alone, with the operations and bits of blockStep().
      const int e = blocks.eq[p0];
      const Row& row = rows[rowOf[e]];
      const bool scalarRevolute = p1 == p0 + 1 && row.kind == Row::Revolute;
      auto newtonStep = [&] {
        if (!scalarRevolute) return blockStep(t, B, b, lu, piv, x);
        const int k = e - rowFirst[rowOf[e]], zu = dependent[blocks.unk[p0]];
        const double value = pointComponent(row.p1, B, c, k) - pointComponent(row.p2, B, c, k);
        const double slope = pointDerivative(row.p1, B, c, k, zu) - pointDerivative(row.p2, B, c, k, zu);
        if (slope == 0.0) {
          throw NumericalError("the mechanism's constraints are singular (a lock-up or a redundant joint)",
                               t);
        }
        const double dx = value / slope;
        B.z[zu] -= dx;
        return std::abs(dx);
      };
      double step = 0.0, previous = 0.0;
      bool converged = false;
      for (int it = 0; it < 50; ++it) {
        step = newtonStep();
        if (!std::isfinite(step)) break;
        if (step <= 1e-11 || (it >= 1 && step <= 1e-7 && step < previous &&
                              step * step * step <= 1e-16 * previous * previous)) {
          converged = true;
          break;
        }
        previous = step;
      }
      if (!converged) {
        throw NumericalError("the mechanism cannot be assembled (Newton on the constraints did not converge)",
                             t);
      }
      if (!polish) continue;
      for (int p = p0; p < p1; ++p) {
        double& u = B.z[dependent[blocks.unk[p]]];
        u = std::ldexp(std::nearbyint(std::ldexp(u, 20)), -20);
      }
      previous = 0.0;
      for (int it = 0; it < 3; ++it) {
        step = newtonStep();
        if (step == 0.0 || (it >= 1 && step < previous && step * step * step <= 1e-16 * previous * previous))
          break;
        previous = step;
      }
    }
    if (cache != nullptr && !cached) {
      for (int u : blocks.inactiveUnknowns) cache->positions[u] = B.z[dependent[u]];
      cache->tPositions = t;
    }
  }

  /// Every block of Phi_u (from the m x nz jac) factorised into lu, piv (Blocks::luOffset, pivOffset).
  void factorBlocks(double t, const double* jac, double* lu, int* piv) const {
    for (int b = 0; b < blocks.count(); ++b)
      factorBlock(t, jac, b, lu + blocks.luOffset[b], piv + blocks.pivOffset[b]);
  }

  /// out = Phi_u^{-1} in by block forward substitution (in by equation, out by unknown; Phi_u's entries
  /// from the m x nz jac, its blocks factorised by factorBlocks()). r: scratch of the largest block.
  void blockSolve(const double* jac, const double* lu, const int* piv, const double* in, double* out,
                  double* r) const {
    const auto [start, eq, unk, offStart, offIndex, offUnk] = blocks.raw();
    const int* luOffset = blocks.luOffset.data();
    const int* pivOffset = blocks.pivOffset.data();
    const int count = blocks.count();
    for (int b = 0; b < count; ++b) {
      const int p0 = start[b], s = start[b + 1] - p0;
      if (s == 1) {  // the common case: one equation, one unknown
        double v = in[eq[p0]];
        for (int k = offStart[p0]; k < offStart[p0 + 1]; ++k) v -= jac[offIndex[k]] * out[offUnk[k]];
        out[unk[p0]] = v / lu[luOffset[b]];
        continue;
      }
      for (int i = 0; i < s; ++i) {
        const int p = p0 + i;
        double v = in[eq[p]];
        for (int k = offStart[p]; k < offStart[p + 1]; ++k) v -= jac[offIndex[k]] * out[offUnk[k]];
        r[i] = v;
      }
      const double* l = lu + luOffset[b];
      if (s == 1) {
        out[unk[p0]] = r[0] / l[0];
      } else {
        luSolve(l, piv + pivOffset[b], s, r);
        for (int i = 0; i < s; ++i) out[unk[p0 + i]] = r[i];
      }
    }
  }

  /// blockSolve() in nd directions at once (in[nd q + e] by equation, out[nd u + e] by unknown), over the
  /// active blocks only (Blocks::active): the others' unknowns are zero, as a dual pass's derivatives are.
  /// Each direction takes blockSolve()'s operations. r: scratch of nd times the largest block.
  void blockSolveActive(const double* jac, const double* lu, const int* piv, const double* in, double* out,
                        double* r, int nd) const {
    const auto [start, eq, unk, offStart, offIndex, offUnk] = blocks.raw();
    for (int u : blocks.inactiveUnknowns) {
      for (int e = 0; e < nd; ++e) out[nd * u + e] = 0.0;
    }
    for (int b : blocks.activeList) {
      const int p0 = start[b], s = start[b + 1] - p0;
      const double* l = lu + blocks.luOffset[b];
      for (int i = 0; i < s; ++i) {
        const int p = p0 + i;
        for (int e = 0; e < nd; ++e) {
          double v = in[nd * eq[p] + e];
          for (int k = offStart[p]; k < offStart[p + 1]; ++k) v -= jac[offIndex[k]] * out[nd * offUnk[k] + e];
          r[i + s * e] = v;
        }
      }
      for (int e = 0; e < nd; ++e) {
        double* x = r + s * e;
        if (s == 1) {
          x[0] = x[0] / l[0];
        } else {
          luSolve(l, piv + blocks.pivOffset[b], s, x);
        }
        for (int i = 0; i < s; ++i) out[nd * unk[p0 + i] + e] = x[i];
      }
    }
  }
};

namespace {

struct Work final : ProblemWorkspace {
  Work(const MechanismProblem::Impl& I, const MechanismProblem::Impl& C)
      : d(I.nz, I.m, I.f, I.n),
        s(I.nz, I.m, I.f, I.n),
        l(I.nz, I.m, I.f, I.n),
        cd(C.nz, C.m, C.f, 1),
        cs(C.nz, C.m, C.f, 1),
        c2(C.nz, C.m, C.f, 1),
        c3(C.nz, C.m, C.f, 1),
        c9(C.nz, C.m, C.f, 1),
        zStar(I.nz),
        zChord(C.nz),
        sigmaLast(C.f),
        zLast(C.nz),
        blockLu(C.blocks.luSize),
        blockPiv(C.blocks.pivSize),
        blockIn(C.m),
        blockOut(C.m),
        blockScratch(C.blocks.maxSize),
        stepLu(C.blocks.maxSize * C.blocks.maxSize),
        stepPiv(C.blocks.maxSize),
        stepX(C.blocks.maxSize),
        sigmaKinematics(C.f),
        sigmaDotKinematics(C.f),
        sigmaTwo(C.f),
        sigmaDotTwo(C.f),
        sigma(C.f),
        sigmaDot(C.f),
        sigmaDdot(C.f),
        luStar(I.m * I.m),
        pivStar(I.m),
        x0(I.m),
        x1(I.m),
        dualIn(C.m * 2 * (MechanismProblem::kMaxFree + 1)),
        dualSolve(C.m * 2 * (MechanismProblem::kMaxFree + 1)),
        dualScratch(C.blocks.maxSize * 2 * (MechanismProblem::kMaxFree + 1)),
        mu(I.f),
        nu(I.nz),
        fScratch(I.f),
        meeSym(I.n, I.n),
        meeQ(I.n),
        h(I.n),
        a1(I.n),
        keeQ(I.n),
        ctV(I.n),
        meeA(I.n),
        ctA(I.n),
        meeV(I.n),
        along(I.n),
        vel(I.n),
        uq(I.n),
        muCt(I.n),
        muCtT(I.n),
        muKee(I.n),
        muMee(I.n),
        qKey(I.n),
        vKey(I.n),
        aKey(I.n) {
    // The chord system's dual buffers, whose rows a masked pass leaves alone (Impl::constraints()).
    cs.clear(2 * C.f);
    c2.clear(2);
    c3.clear(3);
    c9.clear(9);
    timeCache.positions.assign(C.m, 0.0);
    timeCache.jac.assign(C.inactiveJacIndex.size(), 0.0);
    timeCache.phit.assign(C.m, 0.0);
    timeCache.quad.assign(C.m, 0.0);
  }
  Buffers<double> d;
  Buffers<ADS> s;
  Buffers<ADL> l;
  // The chord system (problems/mechanism/mechanism_problem.h): rigid coordinates and c = b q.
  Buffers<double> cd;
  Buffers<ADS> cs;
  Buffers<AD2> c2;
  Buffers<AD3> c3;  ///< the parameter product
  Buffers<AD9> c9;  ///< the Jacobians without free coordinates
  Vector zStar;     ///< full coordinates of the reference path
  Vector zChord;    ///< solved positions of the chord system
  // Warm start of Newton: the last solved (t, sigma, z).
  bool warm = false;
  double tLast = 0.0;
  Vector sigmaLast, zLast;
  // The chord system's Phi_u at the solved positions, factorised block by block (the kinematics' solves
  // and the dual passes'), and scratch of the block solves (by equation, by unknown, one block).
  std::vector<double> blockLu;
  std::vector<int> blockPiv;
  std::vector<double> blockIn, blockOut, blockScratch;
  // Scratch of one block's Newton step in the position solve.
  std::vector<double> stepLu;
  std::vector<int> stepPiv;
  std::vector<double> stepX;
  // The chord kinematics in cd were computed at (tKinematics, sigmaKinematics, sigmaDotKinematics):
  // the engine asks for the mass matrix, the Jacobians and the force (or the parameter product) at one
  // point.
  bool kinematicsValid = false, velocitiesValid = false;
  double tKinematics = 0.0;
  Vector sigmaKinematics, sigmaDotKinematics;
  // The same for the two-direction dual kinematics in c2 (twoDirectionKinematics()).
  bool twoValid = false;
  int twoSeed = 0;
  double tTwo = 0.0;
  Vector sigmaTwo, sigmaDotTwo;
  // sigma = (free coordinates, b q) and its derivatives at the current call.
  Vector sigma, sigmaDot, sigmaDdot;
  // Phi_u at the solved positions, factorised (the implicit-function step of the dual passes).
  std::vector<double> luStar;
  std::vector<int> pivStar;
  std::vector<double> x0, x1;  ///< scratch of the dual solves (kinematics())
  // The chord system's dual solves in all directions at once (Impl::blockSolveActive()).
  std::vector<double> dualIn, dualSolve, dualScratch;
  MechanismProblem::Impl::TimeCache timeCache;  ///< the chord system's parts that depend on time alone
  Vector mu, nu, fScratch;
  // The symmetric part of M_ee: once per solve for a workspace made for a fixed p.
  bool parametersFixed = false;
  Matrix meeSym;
  Matrix meeRotationSym;  ///< M_ee^xy's of a spatial member (View::meeRotation), empty for a plate
  // Products of the modal coordinates with the invariant matrices (modalProducts()), the member's
  // moments, and the q, q', a they were formed from (kept only for a fixed p).
  Vector meeQ, h, a1, keeQ, ctV, meeA, ctA, meeV, along, vel, uq;
  // Products of mu's modal part with the invariant matrices (chordStateVjp()).
  Vector muCt, muCtT, muKee, muMee;
  double moments[kMoments] = {};
  Vector qKey, vKey, aKey;
  bool qKept = false, vKept = false, aKept = false, aZero = false, vJacobian = false, aJacobian = false;
};

Work& workOf(ProblemWorkspace* ws) {
  assert(ws != nullptr);
  return static_cast<Work&>(*ws);
}

/// The dependent coordinates of the chord system at (t, sigma) into w.zChord (see the header on
/// determinism). They depend on the modal coordinates only through c = b q, the last entry of sigma.
void solvePositions(const MechanismProblem::Impl& C, double t, const Vector& sigma, Work& w) {
  Buffers<double>& B = w.cd;
  B.b[0] = 1.0;
  if (w.warm && t == w.tLast && sigma == w.sigmaLast) {
    // The same point as the last call (the adjoint asks for the Jacobians and the parameter product
    // at one point): the positions are a function of (t, sigma), so they are the last ones.
    w.zChord = w.zLast;
    return;
  }
  const double tStart = w.warm ? w.tLast : 0.0;
  const Vector& yStart = w.warm ? w.sigmaLast : C.yInitial;
  const Vector& zStart = w.warm ? w.zLast : C.zInitial;
  for (int i = 0; i < C.nz; ++i) B.z[i] = zStart(i);
  // Continuation in steps that move no driver and no minimal coordinate by more than 0.25 (rad or m),
  // so that Newton stays on the branch (assembly mode) it started on.
  double distance = C.driverDistance(tStart, t);
  for (int i = 0; i < C.f; ++i) distance = std::max(distance, std::abs(sigma(i) - yStart(i)));
  // A million pieces is 250000 rad or m between two calls (the slider-crank moves by 400 in a whole
  // run): beyond it a driver's speed or a diverged coordinate (inf, NaN) would make the continuation
  // run for hours, and the conversion to int would be undefined.
  const double pieces = std::ceil(distance / 0.25);
  if (!(pieces <= 1e6)) {
    throw NumericalError("the mechanism's drivers or free coordinates move by " + std::to_string(distance) +
                             " (rad or m) between two evaluations, more than the position solve follows; a "
                             "driver's speed or the motion is far too large",
                         t);
  }
  const int steps = std::max(1, static_cast<int>(pieces));
  // Block by block (Impl::solveBlocks()), from the last solution; the last piece is polished, so that
  // the positions are a function of (t, sigma) alone.
  for (int k = 1; k <= steps; ++k) {
    const double theta = static_cast<double>(k) / steps;
    const double tk = k == steps ? t : tStart + (t - tStart) * theta;
    for (int i = 0; i < C.f; ++i)
      B.z[C.independent[i]] = k == steps ? sigma(i) : yStart(i) + (sigma(i) - yStart(i)) * theta;
    C.solveBlocks(tk, B, k == steps, w.stepLu.data(), w.stepPiv.data(), w.stepX.data(), &w.timeCache);
  }
  for (int i = 0; i < C.nz; ++i) w.zChord(i) = B.z[i];
  w.warm = true;
  w.tLast = t;
  w.sigmaLast = sigma;
  w.zLast = w.zChord;
}

/// Which part of kinematics(): the position level (z, Phi_u factorised, R), the velocity level (z',
/// zeta; needs the position level of the same point in B), or both.
enum class Part { All, Positions, Velocities };

/// z, z', zeta, R at (t, y, y') in scalar type T with nd derivative directions: y, y' and b are given in
/// B.y, B.v, B.b; zStar holds the solved positions (and for dual passes w.luStar, or for the chord
/// system w.blockLu, the factorised Phi_u).
/// known (dual passes whose b is constant): the double kinematics of the same point (all parts, at the
/// same y'). Its R's dependent rows are the implicit function's derivatives, du = R_u dy, and its R, z'
/// and zeta are the solves' values; without it one Newton correction in dual numbers gives du (b may
/// then carry derivatives) and the solves refine their own double solution.
template <typename T>
void kinematics(const MechanismProblem::Impl& I, double t, Buffers<T>& B, Work& w, const Vector& zStar,
                int nd, Part part = Part::All, const Buffers<double>* known = nullptr) {
  const T zero = Make<T>::constant(0.0, nd);
  const int m = I.m, f = I.f, nz = I.nz;
  // Phi_u^{-1}: in double a factorisation at this point, kept in w.luStar for the dual passes; in dual
  // numbers that factorisation of the same point and one step of iterative refinement,
  // x = x0 + Phi_u0^{-1} (b - Phi_u x0) with x0 = Phi_u0^{-1} b0, whose derivative
  // Phi_u0^{-1} (b' - Phi_u' x0) is exact: no factorisation in dual numbers.
  // With `known`, x0 is its solution (value, the full vector of nz whose dependent rows are taken) and
  // only the derivatives are solved, one double solve per direction.
  // The chord system solves by block forward substitution in the block-triangular order
  // (Impl::Blocks), with its blocks factorised in w.blockLu; its dual passes always have `known`.
  const bool blocks = !I.blocks.empty();
  // The chord system's dual passes evaluate only the rows that depend on sigma (Impl::rowActive).
  const char* rowMask = nullptr;
  if constexpr (!std::is_same_v<T, double>) {
    if (blocks) rowMask = I.rowActive.data();
  }
  auto solve = [&](const double* value) {  // B.rhs = Phi_u^{-1} B.rhs
    if constexpr (std::is_same_v<T, double>) {
      if (blocks) {
        std::copy(B.rhs.begin(), B.rhs.end(), w.blockIn.begin());
        I.blockSolve(B.jac.data(), w.blockLu.data(), w.blockPiv.data(), w.blockIn.data(), B.rhs.data(),
                     w.blockScratch.data());
      } else {
        luSolve(B.lu.data(), B.piv.data(), m, B.rhs.data());
      }
    } else {
      double* x0 = w.x0.data();
      double* d = w.x1.data();
      if (blocks) {
        // The value is known's, x0; the derivatives are Phi_u^{-1} (b' - Phi_u' x0), in all directions
        // at once, with Phi_u' on its structural entries only.
        assert(known != nullptr);
        const MechanismProblem::Impl::Blocks& bl = I.blocks;
        const int* eq = bl.eq.data();
        const int* allStart = bl.allStart.data();
        const int* allIndex = bl.allIndex.data();
        const int* allUnk = bl.allUnk.data();
        const T* rhs = B.rhs.data();
        const T* jac = B.jac.data();
        // Only the blocks that depend on sigma (Blocks::active): the others' derivatives are zero.
        const int* start = bl.start.data();
        double* in = w.dualIn.data();
        double* dd = w.dualSolve.data();
        for (int i = 0; i < m; ++i) x0[i] = value[I.dependent[i]];
        for (int b : bl.activeList) {
          for (int p = start[b]; p < start[b + 1]; ++p) {
            const int q = eq[p];
            for (int e = 0; e < nd; ++e) {
              double v = rhs[q].derivatives()(e);
              for (int k = allStart[p]; k < allStart[p + 1]; ++k)
                v -= jac[allIndex[k]].derivatives()(e) * x0[allUnk[k]];
              in[nd * q + e] = v;
            }
          }
        }
        I.blockSolveActive(known->jac.data(), w.blockLu.data(), w.blockPiv.data(), in, dd,
                           w.dualScratch.data(), nd);
        for (int i = 0; i < m; ++i) {
          B.rhs[i] = Make<T>::constant(x0[i], nd);
          for (int e = 0; e < nd; ++e) B.rhs[i].derivatives()(e) = dd[nd * i + e];
        }
        return;
      }
      if (known != nullptr) {
        for (int i = 0; i < m; ++i) x0[i] = value[I.dependent[i]];
      } else {
        for (int i = 0; i < m; ++i) x0[i] = B.rhs[i].value();
        luSolve(w.luStar.data(), w.pivStar.data(), m, x0);
      }
      for (int j = 0; j < m; ++j) {
        const T* column = B.jac.data() + m * I.dependent[j];
        for (int i = 0; i < m; ++i) B.rhs[i] -= column[i] * x0[j];
      }
      if (known != nullptr) {
        for (int e = 0; e < nd; ++e) {
          for (int i = 0; i < m; ++i) d[i] = B.rhs[i].derivatives()(e);
          luSolve(w.luStar.data(), w.pivStar.data(), m, d);
          for (int i = 0; i < m; ++i) B.rhs[i].derivatives()(e) = d[i];
        }
        for (int i = 0; i < m; ++i) B.rhs[i].value() = x0[i];
      } else {
        luSolve(w.luStar.data(), w.pivStar.data(), m, B.rhs.data());
        for (int i = 0; i < m; ++i) B.rhs[i] += x0[i];
      }
    }
  };
  assert(rowMask == nullptr || part == Part::All);  // the sines and cosines come from the position part
  if (part != Part::Velocities) {
    for (int i = 0; i < nz; ++i) B.z[i] = Make<T>::constant(zStar(i), nd);
    for (int i = 0; i < f; ++i) B.z[I.independent[i]] = B.y[i];
    if constexpr (!std::is_same_v<T, double>) {
      if (known != nullptr) {
        for (int i = 0; i < m; ++i) {
          const int u = I.dependent[i];
          T du = zero;
          for (int j = 0; j < f; ++j) du += known->R[u + nz * j] * B.y[j];
          B.z[u] = Make<T>::withDerivatives(zStar(u), du);
        }
      } else {
        // u = u* - Phi_u^{-1} Phi(z): the value u*, the derivative of the implicit function.
        I.constraints(t, B, false, false, zero);
        for (int i = 0; i < m; ++i) B.rhs[i] = B.phi[i];
        luSolve(w.luStar.data(), w.pivStar.data(), m, B.rhs.data());
        for (int i = 0; i < m; ++i)
          B.z[I.dependent[i]] = Make<T>::withDerivatives(zStar(I.dependent[i]), -B.rhs[i]);
      }
    }
    if constexpr (!std::is_same_v<T, double>) {
      if (rowMask != nullptr) {
        // The bodies' sines and cosines: the double kinematics' (of the same angles' bits) and their
        // derivatives, instead of one more sincos per body.
        for (int k = 0; k <= I.nr; ++k) {
          const T& angle = B.z[I.bodyOffset(k) + 2];
          B.sn[k] = Make<T>::constant(known->sn[k], nd);
          B.cs[k] = Make<T>::constant(known->cs[k], nd);
          if (!I.zActive[I.bodyOffset(k) + 2]) continue;
          B.sn[k].derivatives() = known->cs[k] * angle.derivatives();
          B.cs[k].derivatives() = -known->sn[k] * angle.derivatives();
        }
      }
    }
    if constexpr (std::is_same_v<T, double>) {
      if (blocks) {
        I.constraintsCached(t, B, true, false, true, w.timeCache);
      } else {
        I.constraints(t, B, true, false, zero);
      }
    } else {
      I.constraints(t, B, true, false, zero, rowMask == nullptr, rowMask);
    }
    if constexpr (std::is_same_v<T, double>) {
      if (blocks) {
        I.factorBlocks(t, B.jac.data(), w.blockLu.data(), w.blockPiv.data());
      } else {
        for (int j = 0; j < m; ++j) {
          for (int i = 0; i < m; ++i) B.lu[i + m * j] = B.jac[i + m * I.dependent[j]];
        }
        if (!luFactor(B.lu.data(), B.piv.data(), m)) {
          throw NumericalError("the mechanism's constraints are singular (a lock-up or a redundant joint)",
                               t);
        }
        std::copy(B.lu.begin(), B.lu.end(), w.luStar.begin());
        std::copy(B.piv.begin(), B.piv.end(), w.pivStar.begin());
      }
    }
    // R: identity on the independent rows, -Phi_u^{-1} Phi_y on the dependent ones (column-major nz x f).
    for (int j = 0; j < f; ++j) {
      T* col = B.R.data() + nz * j;
      for (int i = 0; i < f; ++i) col[I.independent[i]] = Make<T>::constant(i == j ? 1.0 : 0.0, nd);
      for (int i = 0; i < m; ++i) B.rhs[i] = -B.jac[i + m * I.independent[j]];
      solve(known != nullptr ? known->R.data() + nz * j : nullptr);
      for (int i = 0; i < m; ++i) col[I.dependent[i]] = B.rhs[i];
    }
  }
  if (part == Part::Positions) return;
  // z' = R y' - Phi_u^{-1} Phi_t (Phi_t of the position pass: the constraint pass below does not
  // touch the Jacobian).
  for (int i = 0; i < m; ++i) {
    T s = B.phit[i];
    for (int j = 0; j < f; ++j) s += B.jac[i + m * I.independent[j]] * B.v[j];
    B.rhs[i] = -s;
  }
  solve(known != nullptr ? known->zd.data() : nullptr);
  for (int j = 0; j < f; ++j) B.zd[I.independent[j]] = B.v[j];
  for (int i = 0; i < m; ++i) B.zd[I.dependent[i]] = B.rhs[i];
  // zeta = -Phi_u^{-1} gamma on the dependent rows.
  // The position pass of the same call left B.sn, B.cs at this B.z (dual numbers keep no angle's bits).
  if constexpr (std::is_same_v<T, double>) {
    if (blocks) {
      I.constraintsCached(t, B, false, true, part != Part::All, w.timeCache);
    } else {
      I.constraints(t, B, false, true, zero, part != Part::All);
    }
  } else {
    I.constraints(t, B, false, true, zero, rowMask == nullptr && part != Part::All, rowMask);
  }
  for (int i = 0; i < m; ++i) B.rhs[i] = -B.quad[i];
  solve(known != nullptr ? known->zeta.data() : nullptr);
  for (int j = 0; j < f; ++j) B.zeta[I.independent[j]] = zero;
  for (int i = 0; i < m; ++i) B.zeta[I.dependent[i]] = B.rhs[i];
}

// Springs and dampers: tension k (l - l0) + d l' pulls point1 towards point2; their generalised forces are
// added to `out`. One code for the full-coordinate reference and the chord path (both after kinematics).
template <typename T>
void addSpringForces(const MechanismProblem::Impl& I, Buffers<T>& B, T* out, const T& zero) {
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

/// out = M(z) x - (with `rest`) Q(z, z', t): the generalised inertia, gravity, elastic and spring forces
/// (see the header). x has length nz.
template <typename T>
void generalizedForce(const MechanismProblem::Impl& I, const View& P, Buffers<T>& B, const T* x, bool rest,
                      T* out, const T& zero) {
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

/// r = R^T (M (R a + zeta) - Q) after kinematics().
template <typename T>
void residualFromKinematics(const MechanismProblem::Impl& I, const View& P, Buffers<T>& B, ConstVectorRef a,
                            int nd) {
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

template <typename T>
void loadInputs(const MechanismProblem::Impl& I, const View& P, Buffers<T>& B, ConstVectorRef y,
                ConstVectorRef v, int nd, bool seedState, bool seedB) {
  for (int i = 0; i < I.f; ++i) {
    B.y[i] = seedState ? Make<T>::variable(y(i), nd, i) : Make<T>::constant(y(i), nd);
    B.v[i] = seedState ? Make<T>::variable(v(i), nd, I.f + i) : Make<T>::constant(v(i), nd);
  }
  for (int i = 0; i < I.n; ++i)
    B.b[i] = seedB ? Make<T>::variable(P.b(i), nd, i) : Make<T>::constant(P.b(i), nd);
}

/// sigma = (free coordinates, b q) and its first two derivatives (a may be null: sigma'' not needed).
void chordInputs(const MechanismProblem::Impl& I, const View& P, ConstVectorRef y, ConstVectorRef v,
                 const double* a, Work& w) {
  const int k = I.nFree;
  double c = 0.0, cd = 0.0, cdd = 0.0;
  for (int i = 0; i < I.n; ++i) {
    c += P.b(i) * y(k + i);
    cd += P.b(i) * v(k + i);
    if (a != nullptr) cdd += P.b(i) * a[k + i];
  }
  for (int i = 0; i < k; ++i) {
    w.sigma(i) = y(i);
    w.sigmaDot(i) = v(i);
    w.sigmaDdot(i) = a != nullptr ? a[i] : 0.0;
  }
  w.sigma(k) = c;
  w.sigmaDot(k) = cd;
  w.sigmaDdot(k) = cdd;
}

/// The reference path in full coordinates: positions from the chord system, kinematics of z.
void fullPass(const MechanismProblem::Impl& I, const MechanismProblem::Impl& C, const View& P, double t,
              ConstVectorRef y, ConstVectorRef v, Work& w) {
  chordInputs(I, P, y, v, nullptr, w);
  w.kinematicsValid = false;  // cd and the factorisations are overwritten below
  solvePositions(C, t, w.sigma, w);
  for (int i = 0; i < I.base + 3; ++i) w.zStar(i) = w.zChord(i);
  for (int i = 0; i < I.n; ++i) w.zStar(I.base + 3 + i) = y(I.nFree + i);
  loadInputs(I, P, w.d, y, v, 0, false, false);
  kinematics(I, t, w.d, w, w.zStar, 0);
}

template <typename T>
void stateJacobians(const MechanismProblem::Impl& I, const View& P, double t, ConstVectorRef y,
                    ConstVectorRef v, ConstVectorRef a, MatrixRef ry, MatrixRef rv, Buffers<T>& B, Work& w) {
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
void chordRowProduct(const MechanismProblem::Impl& I, const View& P, double t, ConstVectorRef y,
                     ConstVectorRef v, ConstVectorRef a, ConstVectorRef mu, VectorRef out, Buffers<T>& B,
                     Work& w) {
  const int nd = I.n;
  loadInputs(I, P, B, y, v, nd, false, true);
  kinematics(I, t, B, w, w.zStar, nd);
  residualFromKinematics(I, P, B, a, nd);
  for (int i = 0; i < I.f; ++i) {
    const auto& d = B.r[i].derivatives();
    for (int j = 0; j < I.n; ++j) out(P.bOffset() + j) += mu(i) * d(j);
  }
}

// ---- The chord path: the production path of every evaluation (see the header). ----

/// The symmetric part of M_ee (View::mee), kept for a whole solve when the workspace was made for p.
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

/// The symmetric part of M_ee^xy (View::meeRotation) after meeOf(): the same matrix for a plate.
const Matrix& meeRotationOf(const View& P, const Work& w) { return P.spatial ? w.meeRotationSym : w.meeSym; }

/// Whether x[0, n) has the bits kept in key (kept: a workspace made for a fixed p).
bool keptBits(const double* x, const Vector& key, bool kept) {
  return kept && std::memcmp(x, key.data(), sizeof(double) * key.size()) == 0;
}

/// The products of q, q', q'' = a with the invariant matrices into the workspace (M_ee q, h = c2 +
/// M_ee q, A1 = a0 + Ct^T q, K_ee q, Ct q', M_ee a; with `jacobian` also Ct a and M_ee q') and the
/// member's moments (enum Moment). a == nullptr stands for a = 0. O(n^2). For a workspace made for a
/// fixed p, the products of q, of q' and of a are kept with the bits they were formed from: the engine
/// asks for the mass matrix, the Jacobians, the force and the parameter product at one point.
/// mee is M_ee (the modal mass, M_ee a), rotation M_ee^xy (h, J_w, M_ee^xy q'): one matrix for a plate.
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

/// The chord system's generalised force out = M z'' - Q (x = z'') on the rigid coordinates and c: the
/// rigid bodies, gravity, the springs, and the member's frame rows written with its moments (the same
/// terms as generalizedForce()); the modal rows are modalRow()'s. phi = (rho0, rho1, beta'', beta'), the
/// frame scalars the modal rows depend on.
template <typename T>
void chordForce(const MechanismProblem::Impl& C, const View& P, Buffers<T>& B, const T* x, const T* mom,
                T* out, T* phi, const T& zero) {
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

/// B.r = R^T (M (R sigma'' + zeta) - Q) of the chord system after its kinematics.
template <typename T>
void chordResidual(const MechanismProblem::Impl& C, const View& P, Buffers<T>& B, const T* sigmaDdot,
                   const T* mom, T* phi, const T& zero) {
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

/// Positions (block by block) and kinematics of the chord system in double at w.sigma, w.sigmaDot; also
/// factorises Phi_u's blocks into w.blockLu for the dual passes. Nothing to do when they are those of the
/// last call; with `anyVelocity` (the mass matrix, which does not depend on the velocities) any sigma' will
/// do.
void chordKinematics(const MechanismProblem::Impl& C, double t, Work& w, bool anyVelocity = false) {
  Buffers<double>& B = w.cd;
  if (!(w.kinematicsValid && t == w.tKinematics && w.sigma == w.sigmaKinematics)) {
    solvePositions(C, t, w.sigma, w);
    for (int i = 0; i < C.f; ++i) B.y[i] = w.sigma(i);
    B.b[0] = 1.0;
    kinematics(C, t, B, w, w.zChord, 0, Part::Positions);
    w.kinematicsValid = true;
    w.velocitiesValid = false;
    w.tKinematics = t;
    w.sigmaKinematics = w.sigma;
  }
  if (anyVelocity || (w.velocitiesValid && w.sigmaDot == w.sigmaDotKinematics)) return;
  for (int i = 0; i < C.f; ++i) B.v[i] = w.sigmaDot(i);
  kinematics(C, t, B, w, w.zChord, 0, Part::Velocities);
  w.velocitiesValid = true;
  w.sigmaDotKinematics = w.sigmaDot;
}

/// The modal row l without the b rho_c term: the member's F_q (docs/design.md §3),
///   F_q = C1^T rho + A1 beta'' + M_ee a + K_ee q - 2 beta' Ct q' - h beta'^2,
/// from the products of modalProducts() and phi = (rho0, rho1, beta'', beta').
inline double modalRow(const View& P, const Work& w, const double* phi, int l) {
  return P.c1(0, l) * phi[0] + P.c1(1, l) * phi[1] + w.a1(l) * phi[2] + w.meeA(l) + w.keeQ(l) -
         2.0 * phi[3] * w.ctV(l) - w.h(l) * (phi[3] * phi[3]);
}

/// dF_q,l/dphi (phi = (rho0, rho1, beta'', beta')).
inline void modalRowPhi(const View& P, const Work& w, double betaDot, int l, double* u) {
  u[0] = P.c1(0, l);
  u[1] = P.c1(1, l);
  u[2] = w.a1(l);
  u[3] = -2.0 * w.ctV(l) - 2.0 * w.h(l) * betaDot;
}

/// d(mu . r)/dp at fixed kinematics for the invariants other than b (r is linear in them): nu = R mu
/// on the member's coordinates (frame, q), the member's z, z', z'' (frame pointers of 3, modal of n).
void memberParameterProduct(const MechanismProblem::Impl& I, const View& P, const double* zf,
                            const double* zdf, const double* xf, const double* q, const double* qd,
                            const double* qdd, const Vector& nuv, VectorRef out) {
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

}  // namespace

MechanismProblem::MechanismProblem(const Mechanism& mechanism, int modeCount, bool spatialMember)
    : mechanism_(mechanism), modes_(modeCount), impl_(std::make_unique<Impl>()) {
  impl_->spatial = spatialMember;
  if (modeCount < 1 || modeCount > kMaxModes) {
    throw std::invalid_argument("modeCount = " + std::to_string(modeCount) + " must be in [1, " +
                                std::to_string(kMaxModes) + "]");
  }
  mechanism_.validate();
  if (static_cast<int>(mechanism_.free.size()) > kMaxFree) {
    throw std::invalid_argument("mechanism.free lists " + std::to_string(mechanism_.free.size()) +
                                " coordinates; at most " + std::to_string(kMaxFree) + " are supported");
  }
  Impl& I = *impl_;
  const Mechanism& M = mechanism_;
  I.nr = static_cast<int>(M.rigidBodies.size());
  I.n = modeCount;
  I.base = 3 * I.nr;
  I.nz = I.base + 3 + I.n;
  I.m = M.constraintCount();
  I.nFree = static_cast<int>(M.free.size());
  I.f = I.nFree + I.n;
  I.length = M.member.length;
  I.gravity = M.gravity;
  for (const RigidBody& b : M.rigidBodies) {
    I.mass.push_back(b.mass);
    I.inertia.push_back(b.inertia);
  }
  I.zInitial = Vector::Zero(I.nz);
  for (int k = 0; k < I.nr; ++k) {
    I.zInitial.segment<2>(3 * k) = M.rigidBodies[k].position;
    I.zInitial(3 * k + 2) = M.rigidBodies[k].angle;
  }
  I.zInitial.segment<2>(I.base) = M.member.position;
  I.zInitial(I.base + 2) = M.member.angle;
  std::vector<bool> isFree(I.nz, false);
  I.vInitial = Vector::Zero(I.f);
  for (int k = 0; k < I.nFree; ++k) {
    const FreeCoordinate& fc = M.free[k];
    const int index = 3 * I.bodyIndex(M, fc.body) + static_cast<int>(fc.coordinate);
    I.independent.push_back(index);
    isFree[index] = true;
    I.vInitial(k) = fc.velocity;
  }
  for (int i = 0; i < I.n; ++i) {
    I.independent.push_back(I.base + 3 + i);
    isFree[I.base + 3 + i] = true;
  }
  for (int i = 0; i < I.base + 3; ++i) {
    if (!isFree[i]) I.dependent.push_back(i);
  }
  auto angleOf = [&](const std::string& body) {
    if (body == "ground") return 0.0;
    if (body == M.member.name) return M.member.angle;
    for (const RigidBody& b : M.rigidBodies) {
      if (b.name == body) return b.angle;
    }
    return 0.0;
  };
  for (const Joint& j : M.joints) {
    Row r;
    r.p1 = I.pointRef(M, j.body1, j.point1);
    r.p2 = I.pointRef(M, j.body2, j.point2);
    r.body1 = I.bodyIndex(M, j.body1);
    r.body2 = I.bodyIndex(M, j.body2);
    r.axis = j.axis.normalized();
    const Driver* driver = nullptr;
    for (const Driver& d : M.drivers) {
      if (d.joint == j.name) driver = &d;
    }
    r.name = j.name;
    const double relative = angleOf(j.body2) - angleOf(j.body1);
    if (j.type == JointType::Revolute || j.type == JointType::Fixed) {
      r.kind = Row::Revolute;
      I.rows.push_back(r);
      if (j.type == JointType::Fixed) {
        r.kind = Row::Angle;
        r.offset = relative;
        I.rows.push_back(r);
      }
      if (driver != nullptr) {
        r.kind = Row::DriveAngle;
        r.offset = driver->offset;
        r.law = driver->law;
        r.name = driver->name;
        I.rows.push_back(r);
      }
    } else {
      r.kind = Row::Angle;
      r.offset = relative;
      I.rows.push_back(r);
      r.kind = Row::Line;
      I.rows.push_back(r);
      if (driver != nullptr) {
        r.kind = Row::DriveLine;
        r.offset = driver->offset;
        r.law = driver->law;
        r.name = driver->name;
        I.rows.push_back(r);
      }
    }
  }
  for (int r = 0, i = 0; r < static_cast<int>(I.rows.size()); ++r) {
    const Row& row = I.rows[r];
    I.rowFirst.push_back(i);
    i += row.kind == Row::Revolute ? 2 : 1;
    I.rowOf.resize(i, r);
    switch (row.kind) {
      case Row::Revolute:
        I.equationNames.push_back(row.name + ".x");
        I.equationNames.push_back(row.name + ".y");
        break;
      case Row::Angle:
        I.equationNames.push_back(row.name + ".angle");
        break;
      case Row::Line:
        I.equationNames.push_back(row.name + ".line");
        break;
      default:
        I.equationNames.push_back(row.name);
    }
  }
  for (int k = 0; k <= I.nr; ++k) {
    const std::string& body = k == I.nr ? M.member.name : M.rigidBodies[k].name;
    for (const char* c : {".x", ".y", ".angle"}) I.coordinateNames.push_back(body + c);
  }
  for (int i = 0; i < I.n; ++i) I.coordinateNames.push_back(M.member.name + ".q" + std::to_string(i));
  for (const Spring& s : M.springs) {
    I.springs.push_back(SpringRef{I.pointRef(M, s.body1, s.point1), I.pointRef(M, s.body2, s.point2),
                                  s.stiffness, s.restLength, s.damping});
  }
  I.yInitial = Vector::Zero(I.f);
  for (int k = 0; k < I.nFree; ++k) I.yInitial(k) = I.zInitial(I.independent[k]);
  // Assemble at t = 0 from the described positions (q = 0, so b does not enter).
  Buffers<double> assembly(I.nz, I.m, I.f, I.n);
  for (int i = 0; i < I.nz; ++i) assembly.z[i] = I.zInitial(i);
  for (int i = 0; i < I.n; ++i) assembly.b[i] = 0.0;
  try {
    I.newton(0.0, assembly, -1, 1e-12);
  } catch (const NumericalError& e) {
    throw std::invalid_argument(std::string("mechanism: the initial positions do not assemble at t = 0: ") +
                                e.what());
  }
  for (int i = 0; i < I.nz; ++i) I.zInitial(i) = assembly.z[i];
  // The chord system: the same bodies and constraints with one coordinate c = b q in place of q (one
  // "mode" whose displacement row at B is 1), independent like the free coordinates.
  chord_ = std::make_unique<Impl>(I);
  Impl& C = *chord_;
  C.n = 1;
  C.nz = I.base + 4;
  C.f = I.nFree + 1;
  C.independent.assign(I.independent.begin(), I.independent.begin() + I.nFree);
  C.independent.push_back(I.base + 3);
  C.zInitial = I.zInitial.head(I.base + 4);
  C.zInitial(I.base + 3) = 0.0;
  C.yInitial = Vector::Zero(C.f);
  C.yInitial.head(I.nFree) = I.yInitial.head(I.nFree);
  C.vInitial = Vector::Zero(C.f);
  C.buildBlocks();
}

MechanismProblem::~MechanismProblem() = default;

int MechanismProblem::coordinateCount() const { return impl_->f; }
int MechanismProblem::freeCount() const { return impl_->nFree; }
int MechanismProblem::parameterSize() const {
  return 4 + 5 * modes_ + (impl_->spatial ? 4 : 3) * modes_ * modes_;
}
int MechanismProblem::fullCoordinateCount() const { return impl_->nz; }
int MechanismProblem::memberOffset() const { return impl_->base; }

std::unique_ptr<ProblemWorkspace> MechanismProblem::createModelWorkspace() const {
  return std::make_unique<Work>(*impl_, *chord_);
}

std::unique_ptr<ProblemWorkspace> MechanismProblem::createModelWorkspaceFor(ConstVectorRef p) const {
  auto w = std::make_unique<Work>(*impl_, *chord_);
  meeOf(View(modes_, p.data(), impl_->spatial), *w);
  w->parametersFixed = true;
  return w;
}

void MechanismProblem::initialCoordinates(ConstVectorRef, VectorRef y0, VectorRef v0) const {
  y0 = impl_->yInitial;
  v0 = impl_->vInitial;
}

namespace {

/// Dual numbers that are constants.
template <typename ADT>
void constants(const double* values, int count, int nd, ADT* out) {
  for (int i = 0; i < count; ++i) out[i] = Make<ADT>::constant(values[i], nd);
}

/// Widens the dual numbers of the chord system's kinematics from `from` to `to` directions (the
/// kinematics depend on sigma and sigma' only, so they run in fewer directions than the residual).
void widen(const MechanismProblem::Impl& C, Buffers<ADS>& B, int from, int to) {
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

}  // namespace

namespace {

/// The derivatives of the chord residual rho (dRho[i + k e]) and of phi (dPhi[4 e + i]) in the
/// directions e = sigma''_j (j < k), A1 . a (k), C1 a (k + 1, k + 2): the acceleration part of
/// chordForce() (no gravity, velocity or spring terms), linear, at the kinematics of w.cd.
void accelerationDerivatives(const MechanismProblem::Impl& C, const View& P, Work& w, const double* mom,
                             double* dRho, double* dPhi) {
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
void massAndForce(const MechanismProblem::Impl& I, const MechanismProblem::Impl& C, double t,
                  ConstVectorRef y, ConstVectorRef v, ConstVectorRef p, MatrixRef mass, VectorRef f, Work& w,
                  bool massOnly) {
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

/// The chord system's kinematics in two directions, sigma_j (0) and sigma'_j (1), into B with nd
/// directions, the two at dy and dv (the others zero). Needs chordKinematics() at the same point (its R
/// gives the positions' derivatives).
template <typename ADT>
void twoDirectionKinematics(const MechanismProblem::Impl& C, double t, Work& w, int j, int nd, int dy, int dv,
                            Buffers<ADT>& B) {
  Buffers<AD2>& A = w.c2;
  // The adjoint asks for the Jacobians and the parameter product at one point; without free
  // coordinates both seed (c, c').
  if (!(w.twoValid && j == w.twoSeed && t == w.tTwo && w.sigma == w.sigmaTwo &&
        w.sigmaDot == w.sigmaDotTwo)) {
    for (int i = 0; i < C.f; ++i) {
      A.y[i] = i == j ? AD2(w.sigma(i), 2, 0) : Make<AD2>::constant(w.sigma(i), 2);
      A.v[i] = i == j ? AD2(w.sigmaDot(i), 2, 1) : Make<AD2>::constant(w.sigmaDot(i), 2);
    }
    A.b[0] = Make<AD2>::constant(1.0, 2);
    kinematics(C, t, A, w, w.zChord, 2, Part::All, &w.cd);
    w.twoValid = true;
    w.twoSeed = j;
    w.tTwo = t;
    w.sigmaTwo = w.sigma;
    w.sigmaDotTwo = w.sigmaDot;
  }
  auto put = [&](const AD2& x, ADT& out) {
    out = Make<ADT>::constant(x.value(), nd);
    out.derivatives()(dy) = x.derivatives()(0);
    out.derivatives()(dv) = x.derivatives()(1);
  };
  for (int i = 0; i < C.nz; ++i) {
    put(A.z[i], B.z[i]);
    put(A.zd[i], B.zd[i]);
    put(A.zeta[i], B.zeta[i]);
  }
  for (int i = 0; i < C.nz * C.f; ++i) put(A.R[i], B.R[i]);
  for (int i = 0; i <= C.nr; ++i) {
    put(A.sn[i], B.sn[i]);
    put(A.cs[i], B.cs[i]);
  }
  put(A.b[0], B.b[0]);
}

}  // namespace

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

namespace {

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
void dualChordResidual(const MechanismProblem::Impl& C, const View& P, double t, const double* mom, Work& w,
                       Buffers<ADT>& B, ADT* phi) {
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
void chordJacobians(const MechanismProblem::Impl& I, const MechanismProblem::Impl& C, const View& P, double t,
                    const double* mom, const Matrix& mee, MatrixRef ry, MatrixRef rv, Work& w,
                    Buffers<ADT>& B) {
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
void chordStateVjp(const MechanismProblem::Impl& I, const MechanismProblem::Impl& C, const View& P, double t,
                   const double* mom, const Matrix& mee, ConstVectorRef mu, VectorRef outY, VectorRef outV,
                   Work& w, Buffers<ADT>& B) {
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

/// The point (t, y, y', a) of the chord path's products: positions and kinematics (kept when they are
/// the last call's), the modal products (with the Jacobians' when `jacobian`) and the moments into mom;
/// returns the symmetric part of M_ee^xy (the Jacobians' and products' -beta'^2 h term; M_ee for a plate).
const Matrix& productPoint(const MechanismProblem::Impl& I, const MechanismProblem::Impl& C, const View& P,
                           double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, bool jacobian,
                           Work& w, double* mom) {
  const int nf = I.nFree;
  chordInputs(I, P, y, v, a.data(), w);
  chordKinematics(C, t, w);
  const Matrix& mee = meeOf(P, w);
  modalProducts(P, mee, meeRotationOf(P, w), y.data() + nf, v.data() + nf, a.data() + nf, jacobian, w, mom);
  return meeRotationOf(P, w);
}

/// chordStateVjp() with the dual numbers of the chord system's size.
void stateVjp(const MechanismProblem::Impl& I, const MechanismProblem::Impl& C, const View& P, double t,
              const double* mom, const Matrix& mee, ConstVectorRef mu, VectorRef outY, VectorRef outV,
              Work& w) {
  if (C.f == 1) {
    chordStateVjp(I, C, P, t, mom, mee, mu, outY, outV, w, w.c9);
  } else {
    chordStateVjp(I, C, P, t, mom, mee, mu, outY, outV, w, w.cs);
  }
}

}  // namespace

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

namespace {

/// out += (r_p)^T mu after chordKinematics() and modalProducts() (mom) at the point.
void parameterProduct(const MechanismProblem::Impl& I, const MechanismProblem::Impl& C, const View& P,
                      double t, ConstVectorRef y, ConstVectorRef v, ConstVectorRef a, ConstVectorRef mu,
                      const double* mom, Work& w, VectorRef out) {
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

}  // namespace

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

// ---- The reference path in full coordinates (tests). ----

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

double MechanismProblem::integrand(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef p,
                                   ProblemWorkspace*) const {
  const View P(modes_, p.data(), impl_->spatial);
  const int o = impl_->nFree;
  double s = 0.0;
  for (int i = 0; i < modes_; ++i) {
    for (int j = 0; j < modes_; ++j) s += y(o + i) * P.kee(i, j) * y(o + j);
  }
  return s;
}

void MechanismProblem::addIntegrandStateGradient(double, ConstVectorRef y, ConstVectorRef, ConstVectorRef p,
                                                 double scale, VectorRef gy, VectorRef,
                                                 ProblemWorkspace*) const {
  const View P(modes_, p.data(), impl_->spatial);
  const int o = impl_->nFree;
  for (int i = 0; i < modes_; ++i) {
    for (int j = 0; j < modes_; ++j) gy(o + i) += scale * (P.kee(i, j) + P.kee(j, i)) * y(o + j);
  }
}

void MechanismProblem::addIntegrandParameterGradient(double, ConstVectorRef y, ConstVectorRef,
                                                     ConstVectorRef p, double scale, VectorRef gp,
                                                     ProblemWorkspace*) const {
  const View P(modes_, p.data(), impl_->spatial);
  const int o = impl_->nFree;
  for (int j = 0; j < modes_; ++j) {
    for (int i = 0; i < modes_; ++i) gp(P.keeOffset() + i + modes_ * j) += scale * y(o + i) * y(o + j);
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

std::vector<MechanismProblem::ConstraintBlock> MechanismProblem::constraintBlocks() const {
  const Impl& C = *chord_;
  std::vector<ConstraintBlock> out;
  for (int b = 0; b < C.blocks.count(); ++b) {
    ConstraintBlock block;
    for (int p = C.blocks.start[b]; p < C.blocks.start[b + 1]; ++p) {
      block.equations.push_back(C.equationNames[C.blocks.eq[p]]);
      block.unknowns.push_back(C.coordinateNames[C.dependent[C.blocks.unk[p]]]);
      block.rows.push_back(C.blocks.eq[p]);
      block.columns.push_back(C.blocks.unk[p]);
    }
    block.affine = C.blocks.affine[b] != 0;
    block.timeOnly = C.blocks.active[b] == 0;
    out.push_back(block);
  }
  return out;
}

Eigen::MatrixXi MechanismProblem::constraintPattern() const {
  const Impl& C = *chord_;
  Eigen::MatrixXi pattern = Eigen::MatrixXi::Zero(C.m, C.m);
  for (int p = 0; p < C.m; ++p) {
    for (int k = C.blocks.allStart[p]; k < C.blocks.allStart[p + 1]; ++k)
      pattern(C.blocks.eq[p], C.blocks.allUnk[k]) = 1;
  }
  return pattern;
}

void MechanismProblem::constraintJacobian(double t, ConstVectorRef y, ConstVectorRef p, MatrixRef phiU,
                                          ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  const Impl& C = *chord_;
  Work& w = workOf(ws);
  w.mu.setZero();
  chordInputs(I, View(I.n, p.data(), I.spatial), y, w.mu, nullptr, w);
  chordKinematics(C, t, w, true);
  for (int j = 0; j < C.m; ++j) {
    for (int i = 0; i < C.m; ++i) phiU(i, j) = w.cd.jac[i + C.m * C.dependent[j]];
  }
}

void MechanismProblem::positionsBlockAndDense(double t, ConstVectorRef y, ConstVectorRef p, VectorRef z,
                                              VectorRef zDense, ProblemWorkspace* ws) const {
  const Impl& I = *impl_;
  const Impl& C = *chord_;
  Work& w = workOf(ws);
  w.mu.setZero();
  chordInputs(I, View(I.n, p.data(), I.spatial), y, w.mu, nullptr, w);
  w.kinematicsValid = false;
  solvePositions(C, t, w.sigma, w);
  z = w.zChord;
  Buffers<double> B(C.nz, C.m, C.f, 1);
  B.b[0] = 1.0;
  for (int i = 0; i < C.nz; ++i) B.z[i] = w.zChord(i);
  for (int i = 0; i < C.m; ++i) B.z[C.dependent[i]] += 1e-3;
  C.newton(t, B, -1, 1e-12);
  C.newton(t, B, 2, 0.0);
  for (int i = 0; i < C.nz; ++i) zDense(i) = B.z[i];
}

}  // namespace hindsight::mechanism
