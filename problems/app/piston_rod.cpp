#include <hindsight/problems/app/piston_rod.h>

#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/app/gradient_routes.h>
#include <hindsight/problems/mechanism/mechanism_problem.h>
#include <hindsight/problems/rod/design_gradient.h>
#include <hindsight/problems/rod/esl.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/invariants.h>
#include <hindsight/problems/rod/modal_reduction.h>
#include <hindsight/problems/rod/solid_member.h>
#include <hindsight/storage/lossy_storage.h>
#include <hindsight/storage/storage_factory.h>

#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

// lossy:target=T's calibration for the reduced rod (LossyStorage::calibrate): the ratio of relative
// gradient error to relative state error measured against full storage was at most 0.05 with
// generalized-alpha (h = 5e-4; 10 and 20 modes, T = 3 and 10 s, bounds 3e-8 to 1e-4) and 0.09 with rk4
// (h = 1e-4), so S = 0.3 keeps a margin of 6 and 3.3 (docs/theory/storage.md, "Compression along time";
// the default-path test in tests/problems/app checks it). It was measured on the plate: other integrators
// and the solid member keep the storage's default.
void calibrateLossyTarget(TrajectoryStorage& storage, const std::string& integrator, bool plate) {
  auto* lossy = dynamic_cast<LossyStorage*>(&storage);
  if (lossy != nullptr && plate && (integrator == "generalized-alpha" || integrator == "rk4")) {
    lossy->calibrate(0.3);
  }
}

}  // namespace

PistonRod::PistonRod(const Config& config)
    : PistonRod(config, std::make_shared<rod::StiffnessFactorizationPool>()) {}

PistonRod::PistonRod(const Config& config, std::shared_ptr<rod::StiffnessFactorizationPool> factorizations)
    : config_(config), stiffness_(std::move(factorizations)) {
  if (!stiffness_) throw std::invalid_argument("PistonRod: the factorisation pool is null");
  config_.validate();
}

Vector PistonRod::initialDesign() const { return Vector::Constant(designCount(), config_.rod.initialDesign); }

IntegratorOptions PistonRod::integratorOptions() const {
  const SimulationSettings& s = config_.simulation;
  IntegratorOptions options;
  options.method = s.integrator;
  options.t0 = 0.0;
  options.t1 = config_.rod.endTime;
  options.adaptive = s.adaptive;
  options.relativeTolerance = s.relativeTolerance;
  options.absoluteTolerance = s.absoluteTolerance;
  options.rhoInfinity = s.rhoInfinity;
  if (s.adaptive) {
    options.step = s.step;
  } else {
    const long samples = config_.rod.eslSamples;
    const long blocks = static_cast<long>(std::ceil(options.t1 / s.step / samples - 1e-9));
    options.step = options.t1 / static_cast<double>(std::max(1L, blocks) * samples);
  }
  options.validate();
  return options;
}

PistonRodEvaluation PistonRod::evaluate(ConstVectorRef design, const Request& request) const {
  // The member is the plate or the solid (problems/rod/member.h); everything after the model is the same
  // code for both, and the mechanism sees only the invariants.
  Stopwatch phase;
  if (config_.rod.isSolid()) return evaluateMember(rod::SolidMember(config_.rod, design), request, phase);
  return evaluateMember(rod::FeModel(config_.rod, design), request, phase);
}

