// Operating scenarios of the piston rod: one design must serve several crank speeds,
// ramps, horizons and crank radii. A configuration's `scenarios` list names them; every field a
// scenario omits takes the `rod` value, so a scenario is the rod configuration with at most four
// mechanism fields replaced. No list means one scenario, the rod itself (and the optimizer then runs
// exactly the single-scenario code path of before, bit for bit).
//
// With a described mechanism (the configuration's `mechanism` section) a scenario sets the drivers
// and gravity of the description instead of the built-in crank: `drivers` maps a driver's name to its
// speed, rampTime and offset (omitted ones keep the description's), `gravity` replaces
// mechanism.gravity; endTime is the horizon as before. crankSpeed, rampTime and crankRadius name the
// built-in crank and are refused there, as drivers and gravity are without a mechanism section
// (problems/app/config.h applies and checks them against the description).
//
// JSON form (top-level key of the configuration):
//   "scenarios": [{"name": "slow", "crankSpeed": 15.7, "weight": 1.0}, {"name": "fast", ...}]
//   "scenarios": [{"name": "fast", "drivers": {"crank": {"speed": 62.8}}, "gravity": [0, -9.81]}]
// Every field is checked where it is read; messages name the entry: "scenarios[1].crankSpeed = -3
// is outside the allowed range (0, inf)". Names are unique and non-empty.
//
// Aggregation (optimization.aggregate), with f_s(x) = w_s psi_s(x) / psi_s(x0) (each scenario
// relative to the initial design, so that scenarios whose psi differ by orders of magnitude -- psi
// grows roughly with the fourth power of the crank speed -- still all count; the weight ranks them):
//   sum  minimize sum_s f_s(x)                                     (the weighted-sum objective)
//   max  minimize z subject to f_s(x) - z <= 0 for every s          (the worst case, MMA's bound
//        formulation; problems/topopt/scenario_objective.h)
#pragma once

#include <hindsight/problems/rod/rod_config.h>

#include <nlohmann/json.hpp>

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace hindsight {

/// A described mechanism's driver as one scenario sets it; omitted fields keep the description's.
struct DriverOverride {
  std::optional<double> speed;     ///< [rad/s] or [m/s], finite
  std::optional<double> rampTime;  ///< [s], > 0 (cycloidal-ramp drivers only)
  std::optional<double> offset;    ///< [rad] or [m], finite
};

struct Scenario {
  std::string name;
  std::optional<double> crankSpeed;   ///< Omega [rad/s] after the ramp, > 0
  std::optional<double> rampTime;     ///< [s], > 0
  std::optional<double> endTime;      ///< [s], >= the scenario's rampTime
  std::optional<double> crankRadius;  ///< [m], in (0, rod.length)
  double weight = 1.0;                ///< w_s > 0
  /// Described mechanisms only: drivers by name, and gravity [m/s^2].
  std::map<std::string, DriverOverride> drivers;
  std::optional<std::array<double, 2>> gravity;
};

/// optimization.aggregate.
enum class Aggregate { Sum, Max };
std::string toString(Aggregate aggregate);
/// Throws std::invalid_argument naming optimization.aggregate and the allowed names.
Aggregate parseAggregate(const std::string& name);

/// Reads the `scenarios` array strictly (unknown field, wrong type, out-of-range value: throws
/// std::invalid_argument naming "scenarios[i].field"). Range checks that need the rod (endTime >=
/// rampTime, crankRadius < length) are made by validateScenarios.
std::vector<Scenario> scenariosFromJson(const nlohmann::json& json);
/// The array as written in a configuration (omitted fields stay omitted).
nlohmann::json toJson(const std::vector<Scenario>& scenarios);

/// The rod configuration of one scenario: `rod` with the scenario's fields replaced.
rod::RodConfig scenarioRod(const rod::RodConfig& rod, const Scenario& scenario);
/// Checks every scenario against the rod (unique names; the replaced rod valid); throws
/// std::invalid_argument naming "scenarios[i]...".
void validateScenarios(const std::vector<Scenario>& scenarios, const rod::RodConfig& rod);

/// A scenario's name and weight (the application configuration's scenarioCases() lists them,
/// problems/app/config.h).
struct ScenarioCase {
  std::string name;
  double weight = 1.0;
};

}  // namespace hindsight
