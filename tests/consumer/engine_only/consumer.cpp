// Computes dpsi/dp of z' = -k z, psi = int z^2 dt, through the installed engine alone, and checks it
// against the closed form, then again with each in-memory checkpointing strategy made by spec string
// (engine/memory_storage_factory.h): exit code 0 only when the first agrees with the closed form and
// every strategy's gradient equals it bit for bit while recomputing what its plan says.
#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/memory_storage_factory.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>

class Decay final : public hindsight::Problem {
 public:
  std::string name() const override { return "decay"; }
  int stateSize() const override { return 1; }
  int parameterSize() const override { return 1; }
  void initialState(hindsight::ConstVectorRef, hindsight::VectorRef z0) const override { z0(0) = 1.0; }
  void rhs(double, hindsight::ConstVectorRef z, hindsight::ConstVectorRef p, hindsight::VectorRef f,
           hindsight::ProblemWorkspace*) const override {
    f(0) = -p(0) * z(0);
  }
  void rhsJacobian(double, hindsight::ConstVectorRef, hindsight::ConstVectorRef p, hindsight::MatrixRef j,
                   hindsight::ProblemWorkspace*) const override {
    j(0, 0) = -p(0);
  }
  void addRhsParameterVjp(double, hindsight::ConstVectorRef z, hindsight::ConstVectorRef,
                          hindsight::ConstVectorRef w, hindsight::VectorRef out,
                          hindsight::ProblemWorkspace*) const override {
    out(0) -= z(0) * w(0);
  }
  double integrand(double, hindsight::ConstVectorRef z, hindsight::ConstVectorRef,
                   hindsight::ProblemWorkspace*) const override {
    return z(0) * z(0);
  }
  void addIntegrandStateGradient(double, hindsight::ConstVectorRef z, hindsight::ConstVectorRef, double scale,
                                 hindsight::VectorRef out, hindsight::ProblemWorkspace*) const override {
    out(0) += 2.0 * scale * z(0);
  }
  void addIntegrandParameterGradient(double, hindsight::ConstVectorRef, hindsight::ConstVectorRef, double,
                                     hindsight::VectorRef, hindsight::ProblemWorkspace*) const override {}
};

int main() {
  Decay problem;
  hindsight::IntegratorOptions options;
  options.t1 = 1.0;
  options.step = 1e-3;
  hindsight::FullStorage storage;
  const double k = 2.0;
  const auto result = hindsight::computeGradient(problem, Eigen::VectorXd::Constant(1, k), options, storage);
  // psi = (1 - e^{-2k}) / (2k); dpsi/dk = e^{-2k}/k - (1 - e^{-2k}) / (2k^2).
  const double exact = std::exp(-2 * k) / k - (1 - std::exp(-2 * k)) / (2 * k * k);
  const double error = std::abs(result.gradient(0) - exact) / std::abs(exact);
  std::printf("hindsight %s: dpsi/dk = %.12g, exact %.12g, relative error %.2e\n", hindsight::version(),
              result.gradient(0), exact, error);
  if (!(error < 1e-10)) return 1;
  // 1000 steps; 10 checkpoints: every strategy but full recomputes, and holds fewer bytes than full.
  const std::int64_t storage0Peak = storage.counters().peakBytesInMemory;
  for (const char* spec : {"full:stages=1", "binomial:checkpoints=10", "binomial:checkpoints=10,stages=1",
                           "online:checkpoints=10", "cams:checkpoints=10"}) {
    const auto storage = hindsight::createMemoryStorage(spec);
    const auto r = hindsight::computeGradient(problem, Eigen::VectorXd::Constant(1, k), options, *storage);
    const bool full = std::string(spec).rfind("full", 0) == 0;
    const hindsight::StorageCounters& stats = storage->counters();
    std::printf("%s: dpsi/dk = %.17g, %lld recomputed steps, peak %lld bytes\n", spec, r.gradient(0),
                static_cast<long long>(stats.recomputedSteps),
                static_cast<long long>(stats.peakBytesInMemory));
    if (r.gradient(0) != result.gradient(0) || r.objective != result.objective) return 1;
    if (full ? stats.recomputedSteps != 0
             : (stats.recomputedSteps == 0 || stats.peakBytesInMemory >= storage0Peak))
      return 1;
  }
  try {
    hindsight::createMemoryStorage("disk");
    return 1;
  } catch (const std::invalid_argument& e) {
    std::printf("disk from the engine alone: %s\n", e.what());
  }
  return 0;
}
