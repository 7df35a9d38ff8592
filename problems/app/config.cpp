#include <hindsight/problems/app/config.h>

#include <hindsight/engine/runge_kutta.h>
#include <hindsight/problems/mechanism/mechanism_json.h>
#include <hindsight/problems/mechanism/mechanism_problem.h>
#include <hindsight/storage/storage_factory.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>

namespace hindsight {
namespace {

using nlohmann::json;

/// Who a value is for and how the user wrote it: messages say "<who> = <shown> ...". `who` is
/// "config field 'rod.modeCount'" for a JSON file or --set, or the flag ("--move-limit") for a
/// command-line flag; `shown` is the text the user gave (the JSON rendering for a file), so a value
/// that does not survive parsing (1e-400 becomes 0) is still reported as written.
struct Subject {
  std::string who;
  std::string shown;
  std::string text;  ///< the user's text when there is one (--set, flags); empty for a JSON file
};

/// One configurable field: its JSON name, how to read it from JSON (with checks), how to write it.
struct Field {
  std::string name;
  std::function<void(Config&, const json&, const Subject&)> read;
  std::function<json(const Config&)> write;
};

// Invalid UTF-8 (a --set value is raw command-line bytes) is replaced: a strict dump would throw
// json::type_error from inside the error message meant to name the field.
std::string render(const json& value) { return value.dump(-1, ' ', false, json::error_handler_t::replace); }

template <typename Member>
Field realField(const std::string& name, Member member, double min, double max, bool openMin = false) {
  return Field{
      name,
      [=](Config& c, const json& v, const Subject& s) {
        std::ostringstream range;
        range << (openMin ? "(" : "[") << min << ", " << max << "]";
        if (!v.is_number())
          throw std::invalid_argument(s.who + " = " + s.shown + " must be a number in " + range.str());
        // JSON parsing turns 1e-400 into 0 and 1e400 into inf: report what the user wrote.
        if (!s.text.empty()) {
          errno = 0;
          const double parsed = std::strtod(s.text.c_str(), nullptr);
          if (errno == ERANGE) {
            throw std::invalid_argument(s.who + " = " + s.text + " is outside the range of a double (it " +
                                        (parsed == 0.0 ? "underflows to 0" : "overflows") +
                                        "); allowed range " + range.str());
          }
        }
        const double x = v.get<double>();
        const bool low = openMin ? !(x > min) : !(x >= min);
        if (low || !(x <= max) || !std::isfinite(x)) {
          throw std::invalid_argument(s.who + " = " + s.shown + " is outside the allowed range " +
                                      range.str());
        }
        member(c) = x;
      },
      [=](const Config& c) { return json(member(const_cast<Config&>(c))); }};
}

template <typename Member>
Field integerField(const std::string& name, Member member, long min, long max) {
  return Field{
      name,
      [=](Config& c, const json& v, const Subject& s) {
        const std::string range = "[" + std::to_string(min) + ", " + std::to_string(max) + "]";
        if (!v.is_number_integer())
          throw std::invalid_argument(s.who + " = " + s.shown + " must be an integer in " + range);
        const bool fits = v.is_number_unsigned()
                              ? v.get<unsigned long long>() <= static_cast<unsigned long long>(max)
                              : true;
        const long x = fits ? v.get<long>() : max;
        if (!fits || x < min || x > max) {
          throw std::invalid_argument(s.who + " = " + s.shown + " is outside the allowed range " + range);
        }
        member(c) = static_cast<int>(x);
      },
      [=](const Config& c) { return json(member(const_cast<Config&>(c))); }};
}

template <typename Member>
Field boolField(const std::string& name, Member member) {
  return Field{name,
               [=](Config& c, const json& v, const Subject& s) {
                 if (!v.is_boolean())
                   throw std::invalid_argument(s.who + " = " + s.shown + " must be true or false");
                 member(c) = v.get<bool>();
               },
               [=](const Config& c) { return json(member(const_cast<Config&>(c))); }};
}

/// The string a choice field was given, checked against `allowed` (empty: any string).
std::string readChoice(const json& v, const Subject& s, const std::vector<std::string>& allowed) {
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
  // A flag's or --set's text is the string itself, even when it would parse as JSON (a storage
  // spec of "5" is rejected by the spec parser, not as "not a string").
  const json& given = !v.is_string() && !s.text.empty() ? json(s.text) : v;
  if (!given.is_string()) {
    throw std::invalid_argument(s.who + " = " + s.shown + " must be a string" +
                                (list.empty() ? "" : " (one of: " + list + ")"));
  }
  const std::string value = given.get<std::string>();
  if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), value) == allowed.end())
    throw std::invalid_argument(s.who + " = " + s.shown + " must be one of: " + list);
  return value;
}

