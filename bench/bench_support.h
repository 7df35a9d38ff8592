// Helpers shared by the benchmark binaries: the revolve optimum a storage spec is measured against,
// the storage counters every storage benchmark reports, and the peak resident set per benchmark.
//
// Peak resident set size of the benchmark process, per benchmark: Linux keeps one high-water mark
// (VmHWM) per process, and writing "5" to /proc/self/clear_refs resets it to the current RSS (Linux >= 4.0,
// Documentation/admin-guide/mm/soft-dirty.rst). A benchmark calls resetPeakRss() before its timed loop
// and reports peakRssBytes() after it, together with the RSS at the reset (what the process held
// before: caches of earlier benchmarks, the model). No library does this; it is 30 lines of procfs.
#pragma once

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>
#include <hindsight/problems/app/gradient_routes.h>

#include <benchmark/benchmark.h>

#include <cstdint>
#include <fstream>
#include <string>

namespace hindsight::bench {

/// Calls add(label, options) for every CVODES variant the benches compare, each a copy of `base` with
/// the CVODES route: Adams and BDF x CV_HERMITE and CV_POLYNOMIAL x Nd in {10, 100, 1000}, configured
/// as the CVODES user guide advises (CvodesOptions defaults: Adams with fixed-point iteration, BDF with
/// Newton and a dense direct solver, the problem's vector-Jacobian product in the backward rhs when it
/// has one); label = "cvodes-METHOD/INTERPOLATION-NdN". At CV_HERMITE, Nd 100 also the alternatives,
/// to show what each choice costs in the same run: "cvodes-adams-aa3" (Anderson acceleration, m = 3),
/// "cvodes-adams-newton" (Newton + dense, the configuration before the CVODES guide's advice was followed),
/// "cvodes-adams-newton-vjp" (Newton + dense with the VJP in the backward rhs), "cvodes-METHOD-jacobian" (the
/// dense F_z^T lambda in the backward rhs), "cvodes-bdf-gmres" (matrix-free Newton-GMRES),
/// "cvodes-METHOD-noquaderr" (quadratures out of the error test: SUNDIALS' default errconQ = false,
/// hindsight's default includes them).
template <class Add>
void forEachCvodesVariant(const GradientOptions& base, Add&& add) {
  for (CvodesMethod method : {CvodesMethod::Adams, CvodesMethod::Bdf}) {
    for (CvodesInterpolation interpolation :
         {CvodesInterpolation::Hermite, CvodesInterpolation::Polynomial}) {
      for (std::int64_t nd : {10, 100, 1000}) {
        GradientOptions cvodes = base;
        cvodes.adjoint = AdjointMethod::Cvodes;
        cvodes.cvodes.method = method;
        cvodes.cvodes.interpolation = interpolation;
        cvodes.cvodes.checkpointSteps = nd;
        const std::string variant = "/" + toString(interpolation) + "-Nd" + std::to_string(nd);
        add("cvodes-" + toString(method) + variant, cvodes);
        if (interpolation != CvodesInterpolation::Hermite || nd != 100) continue;
        GradientOptions alternative = cvodes;
        alternative.cvodes.backwardProducts = CvodesBackwardProducts::Dense;
        add("cvodes-" + toString(method) + "-jacobian" + variant, alternative);
        alternative = cvodes;
        alternative.cvodes.quadratureErrorControl = false;
        add("cvodes-" + toString(method) + "-noquaderr" + variant, alternative);
        if (method == CvodesMethod::Adams) {
          alternative = cvodes;
          alternative.cvodes.fixedPointAcceleration = 3;
          add("cvodes-adams-aa3" + variant, alternative);
          alternative = cvodes;
          alternative.cvodes.nonlinearSolver = CvodesNonlinearSolver::Newton;
          alternative.cvodes.linearSolver = CvodesLinearSolver::Dense;
          alternative.cvodes.backwardProducts = CvodesBackwardProducts::Dense;
          add("cvodes-adams-newton" + variant, alternative);
          alternative.cvodes.backwardProducts = CvodesBackwardProducts::Auto;
          add("cvodes-adams-newton-vjp" + variant, alternative);
        } else {
          alternative = cvodes;
          alternative.cvodes.linearSolver = CvodesLinearSolver::Gmres;
          add("cvodes-bdf-gmres" + variant, alternative);
        }
      }
    }
  }
}

/// computeGradientByMethod(), and for the CVODES route also its CvodesCounters as benchmark counters:
/// bwd_rhs (lambda' evaluations), vjps (rhsStateVjp calls), nl_iters (nonlinear iterations, both
/// problems), lin_iters (GMRES iterations), setups (linear-solver setups), recomputed_rhs (F during CVodeB).
inline GradientResult gradientWithCounters(const Problem& problem, ConstVectorRef p,
                                           const GradientOptions& options, benchmark::State& state) {
  if (options.adjoint != AdjointMethod::Cvodes) return computeGradientByMethod(problem, p, options);
  CvodesOptions cvodes = options.cvodes;
  cvodes.t0 = options.integrator.t0;
  cvodes.t1 = options.integrator.t1;
  CvodesCounters counters;
  GradientResult result = computeGradientCvodes(problem, p, cvodes, &counters);
  state.counters["bwd_rhs"] = static_cast<double>(counters.backwardRhsEvaluations);
  state.counters["vjps"] = static_cast<double>(counters.stateVjps);
  state.counters["nl_iters"] =
      static_cast<double>(counters.forwardNonlinearIterations + counters.backwardNonlinearIterations);
  state.counters["lin_iters"] =
      static_cast<double>(counters.forwardLinearIterations + counters.backwardLinearIterations);
  state.counters["setups"] = static_cast<double>(result.summary.factorizations);
  state.counters["recomputed_rhs"] = static_cast<double>(counters.recomputedRhsEvaluations);
  return result;
}

/// Forward steps of the optimal schedule for `steps` steps under `spec`: revolve's T(N, c) for the
/// checkpointing strategies (binomial, online: c from the spec), N - 1 for the rest (nothing to
/// recompute; T(N, N - 1) = N - 1 as well).
inline double revolveOptimum(const std::string& spec, std::int64_t steps) {
  const StorageSpec parsed = StorageSpec::parse(spec);
  if (parsed.name() == "binomial" || parsed.name() == "online") {
    const std::int64_t c = parsed.integer("checkpoints", 0, 0, BinomialCheckpointing::kMaxCheckpoints);
    return static_cast<double>(revolve::optimalForwardSteps(steps, c));
  }
  return static_cast<double>(steps - 1);
}

/// The counters of one gradient over storage `spec`: steps, recomputed, ratio_to_revolve
/// ((N - 1 + recomputed) / revolveOptimum), peak_bytes, disk_bytes, compression, io_s, stored,
/// forward_s, backward_s.
inline void setStorageCounters(benchmark::State& state, const std::string& spec, const RunSummary& summary,
                               const StorageCounters& counters) {
  const std::int64_t n = summary.steps;
  state.counters["steps"] = static_cast<double>(n);
  state.counters["recomputed"] = static_cast<double>(counters.recomputedSteps);
  state.counters["ratio_to_revolve"] =
      static_cast<double>(n - 1 + counters.recomputedSteps) / revolveOptimum(spec, n);
  state.counters["peak_bytes"] = static_cast<double>(counters.peakBytesInMemory);
  state.counters["disk_bytes"] = static_cast<double>(counters.bytesOnDisk);
  state.counters["compression"] = counters.compressionRatio();
  state.counters["io_s"] = counters.ioSeconds;
  state.counters["stored"] = static_cast<double>(counters.statesStored);
  state.counters["forward_s"] = summary.forwardSeconds;
  state.counters["backward_s"] = summary.backwardSeconds;
}

/// A /proc/self/status field in bytes ("VmHWM", "VmRSS"), or -1 when it cannot be read.
inline double procStatusBytes(const std::string& field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.compare(0, field.size() + 1, field + ":") == 0) {
      return 1024.0 * std::stod(line.substr(field.size() + 1));  // "VmHWM:   12345 kB"
    }
  }
  return -1.0;
}

/// Resets the high-water mark to the current RSS; returns the current RSS in bytes (-1 if unknown).
/// Returns -1 as well when the reset is refused (old kernel), so that callers do not report a stale peak.
inline double resetPeakRss() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5" << std::flush;
  if (!clear) return -1.0;
  return procStatusBytes("VmRSS");
}

/// The high-water mark since the last reset [bytes], -1 if unknown.
inline double peakRssBytes() { return procStatusBytes("VmHWM"); }

}  // namespace hindsight::bench
