// Topology optimization of the piston rod (docs/design.md §7; Held, Knüfer & Seifried, section 6):
//
//   minimize    psi(x) / psi(x0)
//   subject to  (V(x)/V0) / volumeFraction - 1 <= 0,   designLowerBound <= x_d <= 1,
//
// with MMA (problems/topopt/mma.h, the constants of Svanberg's 2007 note, which are the MmaOptions defaults),
// one constraint. psi is optimization.objective:
//   psi1  the integral compliance, with its exact adjoint gradient (the paper's route);
//   psi2  the equivalent-static-load compliance: loads from the simulation at the current design, held
//         fixed for the gradient (the paper's comparison route). psi1 of every design is evaluated too,
//         by the same simulation, so both routes are compared on the same measure.
// psi2 is evaluated on both routes (one factorisation of K, cheap next to the simulation).
//
// With optimization.filterRadius >= 1 the model sees the filtered density xf = F x
// (problems/topopt/density_filter.h) and the gradients are chained through F^T; 0 (the default, the paper's
// choice) means no filter and reproduces the paper's checkerboards.
//
// Iteration k evaluates the design x_k and, while k < optimization.iterations, performs the MMA update
// x_k -> x_{k+1}. After the last update the final record (iteration N, no update) evaluates the run's
// best feasible design x_k* (OptimizerState::bestDesign; x_N itself when no design was feasible, with
// the stopping rule off, the paper's setting, and always with projection, whose model changes with the
// iteration), so a run of N iterations has N + 1
// records, the last one the final design, and a run that never settles still ends at its best.
//
// Stopping rule: after each update the record holds the first-order optimality residual of the MMA
// problem at x_k (problems/topopt/mma.h, kktResidual, with the update's multipliers) and the largest
// design change max|x_{k+1} - x_k|. When the residual is at most optimization.kktTolerance, the
// change at most optimization.changeTolerance, x_k is feasible (kFeasibilitySlack) and its objective
// is no higher than that of x_{k-1} (the MMA state keeps it), x_k is the final design: the update is
// not taken, the record is marked converged, and the run ends after k + 1 records instead of
// iterations + 1. "No higher" is against every feasible design before x_k, not only x_{k-1}: a run the
// rule ends ends at its best feasible design. The change test may be replaced by stagnation: the optimized
// objective of the last five designs varying by at most optimization.objectiveTolerance (relative). Either of
// kktTolerance and changeTolerance 0 turns the rule off. The decision uses only what step k computes and the
// stored state, so a resumed run stops at the same iteration.
//
// End game (optimization.endGame, mma-adaptive with the stopping rule on, one objective or the sum of the
// scenarios', changeTolerance at least MMA's smallest move limit; a declared addition to MMA): on the
// undamped rod the residual stalls above kktTolerance and the objective can leave its best design for a
// resonance peak and creep back for a hundred updates, so some starts never meet the rule. When no more
// than endGameReserve() updates remain before optimization.iterations (in runs long enough for that: not
// within the first endGameReserve() updates, so a short run's budget goes to descent) and the rule has
// not ended the run, it refines: MMA's move limit no longer grows but halves at every update (a trust
// region that only contracts), and an update that finds x_k infeasible or worse than the best feasible
// design so far is not taken: x_{k+1} is that best design, evaluated again (the same bits) with MMA
// restarted there. The limit thus reaches changeTolerance within endGameReserve() updates, at the best
// design, and the trust-region test ends the run by the rule before the cap. A run that meets the rule
// on its own is not touched. Deterministic and part of the stored state (refining), so a resumed run
// refines the same way (docs/guides/optimizer.md has the measurements on the rod).
//
// Divergence guard (a declared addition to plain MMA): the inertia-loaded rod is strongly nonlinear in
// x, and MMA's large early steps can reach a soft, near-mechanism design (first frequency below 1 Hz)
// whose simulation diverges (the floating-frame equations have no geometric stiffening). When the
// simulation of a new design x_k fails with a NumericalError, or its objective exceeds
// maxObjectiveGrowth times the initial one (a diverging response that is still finite), x_k is moved
// halfway back to the previous, successfully evaluated design x_{k-1} (kept in the MMA state as
// xold1), up to maxBacktracks times; the record counts the halvings. Deterministic, so restart stays
// bit-identical. It keeps a run alive; it does not make the standard MMA move limit 0.5 a good choice for
// this problem (optimization.moveLimit 0.1-0.2 descends steadily on it; the default is 0.2).
//
// Opt-in additions: GCMMA, the frequency guard, projection (defaults keep every bit of the runs above):
//  * optimization.method = gcmma: the update is GCMMA (problems/topopt/gcmma.h) instead of MMA; its
//    trial designs are simulated (values only; a diverged or exploding trial counts as
//    non-conservative), so every accepted design is feasible and its objective is no higher than the
//    previous one. The record counts the trials (innerIterations). With scenarios a trial evaluates every
//    scenario, collectively over the MPI ranks, and GCMMA solves MMA's problem of that aggregate
//    (scenarioTrials); under mpirun GCMMA needs scenarios.
//  * optimization.minFirstFrequency = f > 0: a second constraint 1 - lambda_1(x) / (2 pi f)^2 <= 0 on the
//    first eigenvalue of the pinned-roller rod, with its exact derivative
//    (problems/rod/eigen_constraint.h; a repeated lambda_1 is guarded through its cluster mean).
//  * optimization.projectionBeta = beta0 > 0: the model sees xMin + (1 - xMin) H(F x), the Heaviside
//    projection of the filtered density (problems/topopt/heaviside_projection.h) with beta doubling
//    every projectionEvery iterations up to projectionBetaMax; gradients are chained through H' and F^T.
// Every record also holds the grayness (fraction of design elements the model sees in (0.1, 0.9)) and
// the first natural frequency.
// Scenarios (problems/rod/scenarios.h, problems/topopt/scenario_objective.h): with a
// `scenarios` list every scenario is evaluated (over MPI ranks and threads), f_s = w_s psi_s(x) /
// psi_s(x0), and MMA minimizes sum_s f_s (aggregate sum) or, for aggregate max, z over (x, z) subject
// to f_s(x) - z <= 0 and the volume bound (the bound formulation; z in [0, maxObjectiveGrowth max_s
// w_s], restarted at max_s f_s each iteration; its MMA state is OptimizerState::bound). The divergence
// guard applies per scenario; the frequency guard is one constraint of the design (every rank evaluates it
// from a scenario it owns, so at most as many ranks as scenarios). A run without a scenarios list takes the
// same path as the list of its one configuration (weight 1; the scale psi(x0) is then kept as
// OptimizerState::objectiveScale).
//
// Restart: everything that carries over between iterations is the OptimizerState (plain data). An
// optimizer restored from a stored state continues bit for bit as the uninterrupted one (evaluations
// are deterministic, MMA restores exactly).
#pragma once