template <typename Member>
Field stringField(const std::string& name, Member member, std::vector<std::string> allowed) {
  return Field{name,
               [=](Config& c, const json& v, const Subject& s) { member(c) = readChoice(v, s, allowed); },
               [=](const Config& c) { return json(member(const_cast<Config&>(c))); }};
}

/// A choice held as an enum; JSON holds its name.
template <typename Member, typename Enum>
Field enumField(const std::string& name, Member member, std::vector<std::string> names,
                Enum (*parse)(const std::string&), std::string (*print)(Enum)) {
  return Field{
      name, [=](Config& c, const json& v, const Subject& s) { member(c) = parse(readChoice(v, s, names)); },
      [=](const Config& c) { return json(print(member(const_cast<Config&>(c)))); }};
}

template <typename Enum>
using Names = std::vector<std::pair<Enum, std::string>>;

const Names<RodModel> kModels = {{RodModel::Reduced, "reduced"}, {RodModel::Full, "full"}};
const Names<Objective> kObjectives = {{Objective::Psi1, "psi1"}, {Objective::Psi2, "psi2"}};
const Names<rod::EigenvectorSensitivityMethod> kEigenvectorRoutes = {
    {rod::EigenvectorSensitivityMethod::AdjointNelson, "adjoint-nelson"},
    {rod::EigenvectorSensitivityMethod::NelsonPerVariable, "nelson"}};

template <typename Enum>
std::vector<std::string> namesOf(const Names<Enum>& names) {
  std::vector<std::string> out;
  for (const auto& entry : names) out.push_back(entry.second);
  return out;
}

template <typename Enum>
std::string nameOf(const Names<Enum>& names, Enum value) {
  for (const auto& [e, name] : names) {
    if (e == value) return name;
  }
  throw std::logic_error("config: an enum value without a name");
}

template <typename Enum>
Enum parseName(const Names<Enum>& names, const std::string& name, const std::string& field) {
  std::string list;
  for (const auto& [e, n] : names) {
    if (n == name) return e;
    list += (list.empty() ? "" : ", ") + n;
  }
  throw std::invalid_argument("config field '" + field + "' = \"" + name + "\" must be one of: " + list);
}

std::string adjointName(AdjointMethod method) { return toString(method); }
std::string modelName(RodModel model) { return toString(model); }
std::string objectiveName(Objective objective) { return toString(objective); }
std::string routeName(rod::EigenvectorSensitivityMethod route) { return toString(route); }
std::string aggregateName(Aggregate aggregate) { return toString(aggregate); }

#define MEMBER(path) \
  [](Config & c) -> auto& { return c.path; }

