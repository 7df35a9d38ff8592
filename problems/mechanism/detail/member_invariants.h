// The flexible member as the mechanism sees it: its packed invariants p (the layout of
// problems/rod/invariants.h: m, m c, J0, C1, C2, a0, Ct, M_ee, K_ee, b and, for a member that deforms in
// 3-D, M_ee^xy after b) and the moments through which its frame rows depend on q, q' and a. This is all
// the mechanism knows of the member (docs/design.md §11, "The member interface"): the plate and the
// solid differ for it only in whether p carries a block M_ee^xy of its own (View::spatial), and nothing
// here or in the mechanism's other files asks which model produced p. Internal to problems/mechanism/.
#pragma once

namespace hindsight::mechanism::detail {

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
  // M_ee enters through its symmetric part, as in the tests' closed form (tests/support/slider_crank.cpp):
  // the reduced mass matrix must be symmetric, and the gradient splits evenly between (i, j) and (j, i).
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

/// The member's moments: the scalars through which its frame rows depend on q, q' and a
/// (chordForce()): s_w = m c + C1 q (2), J_w = J0 + 2 C2 q + q^T M_ee^xy q, A1 . a, C1 a (2), C1 q' (2),
/// h . q' (h = C2 + M_ee^xy q; M_ee^xy = M_ee for a plate, View::meeRotation).
enum Moment { kSw0, kSw1, kJw, kA1a, kC1a0, kC1a1, kC1v0, kC1v1, kHv, kMoments };

}  // namespace hindsight::mechanism::detail