#include <hindsight/problems/app/config.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/topopt/density_filter.h>
#include <hindsight/problems/topopt/density_filter_3d.h>
#include <hindsight/problems/topopt/gcmma.h>
#include <hindsight/problems/topopt/geometry_export.h>
#include <hindsight/problems/topopt/heaviside_projection.h>
#include <hindsight/problems/topopt/mma.h>
#include <hindsight/problems/topopt/scenario_objective.h>

#include <limits>
#include <memory>
#include <optional>

namespace hindsight {

/// One iteration's record (the history row). Seconds are wall-clock and differ between runs;
/// everything else is reproducible bit for bit.
struct IterationRecord {
  int iteration = 0;
  double psi1 = 0.0;
  double psi2 = 0.0;
  double volumeFraction = 0.0;  ///< V/V0 over all elements (solid end columns included)
  /// max_d |x_{k+1,d} - x_{k,d}| of the update made in this iteration; NaN for the final evaluation.
  double maxDesignChange = std::numeric_limits<double>::quiet_NaN();
  double evaluationSeconds = 0.0;
  double mmaSeconds = 0.0;
  double totalSeconds = 0.0;  ///< evaluation + MMA (OptimizationRun adds its picture writing)
  int backtracks = 0;         ///< halvings toward the previous design after a diverged simulation
  /// Fraction of the design elements whose density (as the model sees it) is in (0.1, 0.9).
  double grayness = std::numeric_limits<double>::quiet_NaN();
  /// First natural frequency of the pinned-roller rod [Hz].
  double firstFrequencyHz = std::numeric_limits<double>::quiet_NaN();
  /// GCMMA: trial designs simulated in this iteration's update (0 for MMA and the final evaluation).
  int innerIterations = 0;
  /// First-order optimality residual at this iteration's design with the update's multipliers
  /// (problems/topopt/mma.h, kktResidual); NaN when no update was computed (the final evaluation).
  double kktResidual = std::numeric_limits<double>::quiet_NaN();
  /// The stopping rule held here: this record is the final design's, its update was not taken.
  bool converged = false;
  /// With scenarios (problems/rod/scenarios.h): every scenario's psi1 and psi2, in scenario order;
  /// psi1 and psi2 above are then those of the worst scenario (largest w_s psi_s / psi_s(x0) of the
  /// optimized objective). Empty without scenarios.
  std::vector<double> scenarioPsi1;
  std::vector<double> scenarioPsi2;
  int worstScenario = -1;  ///< index of the worst scenario (with scenarios), else -1
};

/// What carries over between iterations.
struct OptimizerState {
  int iteration = 0;            ///< number of completed MMA updates; the next record has this index
  Vector design;                ///< x_iteration, the design variables (designCount)
  MmaState mma;                 ///< MMA after `iteration` updates
  double objectiveScale = 0.0;  ///< psi(x0); 0 until the first evaluation
  /// With scenarios: psi_s(x0) per scenario (empty until the first evaluation and without scenarios);
  /// objectiveScale is then the aggregate at x0 (sum or max of the weights).
  Vector scenarioScales;
  /// With aggregate max: MMA's state of the bound variable z (xold1, xold2, low, upp); else empty.
  Vector bound;
  /// The optimized (scaled) objective of the last designs, oldest first, at most kObjectiveWindow: the
  /// stopping rule's stagnation test (optimization.objectiveTolerance).
  std::vector<double> recentObjectives;
  static constexpr std::size_t kObjectiveWindow = 5;
  /// The lowest optimized (scaled) objective of a feasible design so far; NaN before the first. The
  /// stopping rule ends a run only on a design that is no worse, so a run it ends ends at its best.
  double bestObjective = std::numeric_limits<double>::quiet_NaN();
  /// The design variables of that design (empty before the first): what the final evaluation of a run
  /// that reaches optimization.iterations evaluates (see the class comment).
  Vector bestDesign;
  /// The end game's refinement has begun (optimization.endGame; the class comment, "End game").
  bool refining = false;
};

class TopologyOptimizer final {
 public:
  /// Validates the configuration (std::invalid_argument naming the field). Starts from x0. With
  /// several processes (problems/topopt/communicator.h) every rank constructs one and calls step()
  /// in lockstep; each evaluates its own scenarios and all hold the same state.
  explicit TopologyOptimizer(const Config& config, const Communicator& communicator = Communicator::world());

