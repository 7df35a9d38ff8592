// The planar mechanism compiled for evaluation (docs/design.md §10): sizes, the rigid bodies' mass and
// inertia, the joints and drivers as constraint rows, the springs, and the block-triangular (BLT) order
// of the position constraints. The rows' formulas (Phi, its Jacobian, Phi_t and gamma) are templates on
// the scalar type, so the double kinematics and every dual-number pass run one code and get one set of
// bits. The structural analysis at construction is in constraint_blocks.cpp, the solves (Newton, the
// block solves) in constraint_solve.cpp. A MechanismProblem holds two Systems: the full coordinates z (the
// tests' reference) and the chord system (the rigid coordinates and c = b q), both described in
// problems/mechanism/mechanism_problem.h. Internal to problems/mechanism/ (not installed).
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/mechanism/detail/dual.h>
#include <hindsight/problems/mechanism/mechanism.h>
#include <hindsight/problems/mechanism/mechanism_problem.h>

#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace hindsight::mechanism::detail {

constexpr int kGround = -1;

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
  /// (System::constraints()) writes only its rows, and dual numbers start uninitialised.
  void clear(int nd) {
    const T zero = Make<T>::constant(0.0, nd);
    for (auto* v : {&jac, &phi, &phit, &quad}) std::fill(v->begin(), v->end(), zero);
  }
};

struct System {
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

  PointRef pointRef(const Mechanism& mech, const std::string& body, const std::string& point) const;

  int bodyIndex(const Mechanism& mech, const std::string& body) const;

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
                         TimeCache& cache) const;

  /// Constraint row r's equations (from rowFirst[r] on): Phi, with `jacobian` its Jacobian added into
  /// B.jac (the caller zeroes it) and Phi_t, with `quadratic` gamma. Needs B.sn, B.cs at B.z and c, c'.
  template <typename T>
  void evaluateRow(double t, Buffers<T>& B, int r, bool jacobian, bool quadratic, const T& c, const T& cd,
                   const T& zero) const {
    const Row& row = rows[r];
    const int i = rowFirst[r];
    T* jrow = B.jac.data() + i;  // row i of the column-major m x nz matrix: stride m
    const int mm = m;
    // Value-initialised: a caller that passes quadratic = false never reads Q, but where GCC inlines this
    // into such a caller (constraint_solve.cpp) it cannot see that and warns.
    Pt<T> a{}, b{};
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
  double newton(double t, Buffers<double>& B, int iterations, double tol, bool quadratic = false) const;

  double driverDistance(double t0, double t1) const;
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
  std::vector<std::vector<Entry>> structure() const;

  /// Matching of equations to unknowns (augmenting paths) on the sparsity pattern of Phi_u, then
  /// Tarjan's strongly connected components of the graph "equation needs the unknown matched to
  /// another": the Dulmage-Mendelsohn (BLT) order, blocks in the order they can be solved. Throws
  /// std::invalid_argument when the pattern has no perfect matching (redundant or missing constraints).
  void buildBlocks();

  /// Phi and (with `jacobian`) the Jacobian rows of block b's equations at B.z (their other equations'
  /// too, which the block's rows compute alongside). The sines and cosines of the rows' bodies only:
  /// an angle row needs none.
  void evaluateBlock(double t, Buffers<double>& B, int b, bool jacobian) const;

  /// Block b's Jacobian (its rows of Phi_u in its unknowns, s x s column-major) into lu, factorised
  /// (piv); from B.jac.
  void factorBlock(double t, const double* jac, int b, double* lu, int* piv) const;

  /// One Newton step on block b (the earlier blocks' unknowns and the independent coordinates fixed):
  /// returns the step's size. lu, piv, x: scratch of the largest block.
  double blockStep(double t, Buffers<double>& B, int b, double* lu, int* piv, double* x) const;

  /// Component k of a point's position at B.z (the operations of point()).
  double pointComponent(const PointRef& r, Buffers<double>& B, double c, int k) const;

  /// d/dz of component k of a point's position at B.z after pointComponent() (which updated its body's
  /// sine and cosine): the entry addJT() adds, with its bits.
  double pointDerivative(const PointRef& r, const Buffers<double>& B, double c, int k, int z) const;

  /// Equation e's value alone at B.z, with the bits evaluateRow() gives it (c: the chord).
  double equationValue(double t, Buffers<double>& B, int e, double c) const;

  /// The dependent coordinates of B.z solved block by block at time t (independent ones fixed). A block
  /// affine in its unknowns is solved by one step from zero, exactly, and its result is a function of
  /// the earlier blocks and sigma alone. Any other block: Newton from B.z until the step is below 1e-11
  /// or the quadratic convergence predicts the next below 1e-16; with `polish`, its unknowns are then
  /// rounded to a grid of 2^-20 and Newton runs again from the grid point (two or three steps reach
  /// round-off), so that its result is a function of the grid point, the earlier blocks and sigma (see
  /// mechanism_problem.h). lu, piv, x: scratch of the largest block.
  /// With `cache` (polished solves), the blocks that depend on time alone are taken from it when it holds
  /// them at the bits of t, and kept in it otherwise.
  void solveBlocks(double t, Buffers<double>& B, bool polish, double* lu, int* piv, double* x,
                   TimeCache* cache = nullptr) const;

  /// Every block of Phi_u (from the m x nz jac) factorised into lu, piv (Blocks::luOffset, pivOffset).
  void factorBlocks(double t, const double* jac, double* lu, int* piv) const;

  /// out = Phi_u^{-1} in by block forward substitution (in by equation, out by unknown; Phi_u's entries
  /// from the m x nz jac, its blocks factorised by factorBlocks()). r: scratch of the largest block.
  void blockSolve(const double* jac, const double* lu, const int* piv, const double* in, double* out,
                  double* r) const;

  /// blockSolve() in nd directions at once (in[nd q + e] by equation, out[nd u + e] by unknown), over the
  /// active blocks only (Blocks::active): the others' unknowns are zero, as a dual pass's derivatives are.
  /// Each direction takes blockSolve()'s operations. r: scratch of nd times the largest block.
  void blockSolveActive(const double* jac, const double* lu, const int* piv, const double* in, double* out,
                        double* r, int nd) const;
};

}  // namespace hindsight::mechanism::detail

namespace hindsight::mechanism {

/// The two systems of a MechanismProblem (full coordinates, chord system).
struct MechanismProblem::Impl : detail::System {};

}  // namespace hindsight::mechanism
