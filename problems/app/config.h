// The configuration of a piston-rod run: the model (rod::RodConfig, every docs/design.md §2 number),
// the simulation and gradient settings, and the optimisation settings. Read from and written to JSON
// strictly: an unknown field, a wrong type or an out-of-range value throws std::invalid_argument
// naming the field ("rod.modeCount"), the value and the allowed range. `--set KEY=VALUE` on the
// command line goes through the same checks. The fields, their types, ranges, units and descriptions
// are one table, problems/app/config_schema.h, which the reader, the writer, `hindsight config` and
// the CLI reference share; the defaults are the member initializers below.
#pragma once

#include <hindsight/problems/app/gradient_routes.h>
#include <hindsight/problems/mechanism/mechanism.h>
#include <hindsight/problems/rod/design_gradient.h>
#include <hindsight/problems/rod/rod_config.h>
#include <hindsight/problems/rod/scenarios.h>
#include <hindsight/storage/schedule.h>

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace hindsight {

/// simulation.model: the modal slider-crank of docs/design.md §3 or the unreduced FE rod of §9.
enum class RodModel { Reduced, Full };
/// optimization.objective: psi1 (integral compliance) or psi2 (equivalent static loads).
enum class Objective { Psi1, Psi2 };

// The configuration's choices by name: the JSON strings, parsed and printed here only (the adjoint
// route's names live with AdjointMethod in problems/app/gradient_routes.h). parse* throws
// std::invalid_argument listing the names.
std::string toString(RodModel model);
std::string toString(Objective objective);
std::string toString(rod::EigenvectorSensitivityMethod route);  ///< "adjoint-nelson" | "nelson"
RodModel parseRodModel(const std::string& name);
Objective parseObjective(const std::string& name);
rod::EigenvectorSensitivityMethod parseEigenvectorRoute(const std::string& name);

struct SimulationSettings {
  /// rk4 | dopri5 | trbdf2 | sdirk2 | midpoint | generalized-alpha | hht-alpha (the last two: reduced
  /// model only, fixed steps; the rod's modal slider-crank is a SecondOrderProblem)
  /// Default: generalized-alpha (rho_inf = 0.8) at h = 5e-4: psi1 and dpsi1/dx within 1e-4 (relative)
  /// of the converged values (6e-5 on the hardest tested design), unconditionally stable; rk4 with
  /// step = 1e-4 is the converged reference (docs/guides/performance.md).
  std::string integrator = "generalized-alpha";
  double step = 5e-4;                ///< [s]; the grid is refined so that the ESL times are grid points
  bool adaptive = false;             ///< dopri5 / trbdf2 only; psi2 needs a fixed step
  double relativeTolerance = 1e-8;   ///< adaptive steps
  double absoluteTolerance = 1e-12;  ///< adaptive steps
  /// generalized-alpha / hht-alpha: spectral radius at infinity, [0, 1] ([0.5, 1] for hht-alpha).
  double rhoInfinity = 0.8;
  std::string storage = "full";                     ///< trajectory storage spec, e.g. binomial:checkpoints=50
  AdjointMethod adjoint = AdjointMethod::Discrete;  ///< discrete | continuous | cvodes
  /// adjoint-nelson | nelson (Nelson per design variable, the paper's route)
  rod::EigenvectorSensitivityMethod eigenvectorRoute = rod::EigenvectorSensitivityMethod::AdjointNelson;
  /// reduced: the modal slider-crank of docs/design.md §3 (PistonRod); full: the unreduced FE rod in the
  /// rigid frame of docs/design.md §9 (rod::FullOrderRodProblem; needs an implicit integrator at usual
  /// steps).
  RodModel model = RodModel::Reduced;
  /// Full model only: keep the relative Coriolis, centrifugal and Euler terms (false drops them).
  bool fullOrderCoupling = true;
};

struct OptimizationSettings {
  Objective objective = Objective::Psi1;  ///< psi1 (integral compliance) | psi2 (equivalent static loads)
  /// The most MMA updates a run makes; the stopping rule below usually ends it earlier.
  int iterations = 150;
  double volumeFraction = 0.5;  ///< V/V0 bound, in (0, 1)
  double filterRadius = 0.0;    ///< density filter radius in elements; 0 = no filter (the paper's choice)
  int pictureEvery = 0;         ///< a PNG of every k-th design; 0 = final design only
  /// MMA move limit (Svanberg's "move"), in (0, 1]; with mma-adaptive the largest trust region. 0.2,
  /// the move limit of the standard topology-optimization codes (Andreassen et al. 2011; Aage, Andreassen
  /// & Lazarov 2015), not the 0.5 of Svanberg's note (docs/design.md §7, the paper's MMA, asked for with
  /// method mma and moveLimit 0.5): on the undamped rod the steps of 0.5 send starts that differ by an
  /// ulp into valleys whose psi1 differ by more than 1 %; with 0.2 all nine ulp starts of
  /// bench/headline.py --ensemble 8 end by the rule within 1 % of each other, 3 % above the lowest
  /// valley 0.5 had found (docs/guides/optimizer.md). Smaller values also keep the inertia-loaded rod
  /// away from the soft, mechanism-like designs that large first steps reach
  /// (see problems/topopt/topology_optimizer.h).
  double moveLimit = 0.2;
  /// Stopping rule: the run ends at the first design whose first-order optimality residual
  /// (problems/topopt/mma.h, kktResidual; in units of the scaled objective) is <= kktTolerance while
  /// the update would move no variable by more than changeTolerance. 0 in either turns the rule off
  /// (the run makes `iterations` updates). With method mma-adaptive the run also ends when the
  /// adaptive move limit has shrunk to changeTolerance or below (the trust-region test). The defaults
  /// (1e-3, 0.002) were chosen on the piston rod, where the residual stalls at 5e-4 ... 3e-2 because
  /// psi1 of the undamped rod has narrow resonance peaks in x; a looser change tolerance (0.01, the
  /// customary one) stopped runs early at designs 2-3 % worse (docs/guides/optimizer.md).
  double kktTolerance = 1e-3;
  double changeTolerance = 0.002;
  /// Stagnation: with the residual test met, the run also ends when the optimized objective of the
  /// last five designs varies by at most this (relative range (max - min) / min), however far the
  /// update would still move variables the objective barely depends on (void elements swinging with
  /// no effect on psi keep the change test from holding). 0 turns this test off.
  double objectiveTolerance = 1e-3;
  /// The end game of mma-adaptive (problems/topopt/topology_optimizer.h, "End game"): a run the rule has
  /// not ended when only the updates the end game needs remain before `iterations` (15 with the
  /// defaults) refines its best feasible design in a trust region that halves at every update, returning
  /// to the best design after an update that did not improve on it, until the move limit reaches
  /// changeTolerance and the trust-region test ends the run there, by the rule. false: such runs go on to
  /// `iterations` (the behaviour before the end game).
  bool endGame = true;
  /// Smallest distance of MMA's asymptotes from x, in units of the variable's range (MmaOptions::
  /// min_asymptote_distance; 0.01 in Svanberg's 2007 code). Where psi is stationary inside the box with
  /// no active constraint to balance it, MMA's step cannot be shorter than about 0.9 times this, so
  /// those variables end in a limit cycle of that amplitude; smaller values let them converge.
  /// The default 1e-4 lets the rod's interior optimum settle (docs/guides/optimizer.md has the
  /// measurements); the paper's MMA is reproduced with 0.01.
  double minAsymptoteDistance = 1e-4;
  /// mma-adaptive | mma | gcmma. mma-adaptive (the default): MMA whose move limit halves after an
  /// update that raised the objective and grows back 1.2x after one that lowered it, up to moveLimit
  /// (problems/topopt/mma.h, adaptive_move_limit), so that the end game settles instead of swinging at
  /// the move limit. mma: Svanberg's elementary MMA with the fixed move limit, the paper's method.
  /// gcmma: GCMMA, whose inner iterations make every accepted design feasible and no worse than the
  /// previous one (problems/topopt/gcmma.h).
  std::string method = "mma-adaptive";
  /// Guard against mechanisms: the constraint lambda_1 >= (2 pi f)^2 on the first eigenvalue of the
  /// pinned-roller rod [Hz]; 0 = off (the default).
  double minFirstFrequency = 0.0;
  /// Heaviside projection of the filtered density (problems/topopt/heaviside_projection.h): initial
  /// beta, 0 = off (the default); threshold eta; beta doubles every projectionEvery iterations up to
  /// projectionBetaMax.
  double projectionBeta = 0.0;
  double projectionThreshold = 0.5;
  double projectionBetaMax = 32.0;
  int projectionEvery = 10;
  /// With scenarios: sum (weighted sum of the scenarios' relative objectives) | max (the worst
  /// scenario, MMA's bound formulation); problems/rod/scenarios.h. Written to JSON only when it
  /// matters (scenarios given or max), so a configuration without scenarios reads and writes as before.
  Aggregate aggregate = Aggregate::Sum;
};

struct Config {
  rod::RodConfig rod;
  SimulationSettings simulation;
  OptimizationSettings optimization;
  /// Operating scenarios (problems/rod/scenarios.h); empty: the one scenario of `rod`.
  std::vector<Scenario> scenarios;
  /// The `mechanism` section (problems/mechanism/mechanism.h): the mechanism the rod is the flexible
  /// member of. Absent: the default slider-crank of docs/design.md §2, described by mechanism::sliderCrank
  /// from rod.crankRadius, crankSpeed and rampTime; present, those three fields are not used. The member's
  /// length is rod.length.
  std::optional<mechanism::Mechanism> mechanism;

  /// Checks every field; throws std::invalid_argument naming the field, value and range.
  void validate() const;
};

/// The complete configuration as JSON (every field, defaults included).
nlohmann::json toJson(const Config& config);
/// The run summary as a JSON object (same keys as RunSummary's fields, snake_case): the CLI's --json
/// output and the Python module's summary dict.
nlohmann::json summaryToJson(const RunSummary& summary);
/// The fields of a schedule prediction (storage/schedule.h) as `hindsight schedule --json` prints them
/// and hindsight.schedule() returns them; stateBytes is the state size the prediction was made for.
nlohmann::json scheduleToJson(const SchedulePrediction& prediction, std::int64_t stateBytes);
/// Strict reading; fields that are absent keep their defaults.
Config configFromJson(const nlohmann::json& json);
/// Reads a JSON file; throws std::invalid_argument naming the file when it cannot be read or parsed.
Config readConfigFile(const std::string& path);
/// Applies "section.field=value" (value in JSON syntax; bare words are taken as strings). The field's
/// own type and range are always checked; validate = false skips the checks across fields
/// (Config::validate), for applying several assignments whose combination only holds once all are
/// applied (rod.rampTime=5 with rod.endTime=6, in either order): call config.validate() after the last.
void applySetting(Config& config, const std::string& assignment, bool validate = true);
/// Applies a command-line flag that stands for one configuration field (`--move-limit 0.1` is
/// optimization.moveLimit): the text is read as --set reads a value and checked by the same code, so
/// a flag accepts exactly what its field accepts; messages name the flag and the allowed range.
/// validate as for applySetting.
void applyFlag(Config& config, const std::string& flag, const std::string& key, const std::string& text,
               bool validate = true);

/// The configurations of every scenario in order: [config] when there are none (name "rod",
/// weight 1), otherwise config with the scenario's rod and no scenarios.
std::vector<ScenarioCase> scenarioCases(const Config& config);
std::vector<Config> scenarioConfigs(const Config& config);

}  // namespace hindsight
