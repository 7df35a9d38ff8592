// The piston-rod benchmark end to end (docs/design.md §2-4): for a design x, the SIMP FE model,
// the pinned-roller modal basis, the inertia invariants, the slider-crank simulation with psi1 and
// its adjoint gradient dpsi1/dp, the chain to dpsi1/dx through the invariants and the eigenvector
// sensitivities, the equivalent-static-load objective psi2 with its gradient, and the volume
// fraction. The model object is immutable; evaluate() builds everything for one design.
#pragma once

#include <hindsight/engine/adjoint.h>
#include <hindsight/engine/stopwatch.h>
#include <hindsight/problems/app/config.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {
namespace rod {
class StiffnessFactorizationPool;
}

struct PistonRodEvaluation {
  double psi1 = 0.0;
  double psi2 = 0.0;  ///< NaN when not requested
  double volumeFraction = 0.0;
  std::vector<double> frequenciesHz;
  Vector eigenvalues;  ///< lambda_i = omega_i^2 [1/s^2] of the kept eigenmodes (ascending)
  double gapRatio = 0.0;
  std::string warning;             ///< spectral-gap warning, empty when the gap is comfortable
  Vector dpsi1;                    ///< d psi1 / dx over the design variables (empty unless requested)
  Vector dpsi2;                    ///< d psi2 / dx (ESL approximation; empty unless requested)
  Vector dvolume;                  ///< d(V/V0)/dx
  Matrix modes;                    ///< the kept modes on all DOFs (dofCount x n)
  RunSummary summary;              ///< of the psi1 simulation (and adjoint when a gradient was computed)
  double modelSeconds = 0.0;       ///< FE assembly, modes, invariants
  double simulationSeconds = 0.0;  ///< forward (+ adjoint) sweep
  double chainSeconds = 0.0;       ///< dpsi/dp -> dpsi/dx
  double eslSeconds = 0.0;
};

class PistonRod {
 public:
  /// Validates the configuration (std::invalid_argument naming the field).
  explicit PistonRod(const Config& config);
  /// The same, keeping K's factorisation between designs in `factorizations`, which other rods of the same
  /// mesh may share (the scenarios of one run: at most one kept factorisation per concurrent evaluation).
  PistonRod(const Config& config, std::shared_ptr<rod::StiffnessFactorizationPool> factorizations);

  const Config& config() const { return config_; }
  int designCount() const { return config_.rod.designCount(); }
  /// The uniform initial design x0.
  Vector initialDesign() const;

  /// The member's motion at one step of the forward sweep: t, its frame's pose (x, y, beta) in the global
  /// plane and its modal coordinates q (the columns of PistonRodEvaluation::modes).
  using MotionObserver = std::function<void(double t, ConstVectorRef pose, ConstVectorRef q)>;

  struct Request {
    bool psi1Gradient = true;
    bool psi2 = true;
    bool psi2Gradient = true;
    /// Called at every step of the forward sweep (t = t0 included) when set; the pose comes from the
    /// mechanism's position solve in a workspace of its own, so the run's results keep their bits.
    MotionObserver motion;
  };
  /// Throws std::invalid_argument for a design of wrong size or out of bounds (naming the index),
  /// NumericalError for a failed simulation, std::runtime_error for a failed eigen solve.
  PistonRodEvaluation evaluate(ConstVectorRef design, const Request& request) const;
  PistonRodEvaluation evaluate(ConstVectorRef design) const { return evaluate(design, Request{}); }

  /// The integrator options actually used: the fixed step is refined so that N is a multiple of the
  /// number of ESL samples and the sample times t_k = k t1 / N_esl are grid points.
  IntegratorOptions integratorOptions() const;

 private:
  /// evaluate() for the member model of the configuration (rod::FeModel or rod::SolidMember).
  template <class Member>
  PistonRodEvaluation evaluateMember(const Member& model, const Request& request, Stopwatch& phase) const;

  Config config_;
  // The factorisation of K kept from one design to the next (the symbolic analysis depends on the mesh
  // alone); shared by copies of this object, which evaluate the same mesh.
  std::shared_ptr<rod::StiffnessFactorizationPool> stiffness_;
};

}  // namespace hindsight
