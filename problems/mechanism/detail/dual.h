// The scalar types and small dense kernels of the mechanism's equations (docs/design.md §10): dual
// numbers with derivative vectors of fixed capacity (the exact derivatives of the chord path and of the
// full-coordinate reference, without allocation), constants and seeds of a pass's width, sine and cosine
// through hindsight::dmath (the same bits on every CPU), and the partial-pivoting LU of the constraint
// Jacobian's blocks, which pivots by value so that every scalar type takes the same row swaps. Internal to
// problems/mechanism/ (not installed; docs/design.md P 1): its source files include it, nothing else.
#pragma once

#include <hindsight/engine/deterministic_math.h>
#include <hindsight/problems/mechanism/mechanism_problem.h>

#include <unsupported/Eigen/AutoDiff>

#include <cmath>
#include <type_traits>
#include <utility>

namespace hindsight::mechanism::detail {

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

/// Dual numbers that are constants.
template <typename ADT>
void constants(const double* values, int count, int nd, ADT* out) {
  for (int i = 0; i < count; ++i) out[i] = Make<ADT>::constant(values[i], nd);
}

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

}  // namespace hindsight::mechanism::detail