  /// The configuration (with its scenarios, if any).
  const Config& config() const { return config_; }
  /// The rod of the first scenario (the rod itself without scenarios).
  const PistonRod& rod() const { return scenarios_.rod(0); }
  const ScenarioObjective& scenarios() const { return scenarios_; }
  int designCount() const { return config_.rod.designCount(); }
  /// True with several scenarios and optimization.aggregate = max: MMA carries the bound variable z.
  bool boundFormulation() const { return bound_; }

  const OptimizerState& state() const { return state_; }
  /// Continues from a stored state. Throws std::invalid_argument when sizes do not match the
  /// configuration or the iteration is outside [0, optimization.iterations].
  void restore(const OptimizerState& state);

  /// True when the final design has been evaluated.
  bool finished() const { return finished_; }

  /// One iteration: evaluates the current design and, while fewer than optimization.iterations
  /// updates were made, performs the MMA update; otherwise evaluates the final design and sets
  /// finished(). Throws std::logic_error when already finished; evaluation errors propagate
  /// (NumericalError, std::runtime_error) and leave the state unchanged.
  IterationRecord step();

  /// The evaluation made by the last step() (modes, frequencies, gradients) of the first scenario
  /// this rank owns (rank 0: scenario 0); empty before, and on a rank that owns no scenario.
  const std::optional<PistonRodEvaluation>& lastEvaluation() const { return last_; }
  /// The design variables evaluated by the last step() (x_k after any backtracking); empty before.
  const Vector& lastEvaluatedDesign() const { return lastDesign_; }

