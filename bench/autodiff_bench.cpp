// What AutoDiffProblem costs against hand-written derivatives, on the damped pendulum. Argument 0:
// the library's hand-derived Pendulum (second-order adapter: M, f and the residual Jacobians, M^{-1}
// through a Cholesky factor); 1: AutoDiffPendulum (one templated functor,
// problems/classic/classic_problems.h); 2: the same first-order equations with hand-written derivatives and
// no adapter (below), which isolates the cost of the automatic differentiation itself. All are called through
// Problem&, as the engine calls them; the Gradient runs report psi and dpsi/dm so that agreement can be seen.
//
// Raw calls: each iteration alternates between two states, so the adapter's per-stage cache of the
// acceleration misses as it does for the first call at a new stage (at a stage the engine calls rhs,
// then F_z and F_p^T w at the same point, and the adapter reuses M^{-1} f there). Whole gradient: one
// computeGradient over full storage, which includes every such reuse.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/problems/classic/classic_problems.h>

#include <benchmark/benchmark.h>

#include <cmath>

namespace hindsight {
namespace {

// The values F, G, phi and z0 are PendulumEquations' own, instantiated for double (inline, as in
// AutoDiffPendulum); only the derivatives are written by hand, from a = -(g/L) sin(th) - c v/(m L^2).
// So the two differ in nothing but how the derivatives are obtained. (Calling Pendulum's out-of-line
// split-state functions for G instead doubled the cost of G_z; see bench/RESULTS.md.)
class FirstOrderPendulum final : public Problem {
 public:
  std::string name() const override { return "pendulum-first-order"; }
  int stateSize() const override { return 2; }
  int parameterSize() const override { return 4; }
  void initialState(ConstVectorRef p, VectorRef z0) const override {
    equations_.initialState(p.data(), z0.data());
  }
  void addInitialStateVjp(ConstVectorRef, ConstVectorRef lambda0, VectorRef gradient) const override {
    gradient(3) += lambda0(0);
  }
  void rhs(double t, ConstVectorRef z, ConstVectorRef p, VectorRef f, ProblemWorkspace*) const override {
    equations_.rhs(t, z.data(), p.data(), f.data());
  }
  void rhsJacobian(double, ConstVectorRef z, ConstVectorRef p, MatrixRef j,
                   ProblemWorkspace*) const override {
    j << 0.0, 1.0, -Pendulum::kGravity / p(1) * std::cos(z(0)), -p(2) / (p(0) * p(1) * p(1));
  }
  void addRhsParameterVjp(double, ConstVectorRef z, ConstVectorRef p, ConstVectorRef w, VectorRef out,
                          ProblemWorkspace*) const override {
    const double m = p(0), length = p(1), c = p(2), damping = z(1) / (m * length * length);
    out(0) += w(1) * c * damping / m;
    out(1) += w(1) * (Pendulum::kGravity * std::sin(z(0)) / (length * length) + 2.0 * c * damping / length);
    out(2) -= w(1) * damping;
  }
  double integrand(double t, ConstVectorRef z, ConstVectorRef p, ProblemWorkspace*) const override {
    return equations_.integrand(t, z.data(), p.data());
  }
  // G = th^2 does not depend on p: G_p adds nothing.
  void addIntegrandStateGradient(double, ConstVectorRef z, ConstVectorRef, double scale, VectorRef out,
                                 ProblemWorkspace*) const override {
    out(0) += scale * 2.0 * z(0);
  }
  void addIntegrandParameterGradient(double, ConstVectorRef, ConstVectorRef, double, VectorRef,
                                     ProblemWorkspace*) const override {}
  double terminal(ConstVectorRef z, ConstVectorRef p) const override {
    return equations_.terminal(z.data(), p.data());
  }
  void addTerminalGradient(ConstVectorRef z, ConstVectorRef, VectorRef gz, VectorRef) const override {
    gz(1) += z(1);
  }