const std::vector<std::pair<std::string, std::vector<Field>>>& schema() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  static const std::vector<std::pair<std::string, std::vector<Field>>> sections = {
      {"rod",
       {integerField("elementsAlongLength", MEMBER(rod.elementsAlongLength), 3, 100000),
        integerField("elementsThroughHeight", MEMBER(rod.elementsThroughHeight), 2, 10000),
        realField("length", MEMBER(rod.length), 0.0, inf, true),
        realField("height", MEMBER(rod.height), 0.0, inf, true),
        realField("thickness", MEMBER(rod.thickness), 0.0, inf, true),
        realField("youngsModulus", MEMBER(rod.youngsModulus), 0.0, inf, true),
        realField("density", MEMBER(rod.density), 0.0, inf, true),
        realField("poissonRatio", MEMBER(rod.poissonRatio), -1.0, 0.5, true),
        realField("stiffnessPenalty", MEMBER(rod.stiffnessPenalty), 1.0, 10.0),
        realField("massLawFactor", MEMBER(rod.massLawFactor), 0.0, inf, true),
        realField("massLawExponent", MEMBER(rod.massLawExponent), 1.0, 20.0),
        realField("massLawThreshold", MEMBER(rod.massLawThreshold), 0.0, 1.0, true),
        realField("designLowerBound", MEMBER(rod.designLowerBound), 0.0, 1.0, true),
        realField("initialDesign", MEMBER(rod.initialDesign), 0.0, 1.0, true),
        integerField("modeCount", MEMBER(rod.modeCount), 1, 40),
        boolField("inertiaReliefModes", MEMBER(rod.inertiaReliefModes)),
        realField("crankRadius", MEMBER(rod.crankRadius), 0.0, inf, true),
        realField("crankSpeed", MEMBER(rod.crankSpeed), 0.0, inf, true),
        realField("rampTime", MEMBER(rod.rampTime), 0.0, inf, true),
        realField("endTime", MEMBER(rod.endTime), 0.0, inf, true),
        integerField("eslSamples", MEMBER(rod.eslSamples), 1, 100000)}},
      {"simulation",
       {stringField("integrator", MEMBER(simulation.integrator), integratorMethodNames()),
        realField("step", MEMBER(simulation.step), 0.0, 1.0, true),
        boolField("adaptive", MEMBER(simulation.adaptive)),
        realField("relativeTolerance", MEMBER(simulation.relativeTolerance), 0.0, 1.0, true),
        realField("absoluteTolerance", MEMBER(simulation.absoluteTolerance), 0.0, 1.0, true),
        realField("rhoInfinity", MEMBER(simulation.rhoInfinity), 0.0, 1.0),
        stringField("storage", MEMBER(simulation.storage), {}),
        enumField("adjoint", MEMBER(simulation.adjoint), adjointMethodNames(), parseAdjointMethod,
                  adjointName),
        enumField("eigenvectorRoute", MEMBER(simulation.eigenvectorRoute), namesOf(kEigenvectorRoutes),
                  parseEigenvectorRoute, routeName),
        enumField("model", MEMBER(simulation.model), namesOf(kModels), parseRodModel, modelName),
        boolField("fullOrderCoupling", MEMBER(simulation.fullOrderCoupling))}},
      {"optimization",
       {enumField("objective", MEMBER(optimization.objective), namesOf(kObjectives), parseObjective,
                  objectiveName),
        integerField("iterations", MEMBER(optimization.iterations), 0, 100000),
        realField("volumeFraction", MEMBER(optimization.volumeFraction), 0.0, 1.0, true),
        realField("filterRadius", MEMBER(optimization.filterRadius), 0.0, 1000.0),
        integerField("pictureEvery", MEMBER(optimization.pictureEvery), 0, 100000),
        realField("moveLimit", MEMBER(optimization.moveLimit), 0.0, 1.0, true),
        realField("kktTolerance", MEMBER(optimization.kktTolerance), 0.0, 1.0),
        realField("changeTolerance", MEMBER(optimization.changeTolerance), 0.0, 1.0),
        realField("objectiveTolerance", MEMBER(optimization.objectiveTolerance), 0.0, 1.0),
        realField("minAsymptoteDistance", MEMBER(optimization.minAsymptoteDistance), 0.0, 0.5, true),
        stringField("method", MEMBER(optimization.method), {"mma-adaptive", "mma", "gcmma"}),
        realField("minFirstFrequency", MEMBER(optimization.minFirstFrequency), 0.0, 1e6),
        realField("projectionBeta", MEMBER(optimization.projectionBeta), 0.0, 1000.0),
        realField("projectionThreshold", MEMBER(optimization.projectionThreshold), 0.0, 1.0, true),
        realField("projectionBetaMax", MEMBER(optimization.projectionBetaMax), 0.0, 1000.0, true),
        integerField("projectionEvery", MEMBER(optimization.projectionEvery), 1, 100000),
        enumField("aggregate", MEMBER(optimization.aggregate), {"sum", "max"}, parseAggregate,
                  aggregateName)}},
  };
  return sections;
}