  /// Wall time of this process over all step() calls: evaluating its own scenarios, and in the
  /// exchange of the scenarios' results between ranks (waiting for the slowest rank included);
  /// the smallest exchange of one step estimates the pure communication cost.
  struct Times {
    double localSeconds = 0.0;
    double exchangeSeconds = 0.0;
    double smallestExchangeSeconds = 0.0;
    int exchanges = 0;
  };
  const Times& times() const { return times_; }

  /// Halvings toward the previous design before a failed simulation is reported.
  static constexpr int maxBacktracks = 10;
  /// A design whose largest constraint value is at most this counts as feasible (MMA's interior-point
  /// solver ends active constraints at about -1e-7 / lambda, either side of zero).
  static constexpr double kFeasibilitySlack = 1e-6;
  /// The one test of feasibility, for the stopping rule and for the best design of a history: every
  /// constraint value at most kFeasibilitySlack.
  static bool feasible(ConstVectorRef constraints) {
    return constraints.size() == 0 || constraints.maxCoeff() <= kFeasibilitySlack;
  }
  /// The constraint values of a history record, as constraintsOf() forms them: the volume bound, and
  /// the frequency guard from the record's first natural frequency when optimization.minFirstFrequency
  /// > 0 (a NaN frequency, a record without eigenpairs, counts as violating it).
  static Vector recordConstraints(const IterationRecord& record, const OptimizationSettings& settings);
  /// An objective above this multiple of psi(x0) counts as a diverged response.
  static constexpr double maxObjectiveGrowth = 10.0;

  /// The element densities the model sees for design variables x (filtered when a filter is on),
  /// over ALL elements on the picture grid (problems/topopt/pictures.h numbering e = row * nx + column,
  /// solid end columns = 1); length nx * ny. Of the solid member: the mean through the thickness.
  Vector densityGrid(ConstVectorRef design) const;
  /// The solid member's element densities the model sees in iteration k, in SolidModel's element order
  /// ((i ny + j) nz + k, problems/rod/solid_model.h; end columns = 1), nx ny nz entries.
  Vector solidDensities(ConstVectorRef design, int iteration) const;
  /// The same on the solid's box grid in millimetres, for the STL and VTU writers (geometry_export.h).
  BoxDensityField solidField(ConstVectorRef design, int iteration) const;

  /// The design variables step() evaluates from `state` (before any backtracking): x_k, or, for the
  /// final evaluation of a run that reached optimization.iterations, its best feasible design. Of a
  /// finished run's stored state: the final design, which export draws.
  Vector designToEvaluate(const OptimizerState& state) const;