template <class Member>
PistonRodEvaluation PistonRod::evaluateMember(const Member& model, const Request& request,
                                              Stopwatch& phase) const {
  const rod::RodConfig& rc = config_.rod;
  PistonRodEvaluation out;
  // A design the eigensolver cannot handle (a near-mechanism: the stiffness is singular or not positive
  // definite, or the eigenpairs do not converge) is a numerical outcome of that design, like a diverged
  // simulation: as NumericalError the optimizer's divergence guard and GCMMA's trials step back from it
  // instead of ending the run. One factorisation of K serves the eigen-solve, its refinement, ESL and the
  // chain's adjoint solves.
  // The factorisation goes back to the pool when the evaluation ends (also by an exception: a later
  // design refactorises it from scratch).
  struct Kept {
    rod::StiffnessFactorizationPool& pool;
    std::unique_ptr<rod::StiffnessFactorization> factorization;
    ~Kept() { pool.give(std::move(factorization)); }
  } kept{*stiffness_, nullptr};
  std::unique_ptr<rod::StiffnessFactorization>& stiffnessPointer = kept.factorization;
  const rod::ModalBasis basis = [&] {
    try {
      stiffnessPointer = stiffness_->take(model.stiffness(), rod::stiffnessOrdering(model));
      return rod::computeModalBasis(model, rod::ModalReductionOptions::fromConfig(rc), *stiffnessPointer);
    } catch (const NumericalError&) {
      throw;
    } catch (const std::runtime_error& e) {
      throw NumericalError(std::string("the modal reduction of this design failed: ") + e.what(), 0.0);
    }
  }();
  const rod::InertiaInvariants invariants = rod::computeInvariants(model, basis);
  const Vector p = invariants.pack();
  for (int i = 0; i < basis.eigenmodeCount; ++i) out.frequenciesHz.push_back(basis.frequencyHz(i));
  out.eigenvalues = basis.eigenvalues.head(basis.eigenmodeCount);
  out.gapRatio = basis.gapRatio;
  out.warning = basis.warning;
  out.modes = basis.modesFull;
  out.volumeFraction = model.volumeFraction();
  out.dvolume = model.volumeFractionGradient();
  out.modelSeconds = phase.seconds();

  // The mechanism whose flexible member the rod is: the configuration's description, or without one
  // the paper's slider-crank described by the same builder (mechanism::sliderCrank), so that every
  // mechanism takes one path (problems/mechanism/mechanism_problem.h). The closed form of the
  // slider-crank (tests/support/slider_crank.h) is the tests' independent reference for it.
  mechanism::Mechanism described =
      config_.mechanism ? *config_.mechanism
                        : mechanism::sliderCrank(rc.crankRadius, rc.length, rc.crankSpeed, rc.rampTime);
  described.member.length = rc.length;
  auto mechanismProblem =
      std::make_unique<mechanism::MechanismProblem>(described, basis.columnCount(), invariants.spatial());
  const int modalOffset = mechanismProblem->freeCount();  // q within the minimal coordinates
  const mechanism::MechanismProblem& mechanismModel = *mechanismProblem;
  const std::unique_ptr<SecondOrderProblem> problemPointer = std::move(mechanismProblem);
  const SecondOrderProblem& problem = *problemPointer;
  const IntegratorOptions options = integratorOptions();

  // q(t_k) at the ESL sample times, which are grid points of the fixed-step grid.
  const int n = basis.columnCount();
  const int samples = rc.eslSamples;
  Matrix sampled = Matrix::Zero(n, samples);
  std::int64_t stride = 0;
  if (!options.adaptive) {
    stride = static_cast<std::int64_t>(std::llround(options.t1 / options.step)) / samples;
  } else if (request.psi2) {
    throw std::invalid_argument(
        "psi2 needs fixed steps (simulation.adaptive = false): its load times must be grid points");
  }
  // The member's pose for request.motion: the full coordinates z(t, y) from the mechanism's position
  // solve, in a workspace of its own (the simulation's workspaces and bits are untouched).
  std::unique_ptr<ProblemWorkspace> motionWorkspace;
  Vector coordinates, coordinateRates;
  if (request.motion) {
    motionWorkspace = mechanismModel.createModelWorkspaceFor(p);
    coordinates.resize(mechanismModel.fullCoordinateCount());
    coordinateRates.resize(mechanismModel.fullCoordinateCount());
  }
  const StateObserver observer = [&](std::int64_t step, double t, ConstVectorRef z) {
    if (stride > 0 && step > 0 && step % stride == 0 && step / stride <= samples) {
      sampled.col(step / stride - 1) = z.segment(modalOffset, n);
    }
    if (request.motion) {
      const int m = mechanismModel.coordinateCount();
      mechanismModel.coordinates(t, z.head(m), z.segment(m, m), p, coordinates, coordinateRates,
                                 motionWorkspace.get());
      request.motion(t, coordinates.segment(mechanismModel.memberOffset(), 3), z.segment(modalOffset, n));
    }
  };

  phase.restart();
  if (request.psi1Gradient) {
    GradientResult result;
    if (config_.simulation.adjoint == AdjointMethod::Discrete) {
      auto storage = createStorage(config_.simulation.storage);
      calibrateLossyTarget(*storage, options.method, !config_.rod.isSolid());
      result = computeGradient(problem, p, options, *storage, observer);
    } else {
      // The continuous and CVODES routes take their own steps; the ESL samples come from a
      // separate fixed-step forward run when psi2 is asked for.
      GradientOptions routes;
      routes.adjoint = config_.simulation.adjoint;
      routes.integrator = options;
      routes.storage = config_.simulation.storage;
      routes.continuous.relativeTolerance = config_.simulation.relativeTolerance;
      routes.continuous.absoluteTolerance = config_.simulation.absoluteTolerance;
      routes.cvodes.relativeTolerance = config_.simulation.relativeTolerance;
      routes.cvodes.absoluteTolerance = config_.simulation.absoluteTolerance;
      routes.cvodes.maxSteps = 100'000'000;
      result = computeGradientByMethod(problem, p, routes);
      if (request.psi2) simulate(problem, p, options, observer);
    }
    out.psi1 = result.objective;
    out.summary = result.summary;
    out.simulationSeconds = phase.restart();
    rod::DesignGradientOptions chain;
    chain.method = config_.simulation.eigenvectorRoute;
    out.dpsi1 =
        rod::computeDesignGradient(model, basis, result.gradient, chain, {}, *stiffnessPointer).gradient;
    out.chainSeconds = phase.seconds();
  } else {
    ForwardResult result = simulate(problem, p, options, observer);
    out.psi1 = result.objective;
    out.summary = result.summary;
    out.simulationSeconds = phase.seconds();
  }

  out.psi2 = std::numeric_limits<double>::quiet_NaN();
  if (request.psi2) {
    phase.restart();
    // The loads come from this design's own simulation: psi2 follows from K_ee without a solve with K.
    const rod::EslResult esl =
        rod::evaluateEslAtLoadDesign(model, basis, invariants.kee, sampled, options.t1, request.psi2Gradient);
    out.psi2 = esl.value;
    if (request.psi2Gradient) out.dpsi2 = esl.gradient;
    out.eslSeconds = phase.seconds();
  }
  return out;
}

}  // namespace hindsight