#undef MEMBER

const std::vector<Field>& findSection(const std::string& section) {
  std::string names;
  for (const auto& [sectionName, fields] : schema()) {
    if (sectionName == section) return fields;
    names += (names.empty() ? "" : ", ") + sectionName;
  }
  throw std::invalid_argument("config section '" + section + "' is unknown; sections: " + names);
}

const Field& findField(const std::string& section, const std::string& name) {
  const std::vector<Field>& fields = findSection(section);
  std::string names;
  for (const Field& f : fields) {
    if (f.name == name) return f;
    names += (names.empty() ? "" : ", ") + f.name;
  }
  throw std::invalid_argument("config field '" + section + "." + name + "' is unknown; fields of '" +
                              section + "': " + names);
}

/// Reads `text` as --set does: JSON syntax, or a bare word taken as a string.
json parseValueText(const std::string& text) {
  try {
    return json::parse(text);
  } catch (const json::parse_error&) {
    return json(text);  // a bare word such as rk4
  } catch (const json::out_of_range&) {
    // 1e400: not a double; the field's check reports the user's text as out of range.
    return json(std::numeric_limits<double>::infinity());
  }
}

/// Splits "section.field".
std::pair<std::string, std::string> splitKey(const std::string& key) {
  const auto dot = key.find('.');
  if (dot == std::string::npos) return {key, ""};
  return {key.substr(0, dot), key.substr(dot + 1)};
}

/// The one path of --set and of every config-backed flag: `text` read as --set reads it into the field
/// `key` ("section.field"), errors naming `label` (the field or the flag), then the whole check.
void applyText(Config& config, const std::string& key, const std::string& label, const std::string& text,
               bool validate = true) {
  const auto [section, name] = splitKey(key);
  findField(section, name).read(config, parseValueText(text), {label, text, text});
  if (validate) config.validate();
}

}  // namespace

std::string toString(RodModel model) { return nameOf(kModels, model); }
std::string toString(Objective objective) { return nameOf(kObjectives, objective); }
std::string toString(rod::EigenvectorSensitivityMethod route) { return nameOf(kEigenvectorRoutes, route); }
RodModel parseRodModel(const std::string& name) { return parseName(kModels, name, "simulation.model"); }
Objective parseObjective(const std::string& name) {
  return parseName(kObjectives, name, "optimization.objective");
}
rod::EigenvectorSensitivityMethod parseEigenvectorRoute(const std::string& name) {
  return parseName(kEigenvectorRoutes, name, "simulation.eigenvectorRoute");
}

