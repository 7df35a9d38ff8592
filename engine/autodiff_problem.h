// A Problem whose derivatives come from one templated functor by forward-mode automatic
// differentiation (in the spirit of Ceres' AutoDiffCostFunction): the user writes F, G and z0 once,
// generically in the scalar type, and AutoDiffProblem supplies F_z, (F_p)^T w, G_z, G_p, (dz0/dp)^T
// lambda and the terminal gradients, exact to round-off (no truncation error as with differences).
//
// The functor (sizes are compile-time constants kStates = n, kParams = np; arrays are contiguous):
//
//   struct MyOde {
//     // Required. f = F(t, z, p); z, p, f have n, np, n entries.
//     template <class T> void rhs(double t, const T* z, const T* p, T* f) const;
//     // Required. G(t, z, p).
//     template <class T> T integrand(double t, const T* z, const T* p) const;
//     // Required. z0 = z(t0)(p). Written as a template, dz0/dp is derived; written for double only
//     // (void initialState(const double* p, double* z0) const), z0 is taken as independent of p.
//     template <class T> void initialState(const T* p, T* z0) const;
//     // Optional. The terminal term phi(z(t1), p); absent means phi = 0.
//     template <class T> T terminal(const T* z, const T* p) const;
//   };
//   AutoDiffProblem<MyOde, 2, 3> problem("my-ode");
//
// T is double or an Eigen::AutoDiffScalar; call transcendental functions as hindsight::dmath::sin(x)
// (and so on, engine/deterministic_math.h: overloads for both, the same bits on every CPU), or write
// them unqualified after `using std::sin;` to get Eigen's overloads (glibc's CPU-dependent variants),
// and initialise with T(...) rather
// than relying on conversions in branches. The time t is a plain double: the engine never needs a
// derivative in t. The functor is stored by value and must be const-callable (a problem is immutable
// during a solve); its data members may hold constants such as a horizon.
//
// Cost: F_z and G_z take one evaluation with n derivative directions, (F_p)^T w and G_p one with np
// directions, the terminal gradient one with n + np. This suits the small, dense problems the
// functor form is meant for; large problems write their derivatives (or a vector-Jacobian product)
// by hand. The explicit adjoint stages form the dense Jacobian and multiply (hasStateVjp() is false),
// which for forward mode costs the same as a separate vector-Jacobian product would.
// Measured on the pendulum (bench/autodiff_bench.cpp, bench/RESULTS.md): 1.1-2.1x the hand-written
// derivative per call, 1.05-1.22x the hand-written problem for a whole gradient.
//
// No evaluation allocates: the derivative vectors have fixed size (Eigen::Matrix<double, N, 1>), so
// every active scalar lives on the stack (tests/engine/autodiff_problem_test.cpp counts this). We use
// Eigen's unsupported AutoDiffScalar rather than a hand-written dual number because the engine already
// depends on Eigen and nothing else; its expression templates fuse the derivative updates of a
// statement into one loop over the N directions.
#pragma once

#include <hindsight/engine/problem.h>

#include <unsupported/Eigen/AutoDiff>

#include <string>
#include <type_traits>
#include <utility>

namespace hindsight {

/// The active scalar with N derivative directions.
template <int N>
using AutoDiffScalar = Eigen::AutoDiffScalar<Eigen::Matrix<double, N, 1>>;

namespace autodiff_detail {

// Whether the functor has a terminal term phi(z, p).
template <class F, class = void>
struct HasTerminal : std::false_type {};
template <class F>
struct HasTerminal<F, std::void_t<decltype(std::declval<const F&>().terminal(
                          std::declval<const double*>(), std::declval<const double*>()))>> : std::true_type {
};

// Whether initialState is generic, so that dz0/dp can be derived with np directions.
template <class F, int kParams, class = void>
struct HasGenericInitialState : std::false_type {};
template <class F, int kParams>
struct HasGenericInitialState<
    F, kParams,
    std::void_t<decltype(std::declval<const F&>().initialState(std::declval<const AutoDiffScalar<kParams>*>(),
                                                               std::declval<AutoDiffScalar<kParams>*>()))>>
    : std::true_type {};

// x[i] = (value_i, e_{offset + i}): the i-th of `count` independent variables among N directions.
template <int N>
void seed(const double* values, int count, int offset, AutoDiffScalar<N>* x) {
  for (int i = 0; i < count; ++i) x[i] = AutoDiffScalar<N>(values[i], N, offset + i);
}

// x[i] = (value_i, 0): a constant of the differentiation.
template <int N>
void constant(const double* values, int count, AutoDiffScalar<N>* x) {
  for (int i = 0; i < count; ++i) x[i] = AutoDiffScalar<N>(values[i]);
}

}  // namespace autodiff_detail

template <class Functor, int kStates, int kParams>
class AutoDiffProblem final : public Problem {
  static_assert(kStates >= 1, "AutoDiffProblem needs at least one state");
  static_assert(kParams >= 1, "AutoDiffProblem needs at least one parameter (the gradient is dpsi/dp)");
  using StateScalar = AutoDiffScalar<kStates>;
  using ParameterScalar = AutoDiffScalar<kParams>;
  using JointScalar = AutoDiffScalar<kStates + kParams>;

