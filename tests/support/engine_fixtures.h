// Shared helpers for engine tests.
#pragma once

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/full_storage.h>

#include <complex>
#include <functional>
#include <stdexcept>
#include <string>

namespace hindsight::testing {

inline GradientResult gradientWithFullStorage(const Problem& problem, const Vector& p,
                                              const IntegratorOptions& options) {
  FullStorage storage;
  storage.setVerifyRestores(true);
  return computeGradient(problem, p, options, storage);
}

/// psi of the computed trajectory as a function of p, on the grid `times` when given (frozen steps).
inline std::function<double(const Vector&)> computedObjective(const Problem& problem,
                                                              IntegratorOptions options,
                                                              const std::vector<double>& times = {}) {
  if (!times.empty()) options.replayTimes = times;
  return [&problem, options](const Vector& p) { return simulate(problem, p, options).objective; };
}

/// The message of the std::invalid_argument that f throws, or a note that it threw none.
inline std::string invalidArgumentMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "<no std::invalid_argument thrown>";
}

/// Exact gradient of a real-analytic closed form by complex-step differentiation (error ~ eps).
inline Vector complexStepGradient(const std::function<std::complex<double>(const Eigen::VectorXcd&)>& f,
                                  const Vector& x) {
  const double h = 1e-30;
  Vector g(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    Eigen::VectorXcd xc = x.cast<std::complex<double>>();
    xc(i) += std::complex<double>(0.0, h);
    g(i) = f(xc).imag() / h;
  }
  return g;
}

}  // namespace hindsight::testing
