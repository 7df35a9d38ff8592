// Transcendental functions whose results are the same bits on every x86-64 CPU.
//
// glibc selects CPU-specific variants of sin, cos, asin, exp, pow, ... at run time (its "ifunc"
// dispatch: FMA, AVX2 and AVX-512 code paths). Each variant is accurate to about an ulp, but they do
// not round alike, so the same binary gave ψ1(x0) = 0.2525300285237848 on one CPU and ...854 on
// another, and the optimisation built on it drifted apart (docs/guides/reproducibility.md). Every
// transcendental function on the result path therefore goes through this header instead of <cmath>.
//
// The implementation is SLEEF's (Debian's libsleef3): its "cinz" functions are the pure-C, FMA-free,
// deterministic variants (Sleef_cinz_<name>d1_u10purec, error bound 1.0 ulp), which SLEEF documents to
// give identical results on every CPU of an architecture as long as FMA use is the same; they are
// compiled into the library with plain SSE2 arithmetic, so no run-time dispatch is involved. We call
// the library instead of writing our own polynomial kernels because a maintained, tested package
// does exactly this. sqrt, fabs, floor and the arithmetic operators are exactly rounded by IEEE 754
// and need nothing.
//
// For Eigen::AutoDiffScalar arguments the overloads below apply the chain rule with the same
// deterministic value functions (Eigen's own AutoDiff overloads would call std::sin and friends).
// Call them qualified (dmath::sin) or unqualified after `using hindsight::dmath::sin;`.
#pragma once

#include <Eigen/Core>
#include <unsupported/Eigen/AutoDiff>

#include <cmath>

namespace hindsight::dmath {

double sin(double x);
double cos(double x);
/// sin and cos of the same argument in one call (each bit-identical to sin(x) and cos(x)).
void sincos(double x, double* sine, double* cosine);
double asin(double x);
double exp(double x);
double log2(double x);
double pow(double x, double y);
double tanh(double x);

// Chain rule for forward-mode automatic differentiation. Only the value functions differ from
// Eigen's overloads; the derivative expressions use exact arithmetic and sqrt.
template <typename Derivatives>
using ActiveOf = Eigen::AutoDiffScalar<typename Eigen::internal::remove_all<Derivatives>::type::PlainObject>;

template <typename D>
ActiveOf<D> sin(const Eigen::AutoDiffScalar<D>& x) {
  double s, c;
  sincos(x.value(), &s, &c);
  return ActiveOf<D>(s, x.derivatives() * c);
}
template <typename D>
ActiveOf<D> cos(const Eigen::AutoDiffScalar<D>& x) {
  double s, c;
  sincos(x.value(), &s, &c);
  return ActiveOf<D>(c, x.derivatives() * (-s));
}
template <typename D>
ActiveOf<D> asin(const Eigen::AutoDiffScalar<D>& x) {
  const double v = x.value();
  return ActiveOf<D>(asin(v), x.derivatives() * (1.0 / std::sqrt(1.0 - v * v)));
}
template <typename D>
ActiveOf<D> exp(const Eigen::AutoDiffScalar<D>& x) {
  const double e = exp(x.value());
  return ActiveOf<D>(e, x.derivatives() * e);
}
template <typename D>
ActiveOf<D> tanh(const Eigen::AutoDiffScalar<D>& x) {
  const double t = tanh(x.value());
  return ActiveOf<D>(t, x.derivatives() * (1.0 - t * t));
}

}  // namespace hindsight::dmath
