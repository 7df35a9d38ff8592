// The mechanism's position constraints solved (docs/design.md §10; mechanism_problem.h, "The position
// solve" and "Determinism and cost"): Newton on all of them (assembly at t = 0, the tests' dense
// reference), the block-by-block solve in the BLT order with its grid polish, and the block forward
// substitutions with Phi_u that the kinematics and the dual passes use; with the rows that depend on time
// alone kept per time.
#include <hindsight/problems/mechanism/detail/system.h>

#include <algorithm>
#include <cmath>

namespace hindsight::mechanism::detail {

void System::constraintsCached(double t, Buffers<double>& B, bool jacobian, bool quadratic, bool trig,
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

double System::newton(double t, Buffers<double>& B, int iterations, double tol, bool quadratic) const {
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
    throw NumericalError("the mechanism cannot be assembled (Newton on the constraints did not converge)", t);
  }
  return step;
}

double System::driverDistance(double t0, double t1) const {
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

void System::evaluateBlock(double t, Buffers<double>& B, int b, bool jacobian) const {
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

void System::factorBlock(double t, const double* jac, int b, double* lu, int* piv) const {
  const int p0 = blocks.start[b], s = blocks.start[b + 1] - p0;
  for (int j = 0; j < s; ++j) {
    for (int i = 0; i < s; ++i) lu[i + s * j] = jac[blocks.eq[p0 + i] + m * dependent[blocks.unk[p0 + j]]];
  }
  if (s == 1 ? lu[0] == 0.0 : !luFactor(lu, piv, s)) {
    throw NumericalError("the mechanism's constraints are singular (a lock-up or a redundant joint)", t);
  }
}

double System::blockStep(double t, Buffers<double>& B, int b, double* lu, int* piv, double* x) const {
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

double System::pointComponent(const PointRef& r, Buffers<double>& B, double c, int k) const {
  if (r.body == kGround) return r.local(k);
  updateTrigOf(B, r.body);
  const double s = B.sn[r.body], cs = B.cs[r.body];
  const double sb0 = r.atB ? c + r.local(0) : 0.0 + r.local(0), sb1 = r.local(1);
  return B.z[bodyOffset(r.body) + k] + (k == 0 ? cs * sb0 - s * sb1 : s * sb0 + cs * sb1);
}

double System::pointDerivative(const PointRef& r, const Buffers<double>& B, double c, int k, int z) const {
  if (r.body == kGround) return 0.0;
  const int o = bodyOffset(r.body);
  if (z == o + k) return 1.0;
  if (z != o + 2) return 0.0;
  const double s = B.sn[r.body], cs = B.cs[r.body];
  const double sb0 = r.atB ? c + r.local(0) : 0.0 + r.local(0), sb1 = r.local(1);
  return k == 0 ? -(s * sb0 + cs * sb1) : cs * sb0 - s * sb1;
}

double System::equationValue(double t, Buffers<double>& B, int e, double c) const {
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

void System::solveBlocks(double t, Buffers<double>& B, bool polish, double* lu, int* piv, double* x,
                         TimeCache* cache) const {
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
        throw NumericalError("the mechanism's constraints are singular (a lock-up or a redundant joint)", t);
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
      if (step <= 1e-11 ||
          (it >= 1 && step <= 1e-7 && step < previous && step * step * step <= 1e-16 * previous * previous)) {
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

void System::factorBlocks(double t, const double* jac, double* lu, int* piv) const {
  for (int b = 0; b < blocks.count(); ++b)
    factorBlock(t, jac, b, lu + blocks.luOffset[b], piv + blocks.pivOffset[b]);
}

void System::blockSolve(const double* jac, const double* lu, const int* piv, const double* in, double* out,
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

void System::blockSolveActive(const double* jac, const double* lu, const int* piv, const double* in,
                              double* out, double* r, int nd) const {
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

}  // namespace hindsight::mechanism::detail