void Config::validate() const {
  rod.validate();
  validateScenarios(scenarios, rod);
  if (optimization.volumeFraction >= 1.0 || optimization.volumeFraction <= 0.0) {
    throw std::invalid_argument("config field 'optimization.volumeFraction' = " +
                                std::to_string(optimization.volumeFraction) + " must be in (0, 1)");
  }
  if (!(optimization.moveLimit > 0.0 && optimization.moveLimit <= 1.0)) {
    throw std::invalid_argument("config field 'optimization.moveLimit' = " +
                                std::to_string(optimization.moveLimit) + " must be in (0, 1]");
  }
  if (!(optimization.projectionThreshold > 0.0 && optimization.projectionThreshold < 1.0)) {
    throw std::invalid_argument("config field 'optimization.projectionThreshold' = " +
                                std::to_string(optimization.projectionThreshold) + " must be in (0, 1)");
  }
  if (optimization.projectionBeta > 0.0 && optimization.projectionBetaMax < optimization.projectionBeta) {
    throw std::invalid_argument(
        "config field 'optimization.projectionBetaMax' = " + std::to_string(optimization.projectionBetaMax) +
        " must be >= optimization.projectionBeta = " + std::to_string(optimization.projectionBeta));
  }
  const IntegratorMethod method = parseIntegratorMethod(simulation.integrator);
  if (simulation.adaptive && method != IntegratorMethod::Dopri5 && method != IntegratorMethod::TrBdf2) {
    throw std::invalid_argument(
        "config field 'simulation.adaptive' = true needs simulation.integrator dopri5 or "
        "trbdf2, not '" +
        simulation.integrator + "'");
  }
  if (method == IntegratorMethod::HhtAlpha && simulation.rhoInfinity < 0.5) {
    std::ostringstream message;
    message << "config field 'simulation.rhoInfinity' = " << simulation.rhoInfinity
            << " must be in [0.5, 1] for simulation.integrator = hht-alpha";
    throw std::invalid_argument(message.str());
  }
  createStorage(simulation.storage);  // throws naming the bad part of the spec
  if (mechanism) {
    mechanism::Mechanism described = *mechanism;
    described.member.length = rod.length;
    described.validate();
    // Assembles the mechanism at t = 0 (the modes do not enter): positions that cannot be assembled
    // are bad input, named before any computation.
    const mechanism::MechanismProblem assembled(described, 1);
    (void)assembled;
    if (simulation.model != RodModel::Reduced) {
      throw std::invalid_argument(
          "config field 'simulation.model' = full is the built-in slider-crank's full-order rod; with a "
          "mechanism section it must be reduced");
    }
    if (!scenarios.empty()) {
      throw std::invalid_argument(
          "config section 'scenarios' varies the built-in slider-crank's crank; it cannot be combined with a "
          "mechanism section (give each operating case its own configuration)");
    }
  }
}

nlohmann::json toJson(const Config& config) {
  json out = json::object();
  for (const auto& [section, fields] : schema()) {
    json s = json::object();
    for (const Field& f : fields) {
      // Without scenarios the default aggregate is not written: such a configuration is the one of
      // before (results files keep their bytes, and older results files resume).
      if (f.name == "aggregate" && config.scenarios.empty() &&
          config.optimization.aggregate == Aggregate::Sum)
        continue;
      s[f.name] = f.write(config);
    }
    out[section] = s;
  }
  if (!config.scenarios.empty()) out["scenarios"] = toJson(config.scenarios);
  if (config.mechanism) out["mechanism"] = mechanism::toJson(*config.mechanism);
  return out;
}

Config configFromJson(const nlohmann::json& in) {
  if (!in.is_object()) throw std::invalid_argument("configuration must be a JSON object");
  Config config;
  const json* described = nullptr;
  for (const auto& [section, value] : in.items()) {
    if (section == "scenarios") {
      config.scenarios = scenariosFromJson(value);
      continue;
    }
    if (section == "mechanism") {
      described = &value;  // read after the rod section, whose length the member takes
      continue;
    }
    findSection(section);  // an unknown section is named, even when it is empty
    if (!value.is_object()) {
      throw std::invalid_argument("config section '" + section + "' = " + render(value) +
                                  " must be a JSON object of fields");
    }
    for (const auto& [name, v] : value.items()) {
      const std::string full = section + "." + name;
      findField(section, name).read(config, v, {"config field '" + full + "'", render(v), ""});
    }
  }
  if (described != nullptr) config.mechanism = mechanism::mechanismFromJson(*described, config.rod.length);
  config.validate();
  return config;
}

Config readConfigFile(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw std::invalid_argument("cannot read configuration file '" + path + "'");
  json parsed;
  try {
    parsed = json::parse(file);
  } catch (const json::exception& e) {  // also a number overflow such as 1e400
    throw std::invalid_argument("configuration file '" + path + "' is not valid JSON: " + e.what());
  }
  return configFromJson(parsed);
}

