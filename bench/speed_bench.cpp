// Where the CPU of one evaluation goes, and what the backward sweep costs against the forward one.
// Prints markdown tables (no Google Benchmark fixtures: the quantities are phase CPU times of one
// evaluation and ratios of one run's sweeps). Times are process CPU seconds (CLOCK_PROCESS_CPUTIME_ID,
// every thread), so they mean something on a shared machine where wall time does not.
//  1. phases of one gradient dpsi1/dx (the piston rod's default configuration) per mesh:
//     K factorisation + eigen-solve + invariants ("model"), the discrete adjoint ("simulation":
//     forward + backward sweep), the chain dpsi/dp -> dpsi/dx with the Nelson systems ("chain") and
//     psi2 without its gradient ("esl"), the sum, and the forward sweep alone for scale.
//  2. (forward + backward) / forward CPU per integrator on the 200 x 12 rod (invariants of x0), median
//     of 3, with full:stages=1 for rk4 (the backward sweep then recomputes no stage).
//  3. the closed-form slider-crank (tests/support/slider_crank.h, the reference) against the default path,
//     the same slider-crank described (problems/mechanism/mechanism_problem.h), on the default
//     configuration: CPU of the discrete adjoint (forward + backward), median of 3, the largest
//     difference of dpsi1/dp, and the CPU of the default configuration's whole evaluation (PistonRod:
//     model, dpsi1/dx, psi2 and its gradient).
//  4. (mode 5 only) the one-vector sweeps of K's factor per mesh: Eigen's serial back-substitution
//     against rod::SubtreeParallelLdlt's on the subtrees, wall seconds.
// Usage: speed_bench [largest mesh index 0..4 (100x6 ... 1600x96), default 3] [integrators only: 1,
//        the mechanism table only: 2, one rk4 forward sweep and one rk4 gradient for callgrind: 3 (the
//        default path) or 4 (the closed form), the one-vector sweeps of K's factor per mesh: 5]
#include <hindsight/engine/adjoint.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/mechanism/mechanism_problem.h>
#include <hindsight/problems/rod/design_gradient.h>
#include <hindsight/problems/rod/esl.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/invariants.h>
#include <hindsight/problems/rod/modal_reduction.h>
#include <hindsight/storage/storage_factory.h>
#include "support/slider_crank.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

using namespace hindsight;