 private:
  PendulumEquations equations_;
};

const Pendulum kHand;
const AutoDiffPendulum kDerived("pendulum-autodiff");
const FirstOrderPendulum kFirstOrder;

const Problem& problemFor(const benchmark::State& state) {
  if (state.range(0) == 0) return kHand;
  if (state.range(0) == 1) return kDerived;
  return kFirstOrder;
}

enum class Call { Rhs, Jacobian, ParameterVjp, IntegrandStateGradient, IntegrandParameterGradient };

template <Call kCall>
void RawCall(benchmark::State& state) {
  const Problem& problem = problemFor(state);
  const auto ws = problem.createWorkspace();
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  const Vector states[2] = {Eigen::Vector2d(1.2, -0.3), Eigen::Vector2d(0.7, 0.4)};
  const Vector w = Eigen::Vector2d(0.6, -1.1);
  Vector f(2), gz = Vector::Zero(2), gp = Vector::Zero(4);
  Matrix jacobian(2, 2);
  int which = 0;
  for (auto _ : state) {
    const Vector& z = states[which];
    which ^= 1;
    if constexpr (kCall == Call::Rhs) problem.rhs(0.1, z, p, f, ws.get());
    if constexpr (kCall == Call::Jacobian) problem.rhsJacobian(0.1, z, p, jacobian, ws.get());
    if constexpr (kCall == Call::ParameterVjp) problem.addRhsParameterVjp(0.1, z, p, w, gp, ws.get());
    if constexpr (kCall == Call::IntegrandStateGradient) {
      problem.addIntegrandStateGradient(0.1, z, p, 0.5, gz, ws.get());
    }
    if constexpr (kCall == Call::IntegrandParameterGradient) {
      problem.addIntegrandParameterGradient(0.1, z, p, 0.5, gp, ws.get());
    }
    benchmark::DoNotOptimize(f.data());
    benchmark::DoNotOptimize(jacobian.data());
    benchmark::DoNotOptimize(gz.data());
    benchmark::DoNotOptimize(gp.data());
    benchmark::ClobberMemory();
  }
  state.SetLabel(problem.name());
}

// One gradient: rk4, h = 1e-4, t1 = 10 s (100 000 steps, as in engine_bench), or trbdf2 with
// h = 1e-3 (10 000 steps; the Newton matrix needs F_z at every stage).
void Gradient(benchmark::State& state) {
  const Problem& problem = problemFor(state);
  const Vector p = Eigen::Vector4d(1.5, 0.8, 0.3, 1.2);
  IntegratorOptions options;
  options.method = state.range(1) == 0 ? "rk4" : "trbdf2";
  options.t1 = 10.0;
  options.step = state.range(1) == 0 ? 1e-4 : 1e-3;
  std::int64_t steps = 0;
  double psi = 0.0, dpsiDm = 0.0;
  for (auto _ : state) {
    FullStorage storage;
    const GradientResult result = computeGradient(problem, p, options, storage);
    benchmark::DoNotOptimize(result.gradient.data());
    steps = result.summary.steps;
    psi = result.objective;
    dpsiDm = result.gradient(0);
  }
  state.counters["steps"] = static_cast<double>(steps);
  state.counters["psi"] = psi;
  state.counters["dpsi_dm"] = dpsiDm;
  state.SetLabel(problem.name() + "/" + options.method);
}

BENCHMARK_TEMPLATE(RawCall, Call::Rhs)->DenseRange(0, 2);
BENCHMARK_TEMPLATE(RawCall, Call::Jacobian)->DenseRange(0, 2);
BENCHMARK_TEMPLATE(RawCall, Call::ParameterVjp)->DenseRange(0, 2);
BENCHMARK_TEMPLATE(RawCall, Call::IntegrandStateGradient)->DenseRange(0, 2);
BENCHMARK_TEMPLATE(RawCall, Call::IntegrandParameterGradient)->DenseRange(0, 2);
BENCHMARK(Gradient)->ArgsProduct({{0, 1, 2}, {0, 1}})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace hindsight

BENCHMARK_MAIN();
