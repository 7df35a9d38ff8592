// The flexible member's floating-frame-of-reference terms (docs/design.md §3 and §10; §11 for a member
// that deforms in 3-D): the generalised inertia, gravity, elastic, spring and quadratic-velocity forces
// M(z) z'' - Q in full coordinates and on the chord system, their projection R^T (M z'' - Q), and the
// member's modal rows F_q from the products of q, q', a with the invariant matrices. Defined in
// member_forces.cpp. Internal to problems/mechanism/ (not installed).
#pragma once

#include <hindsight/problems/mechanism/detail/workspace.h>

namespace hindsight::mechanism::detail {

/// out = M(z) x - (with `rest`) Q(z, z', t): the generalised inertia, gravity, elastic and spring forces
/// (see mechanism_problem.h). x has length nz.
template <typename T>
void generalizedForce(const System& I, const View& P, Buffers<T>& B, const T* x, bool rest, T* out,
                      const T& zero);

/// r = R^T (M (R a + zeta) - Q) after kinematics().
template <typename T>
void residualFromKinematics(const System& I, const View& P, Buffers<T>& B, ConstVectorRef a, int nd);

/// B.r = R^T (M (R sigma'' + zeta) - Q) of the chord system after its kinematics.
template <typename T>
void chordResidual(const System& C, const View& P, Buffers<T>& B, const T* sigmaDdot, const T* mom, T* phi,
                   const T& zero);

/// The symmetric part of M_ee (View::mee), kept for a whole solve when the workspace was made for p.
const Matrix& meeOf(const View& P, Work& w);

/// The symmetric part of M_ee^xy (View::meeRotation) after meeOf(): the same matrix for a plate.
inline const Matrix& meeRotationOf(const View& P, const Work& w) {
  return P.spatial ? w.meeRotationSym : w.meeSym;
}

/// The products of q, q', q'' = a with the invariant matrices into the workspace (M_ee q, h = c2 +
/// M_ee q, A1 = a0 + Ct^T q, K_ee q, Ct q', M_ee a; with `jacobian` also Ct a and M_ee q') and the
/// member's moments (enum Moment). a == nullptr stands for a = 0. O(n^2). For a workspace made for a
/// fixed p, the products of q, of q' and of a are kept with the bits they were formed from: the engine
/// asks for the mass matrix, the Jacobians, the force and the parameter product at one point.
/// mee is M_ee (the modal mass, M_ee a), rotation M_ee^xy (h, J_w, M_ee^xy q'): one matrix for a plate.
void modalProducts(const View& P, const Matrix& mee, const Matrix& rotation, const double* q, const double* v,
                   const double* a, bool jacobian, Work& w, double* moments);

/// The point (t, y, y', a) of the chord path's products: positions and kinematics (kept when they are
/// the last call's), the modal products (with the Jacobians' when `jacobian`) and the moments into mom;
/// returns the symmetric part of M_ee^xy (the Jacobians' and products' -beta'^2 h term; M_ee for a plate).
const Matrix& productPoint(const System& I, const System& C, const View& P, double t, ConstVectorRef y,
                           ConstVectorRef v, ConstVectorRef a, bool jacobian, Work& w, double* mom);

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

}  // namespace hindsight::mechanism::detail
