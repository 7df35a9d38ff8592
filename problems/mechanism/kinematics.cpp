// The kinematics of the planar mechanism (docs/design.md §10; mechanism_problem.h, "The chord path" and
// "Derivatives are exact"): the positions by continuation and the block solve, z, z', zeta and R in double
// and in dual numbers (the implicit function's derivatives by block forward substitution), the chord
// system's inputs sigma, and the kinematics kept for the point last evaluated. The templates are
// instantiated at the end of this file for the scalar types the passes use.
#include <hindsight/problems/mechanism/detail/kinematics.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace hindsight::mechanism::detail {

void solvePositions(const System& C, double t, const Vector& sigma, Work& w) {
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
  // Block by block (System::solveBlocks()), from the last solution; the last piece is polished, so that
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

template <typename T>
void kinematics(const System& I, double t, Buffers<T>& B, Work& w, const Vector& zStar, int nd, Part part,
                const Buffers<double>* known) {
  const T zero = Make<T>::constant(0.0, nd);
  const int m = I.m, f = I.f, nz = I.nz;
  // Phi_u^{-1}: in double a factorisation at this point, kept in w.luStar for the dual passes; in dual
  // numbers that factorisation of the same point and one step of iterative refinement,
  // x = x0 + Phi_u0^{-1} (b - Phi_u x0) with x0 = Phi_u0^{-1} b0, whose derivative
  // Phi_u0^{-1} (b' - Phi_u' x0) is exact: no factorisation in dual numbers.
  // With `known`, x0 is its solution (value, the full vector of nz whose dependent rows are taken) and
  // only the derivatives are solved, one double solve per direction.
  // The chord system solves by block forward substitution in the block-triangular order
  // (System::Blocks), with its blocks factorised in w.blockLu; its dual passes always have `known`.
  const bool blocks = !I.blocks.empty();
  // The chord system's dual passes evaluate only the rows that depend on sigma (System::rowActive).
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
        const System::Blocks& bl = I.blocks;
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

void chordInputs(const System& I, const View& P, ConstVectorRef y, ConstVectorRef v, const double* a,
                 Work& w) {
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

void chordKinematics(const System& C, double t, Work& w, bool anyVelocity) {
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

template <typename ADT>
void twoDirectionKinematics(const System& C, double t, Work& w, int j, int nd, int dy, int dv,
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

// The scalar types of the passes: double (the kinematics), AD2 (two directions, kept for the Jacobians and
// the parameter product), ADS and ADL (the chord path with free coordinates and the full-coordinate
// reference); the two-direction kinematics widened to AD9 (the Jacobians without free coordinates) and
// AD3 (the parameter product).
template void kinematics<double>(const System&, double, Buffers<double>&, Work&, const Vector&, int, Part,
                                 const Buffers<double>*);
template void kinematics<AD2>(const System&, double, Buffers<AD2>&, Work&, const Vector&, int, Part,
                              const Buffers<double>*);
template void kinematics<ADS>(const System&, double, Buffers<ADS>&, Work&, const Vector&, int, Part,
                              const Buffers<double>*);
template void kinematics<ADL>(const System&, double, Buffers<ADL>&, Work&, const Vector&, int, Part,
                              const Buffers<double>*);
template void twoDirectionKinematics<AD9>(const System&, double, Work&, int, int, int, int, Buffers<AD9>&);
template void twoDirectionKinematics<AD3>(const System&, double, Work&, int, int, int, int, Buffers<AD3>&);

}  // namespace hindsight::mechanism::detail

namespace hindsight::mechanism {

using namespace detail;

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