namespace {

double cpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

/// The closed-form slider-crank (tests/support/slider_crank.h): the reference of the mechanism table.
rod::SliderCrankProblem closedFormOf(const rod::RodConfig& rc, int columns) {
  rod::CrankMotion crank;
  crank.radius = rc.crankRadius;
  crank.omega = rc.crankSpeed;
  crank.rampTime = rc.rampTime;
  return rod::SliderCrankProblem(columns, rc.length, crank);
}

/// The problem the piston rod runs without a mechanism section: the slider-crank described by
/// mechanism::sliderCrank through the general path.
std::unique_ptr<mechanism::MechanismProblem> problemOf(const rod::RodConfig& rc, int columns) {
  return std::make_unique<mechanism::MechanismProblem>(
      mechanism::sliderCrank(rc.crankRadius, rc.length, rc.crankSpeed, rc.rampTime), columns);
}

/// The benchmark meshes, 100 x 6 ... 1600 x 96 (index 0 ... 4), as the default configuration on them.
constexpr int kMeshes[5][2] = {{100, 6}, {200, 12}, {400, 24}, {800, 48}, {1600, 96}};

Config meshConfig(int m) {
  Config config;
  config.rod.elementsAlongLength = kMeshes[m][0];
  config.rod.elementsThroughHeight = kMeshes[m][1];
  return config;
}

void phaseTable(int largest) {
  std::printf(
      "| mesh | designs | model | simulation (fwd+bwd) | forward alone | chain | esl | sum | integrator |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---|\n");
  for (int m = 0; m <= largest && m < 5; ++m) {
    const Config config = meshConfig(m);
    const PistonRod piston(config);
    const rod::RodConfig& rc = config.rod;
    const Vector x = piston.initialDesign();
    const IntegratorOptions options = piston.integratorOptions();

    double start = cpuSeconds();
    const rod::FeModel model(rc, x);
    const rod::StiffnessFactorization stiffness(model.stiffness(), rod::stiffnessOrdering(model));
    const rod::ModalBasis basis =
        rod::computeModalBasis(model, rod::ModalReductionOptions::fromConfig(rc), stiffness);
    const rod::InertiaInvariants invariants = rod::computeInvariants(model, basis);
    const Vector p = invariants.pack();
    const double modelCpu = cpuSeconds() - start;

    const auto problemPointer = problemOf(rc, basis.columnCount());
    const SecondOrderProblem& problem = *problemPointer;
    const int n = basis.columnCount();
    Matrix sampled = Matrix::Zero(n, rc.eslSamples);
    const std::int64_t stride =
        static_cast<std::int64_t>(std::llround(options.t1 / options.step)) / rc.eslSamples;
    const StateObserver observer = [&](std::int64_t step, double, ConstVectorRef z) {
      if (step > 0 && step % stride == 0 && step / stride <= rc.eslSamples)
        sampled.col(step / stride - 1) = z.head(n);
    };
    start = cpuSeconds();
    const ForwardResult forward = simulate(problem, p, options, observer);
    const double forwardCpu = cpuSeconds() - start;
    start = cpuSeconds();
    auto storage = createStorage(config.simulation.storage);
    const GradientResult gradient = computeGradient(problem, p, options, *storage, observer);
    const double simulationCpu = cpuSeconds() - start;
    start = cpuSeconds();
    rod::DesignGradientOptions chain;
    chain.method = config.simulation.eigenvectorRoute;
    const Vector dpsi =
        rod::computeDesignGradient(model, basis, gradient.gradient, chain, {}, stiffness).gradient;
    const double chainCpu = cpuSeconds() - start;
    start = cpuSeconds();
    const rod::EslResult esl =
        rod::evaluateEslAtLoadDesign(model, basis, invariants.kee, sampled, options.t1, false);
    const double eslCpu = cpuSeconds() - start;
    if (!(forward.objective == gradient.objective) || !dpsi.allFinite() || !(esl.value > 0.0)) {
      std::fprintf(stderr, "inconsistent evaluation at mesh %d\n", m);
      std::exit(1);
    }
    std::printf("| %dx%d | %d | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %s h = %g |\n", kMeshes[m][0],
                kMeshes[m][1], model.designCount(), modelCpu, simulationCpu, forwardCpu, chainCpu, eslCpu,
                modelCpu + simulationCpu + chainCpu + eslCpu, options.method.c_str(), options.step);
    std::fflush(stdout);
  }
}

/// The invariants p of the default configuration's initial design and the number of modal columns.
struct DefaultInvariants {
  Vector p;
  int columns = 0;
};

DefaultInvariants defaultInvariants(const PistonRod& piston) {
  const rod::RodConfig& rc = piston.config().rod;
  const rod::FeModel model(rc, piston.initialDesign());
  const rod::ModalBasis basis = rod::computeModalBasis(model, rod::ModalReductionOptions::fromConfig(rc));
  return {rod::computeInvariants(model, basis).pack(), basis.columnCount()};
}

void integratorTable() {
  Config config;
  const PistonRod piston(config);
  const rod::RodConfig& rc = config.rod;
  const auto [p, columns] = defaultInvariants(piston);
  const auto problemPointer = problemOf(rc, columns);
  const SecondOrderProblem& problem = *problemPointer;
  struct Case {
    const char* method;
    double step;
    const char* storage;
  };
  const Case cases[] = {{"rk4", 1e-4, "full"},
                        {"rk4", 1e-4, "full:stages=1"},
                        {"generalized-alpha", 5e-4, "full"},
                        {"generalized-alpha", 1e-3, "full"},
                        {"generalized-alpha", 2e-3, "full"}};
  std::printf(
      "\n| integrator | h | storage | forward CPU s | forward + backward CPU s | (fwd+bwd)/fwd | psi1 |\n"
      "|---|---:|---|---:|---:|---:|---:|\n");
  for (const Case& c : cases) {
    IntegratorOptions options;
    options.method = c.method;
    options.t1 = rc.endTime;
    options.step = c.step;
    options.rhoInfinity = config.simulation.rhoInfinity;
    std::vector<double> forward, total, ratio;
    double psi1 = 0.0;
    for (int run = 0; run < 3; ++run) {
      double start = cpuSeconds();
      simulate(problem, p, options);
      const double f = cpuSeconds() - start;
      const auto storage = createStorage(c.storage);
      start = cpuSeconds();
      psi1 = computeGradient(problem, p, options, *storage).objective;
      const double g = cpuSeconds() - start;
      forward.push_back(f);
      total.push_back(g);
      ratio.push_back(g / f);
    }
    std::printf("| %s | %g | %s | %.4f | %.4f | %.2f | %.10g |\n", c.method, c.step, c.storage,
                median(forward), median(total), median(ratio), psi1);
    std::fflush(stdout);
  }
}

void mechanismTable() {
  Config config;
  const rod::RodConfig& rc = config.rod;
  const PistonRod piston(config);
  const Vector x = piston.initialDesign();
  const auto [p, columns] = defaultInvariants(piston);
  const rod::SliderCrankProblem closedForm = closedFormOf(rc, columns);
  const auto general = problemOf(rc, columns);
  const IntegratorOptions options = piston.integratorOptions();
  std::printf(
      "\n| slider-crank | simulation + adjoint CPU s | psi1 |\n"
      "|---|---:|---:|\n");
  Vector reference;
  for (int k = 0; k < 2; ++k) {
    const SecondOrderProblem& problem =
        k == 0 ? static_cast<const SecondOrderProblem&>(closedForm) : *general;
    std::vector<double> simulation;
    GradientResult result;
    for (int run = 0; run < 3; ++run) {
      const auto storage = createStorage(config.simulation.storage);
      const double start = cpuSeconds();
      result = computeGradient(problem, p, options, *storage);
      simulation.push_back(cpuSeconds() - start);
    }
    if (k == 0) reference = result.gradient;
    std::printf("| %s | %.4f | %.16g |\n",
                k == 0 ? "closed form (reference)" : "described (the default path)", median(simulation),
                result.objective);
    if (k == 1) {
      std::printf("\nlargest |d psi1/dp| difference: %.3g (largest entry %.3g)\n",
                  (result.gradient - reference).cwiseAbs().maxCoeff(), reference.cwiseAbs().maxCoeff());
    }
    std::fflush(stdout);
  }
  std::vector<double> evaluation;
  for (int run = 0; run < 3; ++run) {
    const double start = cpuSeconds();
    piston.evaluate(x);
    evaluation.push_back(cpuSeconds() - start);
  }
  std::printf(
      "whole evaluation of the default configuration (model, dpsi1/dx, psi2 and its gradient): %.4f s\n",
      median(evaluation));
}

}  // namespace