 public:
  explicit AutoDiffProblem(std::string name, Functor functor = Functor())
      : name_(std::move(name)), functor_(std::move(functor)) {}

  const Functor& functor() const { return functor_; }

  std::string name() const override { return name_; }
  int stateSize() const override { return kStates; }
  int parameterSize() const override { return kParams; }

  void initialState(ConstVectorRef p, VectorRef z0) const override {
    functor_.initialState(p.data(), z0.data());
  }

  void addInitialStateVjp(ConstVectorRef p, ConstVectorRef lambda0, VectorRef gradient) const override {
    if constexpr (autodiff_detail::HasGenericInitialState<Functor, kParams>::value) {
      ParameterScalar pj[kParams], z0[kStates];
      autodiff_detail::seed(p.data(), kParams, 0, pj);
      functor_.initialState(pj, z0);
      for (int i = 0; i < kStates; ++i) gradient += lambda0(i) * z0[i].derivatives();
    }
  }

  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
    functor_.rhs(t, z.data(), p.data(), f.data());
  }

  void rhsJacobian(double t, ConstVectorRef z, ConstVectorRef p, MatrixRef jacobian,
                   ProblemWorkspace*) const override {
    StateScalar zj[kStates], pj[kParams], f[kStates];
    autodiff_detail::seed(z.data(), kStates, 0, zj);
    autodiff_detail::constant(p.data(), kParams, pj);
    functor_.rhs(t, zj, pj, f);
    for (int i = 0; i < kStates; ++i) jacobian.row(i) = f[i].derivatives().transpose();
  }

  void addRhsParameterVjp(double t, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace*) const override {
    ParameterScalar zj[kStates], pj[kParams], f[kStates];
    autodiff_detail::constant(z.data(), kStates, zj);
    autodiff_detail::seed(p.data(), kParams, 0, pj);
    functor_.rhs(t, zj, pj, f);
    for (int i = 0; i < kStates; ++i) out += w(i) * f[i].derivatives();
  }

  double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace*) const override {
    return functor_.integrand(t, z.data(), p.data());
  }

  void addIntegrandStateGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale, VectorRef out,
                                 ProblemWorkspace*) const override {
    StateScalar zj[kStates], pj[kParams];
    autodiff_detail::seed(z.data(), kStates, 0, zj);
    autodiff_detail::constant(p.data(), kParams, pj);
    out += scale * StateScalar(functor_.integrand(t, zj, pj)).derivatives();
  }

  void addIntegrandParameterGradient(double t, ConstVectorRef z, ConstVectorRef p, double scale,
                                     VectorRef out, ProblemWorkspace*) const override {
    ParameterScalar zj[kStates], pj[kParams];
    autodiff_detail::constant(z.data(), kStates, zj);
    autodiff_detail::seed(p.data(), kParams, 0, pj);
    out += scale * ParameterScalar(functor_.integrand(t, zj, pj)).derivatives();
  }

  double terminal(ConstVectorRef z, ConstVectorRef p) const override {
    if constexpr (autodiff_detail::HasTerminal<Functor>::value) {
      return functor_.terminal(z.data(), p.data());
    } else {
      return 0.0;
    }
  }

  void addTerminalGradient(ConstVectorRef z, ConstVectorRef p, VectorRef gz, VectorRef gp) const override {
    if constexpr (autodiff_detail::HasTerminal<Functor>::value) {
      // One pass with n + np directions: phi is evaluated once for both gradients.
      JointScalar zj[kStates], pj[kParams];
      autodiff_detail::seed(z.data(), kStates, 0, zj);
      autodiff_detail::seed(p.data(), kParams, kStates, pj);
      const JointScalar phi = functor_.terminal(zj, pj);
      gz += phi.derivatives().template head<kStates>();
      gp += phi.derivatives().template tail<kParams>();
    }
  }

 private:
  std::string name_;
  Functor functor_;
};

}  // namespace hindsight