void applySetting(Config& config, const std::string& assignment, bool validate) {
  const auto eq = assignment.find('=');
  const auto dot = assignment.find('.');
  if (eq == std::string::npos || dot == std::string::npos || dot > eq) {
    throw std::invalid_argument("--set '" + assignment + "' must have the form section.field=value");
  }
  const std::string key = assignment.substr(0, eq);
  applyText(config, key, "config field '" + key + "'", assignment.substr(eq + 1), validate);
}

void applyFlag(Config& config, const std::string& flag, const std::string& key, const std::string& text,
               bool validate) {
  applyText(config, key, flag, text, validate);
}

nlohmann::json scheduleToJson(const SchedulePrediction& p, std::int64_t stateBytes) {
  return {{"storage", p.strategy},
          {"plan", p.plan},
          {"steps", p.steps},
          {"stages", p.stages},
          {"state_bytes", stateBytes},
          {"forward_steps", p.forwardSteps},
          {"recomputed_steps", p.recomputedSteps},
          {"rhs_evaluations", p.rhsEvaluations},
          {"adjoint_stage_recomputations", p.adjointRecomputations},
          {"step_data_stored", p.stepDataStored},
          {"step_data_restored", p.stepDataRestored},
          {"states_stored", p.statesStored},
          {"ram_writes", p.ramWrites},
          {"ram_reads", p.ramReads},
          {"disk_writes", p.diskWrites},
          {"disk_reads", p.diskReads},
          {"peak_ram_bytes", p.peakRamBytes},
          {"peak_disk_bytes", p.peakDiskBytes},
          {"schedule_cost", p.scheduleCost},
          {"total_cost", p.totalCost}};
}

nlohmann::json summaryToJson(const RunSummary& s) {
  nlohmann::json json = {{"method", s.method},
                         {"adjoint", s.adjoint},
                         {"storage", s.storage},
                         {"steps", s.steps},
                         {"rejected_steps", s.rejectedSteps},
                         {"rhs_evaluations", s.rhsEvaluations},
                         {"jacobian_evaluations", s.jacobianEvaluations},
                         {"factorizations", s.factorizations},
                         {"newton_iterations", s.newtonIterations},
                         {"recomputed_steps", s.recomputedSteps},
                         {"states_stored", s.statesStored},
                         {"peak_bytes_in_memory", s.peakBytesInMemory},
                         {"bytes_on_disk", s.bytesOnDisk},
                         {"compression_ratio", s.compressionRatio},
                         {"forward_seconds", s.forwardSeconds},
                         {"backward_seconds", s.backwardSeconds},
                         {"io_seconds", s.ioSeconds}};
  if (s.predictedStorageSeconds > 0.0 || s.measuredStorageSeconds > 0.0) {
    json["predicted_storage_seconds"] = s.predictedStorageSeconds;
    json["measured_storage_seconds"] = s.measuredStorageSeconds;
  }
  if (s.gradientErrorEstimate >= 0.0) json["gradient_error_estimate"] = s.gradientErrorEstimate;
  if (s.stepDataStored > 0 || s.stepDataRestored > 0) {
    json["step_data_stored"] = s.stepDataStored;
    json["step_data_restored"] = s.stepDataRestored;
  }
  if (s.planningSeconds > 0.0) json["planning_seconds"] = s.planningSeconds;
  return json;
}

std::vector<ScenarioCase> scenarioCases(const Config& config) {
  if (config.scenarios.empty()) return {ScenarioCase{"rod", 1.0}};
  std::vector<ScenarioCase> out;
  for (const Scenario& s : config.scenarios) out.push_back({s.name, s.weight});
  return out;
}

std::vector<Config> scenarioConfigs(const Config& config) {
  if (config.scenarios.empty()) return {config};
  std::vector<Config> out;
  for (const Scenario& s : config.scenarios) {
    Config c = config;
    c.scenarios.clear();
    c.rod = scenarioRod(config.rod, s);
    out.push_back(c);
  }
  return out;
}

}  // namespace hindsight