  /// What the model sees in iteration k for design variables x: the filtered design, projected when
  /// optimization.projectionBeta > 0 (with the beta of iteration k); one entry per design variable.
  Vector modelDesign(ConstVectorRef design, int iteration) const;
  /// The chain rule through filter and projection: d phi / dx from d phi / d(modelDesign(x, k)).
  Vector chainToDesign(ConstVectorRef gradient, ConstVectorRef design, int iteration) const;

 private:
  Vector physicalDesign(ConstVectorRef design) const;        // filtered design variables
  MmaState fullMmaState(const OptimizerState& state) const;  // state.mma with z's entries appended
  Vector chainThroughFilter(ConstVectorRef gradient) const;  // F^T on the design variables
  // The projection of iteration k; empty when optimization.projectionBeta = 0.
  std::optional<HeavisideProjection> projectionAt(int iteration) const;
  int constraintCount() const;
  // The constraint values (and, when jacobian is not null, their gradients over the design
  // variables) of an evaluation of `design` in iteration k.
  // `evaluation` (the full one, for the eigenvalues) may be null without the frequency guard.
  Vector constraintsOf(double volumeFraction, ConstVectorRef dvolume, const PistonRodEvaluation* evaluation,
                       ConstVectorRef design, int iteration, Matrix* jacobian) const;
  // Picture-grid index of every design variable.
  std::vector<int> designToGrid_;

  // One MMA or GCMMA update (GCMMA when `trials` is not null) of x from the MMA state `from`: x becomes
  // the next iterate; record gets the KKT residual at the current x and GCMMA's trial count. Returns
  // the MMA state after the update.
  // `recent` holds the objectives of the last designs, this one's last (the stagnation test);
  // `bestSoFar`: no feasible design before this one had a lower objective.
  MmaState updateDesign(const MmaState& from, double objective, const Vector& objectiveGradient,
                        const Vector& constraints, const Matrix& jacobian, const Vector& lower,
                        const Vector& upper, const Gcmma::Evaluate* trials, const std::vector<double>& recent,
                        bool bestSoFar, Vector& x, IterationRecord& record);

  // The update of every run: sum or max of the scenarios' relative objectives (scenarios.h); a run
  // without a scenarios list is one scenario of weight 1.
  /// GCMMA's trial evaluations (collective over the ranks).
  Gcmma::Evaluate scenarioTrials(const OptimizerState& next) const;
  void updateFromScenarios(const ScenarioResults& results, OptimizerState& next, const Vector& design,
                           IterationRecord& record);
  // kktTolerance and changeTolerance both > 0: the stopping rule, and with it the end at the best design.
  bool stoppingRuleOn() const;
  // The end game applies (see the header comment): endGame, mma-adaptive, the rule on, no bound variable.
  bool endGameOn() const;
  // The objective of the last kObjectiveWindow designs varies by at most objectiveTolerance (relative).
  bool stagnated(const std::vector<double>& recent) const;
  // The most updates the end game needs: two per halving of moveLimit down to changeTolerance (an update
  // and a return to the best design), plus one.
  int endGameReserve() const;
  // psi_s(x0), the scale of scenario s: the state's objectiveScale without a scenarios list.
  double scenarioScale(const OptimizerState& state, int s) const;

  Config config_;
  ScenarioObjective scenarios_;
  bool multiple_;                              // the configuration lists scenarios
  bool bound_;                                 // multiple_ and aggregate max
  DensityFilter filter_;                       // the plate's (the identity for the solid)
  std::unique_ptr<DensityFilter3d> filter3d_;  // the solid member's (rod.elementsThroughThickness >= 1)
  Mma mma_;
  std::unique_ptr<Gcmma> gcmma_;  // optimization.method = gcmma
  OptimizerState state_;
  int lastIteration_ = 0;  // the iteration of the last evaluated design (its projection)
  bool finished_ = false;
  bool settled_ = false;  // the last updateDesign met the stopping rule
  std::optional<PistonRodEvaluation> last_;
  Vector lastDesign_;
  Times times_;
};

}  // namespace hindsight