/// One forward sweep (simulate) and one gradient (computeGradient) with rk4 h = 1e-4 and full:stages=1 on
/// the default path (closedForm: the closed-form slider-crank), nothing else timed: run under callgrind,
/// the two functions' inclusive instruction counts give (forward + backward) / forward without this
/// machine's ±30 % in CPU time (bench/RESULTS.md has the command).
void rk4SweepsForCallgrind(bool closedForm) {
  Config config;
  const PistonRod piston(config);
  const rod::RodConfig& rc = config.rod;
  const auto [p, columns] = defaultInvariants(piston);
  const auto described = problemOf(rc, columns);
  const rod::SliderCrankProblem closed = closedFormOf(rc, columns);
  const SecondOrderProblem& problem =
      closedForm ? static_cast<const SecondOrderProblem&>(closed) : *described;
  IntegratorOptions options = piston.integratorOptions();
  options.method = "rk4";
  options.step = 1e-4;
  const ForwardResult forward = simulate(problem, p, options);
  const auto storage = createStorage("full:stages=1");
  const GradientResult gradient = computeGradient(problem, p, options, *storage);
  std::printf("%s: psi1 %.17g (forward) %.17g (gradient)\n", closedForm ? "closed form" : "default path",
              forward.objective, gradient.objective);
}

double wallSeconds() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// The one-vector sweeps of K's factor that the eigen-solve's Lanczos iteration runs (one of each per
/// step), on the initial design of each mesh up to `largest`: the forward sweep L^-1 (the class's serial
/// block sweep with one column), for scale, and Eigen's back-substitution against the one on the
/// subtrees (rod::SubtreeParallelLdlt, the same bits), wall seconds, best of 5 (the second core is what
/// it gains, so CPU time would not show it).
void sweepTable(int largest) {
  std::printf(
      "| mesh | order | share on the subtrees | L^-1 (forwardSweep, serial) | L^-T, Eigen | L^-T, subtrees | "
      "same bits |\n"
      "|---|---:|---:|---:|---:|---:|---|\n");
  for (int m = 0; m <= largest && m < 5; ++m) {
    const Config config = meshConfig(m);
    const PistonRod piston(config);
    const rod::FeModel model(config.rod, piston.initialDesign());
    const rod::StiffnessFactorization k(model.stiffness(), rod::stiffnessOrdering(model));
    const rod::SubtreeParallelLdlt& ldlt = k.solver();
    const Vector b = Vector::LinSpaced(k.size(), 1.0, 2.0);
    double forward = 1e30, eigen = 1e30, subtrees = 1e30;
    Vector x, y, z;
    for (int run = 0; run < 5; ++run) {
      x = b;
      double start = wallSeconds();
      ldlt.forwardSweep(x.data(), 1);
      forward = std::min(forward, wallSeconds() - start);
      y = b;
      start = wallSeconds();
      ldlt.matrixU().solveInPlace(y);
      eigen = std::min(eigen, wallSeconds() - start);
      z = b;
      start = wallSeconds();
      ldlt.backwardSweep(z.data(), 1, true);
      subtrees = std::min(subtrees, wallSeconds() - start);
    }
    std::printf("| %dx%d | %ld | %.2f | %.4f | %.4f | %.4f | %s |\n", kMeshes[m][0], kMeshes[m][1],
                static_cast<long>(k.size()), ldlt.parallelShare(), forward, eigen, subtrees,
                std::memcmp(y.data(), z.data(), sizeof(double) * static_cast<std::size_t>(y.size())) == 0
                    ? "yes"
                    : "NO");
    std::fflush(stdout);
  }
}

int main(int argc, char** argv) {
  const int largest = argc > 1 ? std::atoi(argv[1]) : 3;
  const int only = argc > 2 ? std::atoi(argv[2]) : 0;
  if (only == 5) {
    sweepTable(largest);
    return 0;
  }
  if (only == 2) {
    mechanismTable();
    return 0;
  }
  if (only == 3 || only == 4) {
    rk4SweepsForCallgrind(only == 4);
    return 0;
  }
  if (only != 1) phaseTable(largest);
  integratorTable();
  mechanismTable();
  return 0;
}
