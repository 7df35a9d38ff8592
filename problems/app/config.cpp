#include <hindsight/problems/app/config.h>

#include <hindsight/engine/runge_kutta.h>
#include <hindsight/problems/app/config_schema.h>
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

// Invalid UTF-8 (a --set value is raw command-line bytes) is replaced: a strict dump would throw
// json::type_error from inside the error message meant to name the field.
std::string render(const json& value) { return value.dump(-1, ' ', false, json::error_handler_t::replace); }

/// The string a choice or text field was given, checked against `allowed` (empty: any string).
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

/// Checks `v` against the row's type and range and returns the value to store; throws
/// std::invalid_argument saying "<who> = <shown> ..." with the allowed values.
json checkValue(const ConfigField& field, const json& v, const Subject& s) {
  switch (field.type) {
    case ConfigFieldType::real: {
      const std::string range = field.allowed();
      if (!v.is_number())
        throw std::invalid_argument(s.who + " = " + s.shown + " must be a number in " + range);
      // JSON parsing turns 1e-400 into 0 and 1e400 into inf: report what the user wrote.
      if (!s.text.empty()) {
        errno = 0;
        const double parsed = std::strtod(s.text.c_str(), nullptr);
        if (errno == ERANGE) {
          throw std::invalid_argument(s.who + " = " + s.text + " is outside the range of a double (it " +
                                      (parsed == 0.0 ? "underflows to 0" : "overflows") +
                                      "); allowed range " + range);
        }
      }
      const double x = v.get<double>();
      const bool low = field.lowerOpen ? !(x > field.lower) : !(x >= field.lower);
      if (low || !(x <= field.upper) || !std::isfinite(x))
        throw std::invalid_argument(s.who + " = " + s.shown + " is outside the allowed range " + range);
      return json(x);
    }
    case ConfigFieldType::integer: {
      const std::string range = field.allowed();
      const long min = static_cast<long>(field.lower), max = static_cast<long>(field.upper);
      if (!v.is_number_integer())
        throw std::invalid_argument(s.who + " = " + s.shown + " must be an integer in " + range);
      const bool fits =
          v.is_number_unsigned() ? v.get<unsigned long long>() <= static_cast<unsigned long long>(max) : true;
      const long x = fits ? v.get<long>() : max;
      if (!fits || x < min || x > max)
        throw std::invalid_argument(s.who + " = " + s.shown + " is outside the allowed range " + range);
      return json(x);
    }
    case ConfigFieldType::boolean:
      if (!v.is_boolean()) throw std::invalid_argument(s.who + " = " + s.shown + " must be true or false");
      return v;
    case ConfigFieldType::choice:
    case ConfigFieldType::text:
      return json(readChoice(v, s, field.choices));
  }
  throw std::logic_error("config: a field of unknown type");
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

// Row makers. `access` is a lambda returning a reference to the member (MEMBER below); the checks are
// checkValue()'s, by the row's type and range.
template <typename Access>
ConfigField real(std::string key, Access access, double lower, bool lowerOpen, double upper, std::string unit,
                 std::string description, std::string flag = "") {
  ConfigField f{std::move(key),  ConfigFieldType::real,  lower,           upper,   lowerOpen, {},
                std::move(unit), std::move(description), std::move(flag), nullptr, nullptr};
  f.get = [access](const Config& c) { return json(access(const_cast<Config&>(c))); };
  f.set = [access](Config& c, const json& v) { access(c) = v.get<double>(); };
  return f;
}

template <typename Access>
ConfigField integer(std::string key, Access access, long lower, long upper, std::string unit,
                    std::string description, std::string flag = "") {
  ConfigField f{std::move(key),
                ConfigFieldType::integer,
                static_cast<double>(lower),
                static_cast<double>(upper),
                false,
                {},
                std::move(unit),
                std::move(description),
                std::move(flag),
                nullptr,
                nullptr};
  f.get = [access](const Config& c) { return json(access(const_cast<Config&>(c))); };
  f.set = [access](Config& c, const json& v) { access(c) = static_cast<int>(v.get<long>()); };
  return f;
}

template <typename Access>
ConfigField boolean(std::string key, Access access, std::string description) {
  ConfigField f{
      std::move(key), ConfigFieldType::boolean, 0.0, 0.0, false, {}, "", std::move(description), "", nullptr,
      nullptr};
  f.get = [access](const Config& c) { return json(access(const_cast<Config&>(c))); };
  f.set = [access](Config& c, const json& v) { access(c) = v.get<bool>(); };
  return f;
}

/// A string field: one of `choices`, or with no choices any text.
template <typename Access>
ConfigField text(std::string key, Access access, std::vector<std::string> choices, std::string description,
                 std::string flag = "") {
  const ConfigFieldType type = choices.empty() ? ConfigFieldType::text : ConfigFieldType::choice;
  ConfigField f{std::move(key),  type,    0.0,    0.0, false, std::move(choices), "", std::move(description),
                std::move(flag), nullptr, nullptr};
  f.get = [access](const Config& c) { return json(access(const_cast<Config&>(c))); };
  f.set = [access](Config& c, const json& v) { access(c) = v.get<std::string>(); };
  return f;
}

/// A choice held as an enum; JSON holds its name.
template <typename Access, typename Enum>
ConfigField named(std::string key, Access access, std::vector<std::string> choices,
                  Enum (*parse)(const std::string&), std::string (*print)(Enum), std::string description,
                  std::string flag = "") {
  ConfigField f{
      std::move(key),         ConfigFieldType::choice, 0.0,     0.0,    false, std::move(choices), "",
      std::move(description), std::move(flag),         nullptr, nullptr};
  f.get = [access, print](const Config& c) { return json(print(access(const_cast<Config&>(c)))); };
  f.set = [access, parse](Config& c, const json& v) { access(c) = parse(v.get<std::string>()); };
  return f;
}

std::string adjointName(AdjointMethod method) { return toString(method); }
std::string modelName(RodModel model) { return toString(model); }
std::string objectiveName(Objective objective) { return toString(objective); }
std::string routeName(rod::EigenvectorSensitivityMethod route) { return toString(route); }
std::string aggregateName(Aggregate aggregate) { return toString(aggregate); }

const std::vector<std::string> kSections = {"rod", "simulation", "optimization"};

/// The fields of `section`; throws std::invalid_argument naming an unknown section and the sections.
std::vector<const ConfigField*> sectionFields(const std::string& section) {
  std::vector<const ConfigField*> out;
  for (const ConfigField& f : configFields()) {
    if (f.section() == section) out.push_back(&f);
  }
  if (out.empty()) {
    std::string names;
    for (const auto& s : kSections) names += (names.empty() ? "" : ", ") + s;
    throw std::invalid_argument("config section '" + section + "' is unknown; sections: " + names);
  }
  return out;
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

/// Reads `v` into the field, checked, errors naming `subject`.
void readField(Config& config, const ConfigField& field, const json& v, const Subject& subject) {
  field.set(config, checkValue(field, v, subject));
}

/// The one path of --set and of every config-backed flag: `text` read as --set reads it into the field
/// `key` ("section.field"), errors naming `label` (the field or the flag), then the whole check.
void applyText(Config& config, const std::string& key, const std::string& label, const std::string& text,
               bool validate = true) {
  readField(config, findConfigField(key), parseValueText(text), {label, text, text});
  if (validate) config.validate();
}

/// A default or any value as the listing and the page show it: strings without quotes.
std::string shown(const json& value) { return value.is_string() ? value.get<std::string>() : render(value); }

std::string typeName(ConfigFieldType type) {
  switch (type) {
    case ConfigFieldType::integer:
      return "integer";
    case ConfigFieldType::real:
      return "number";
    case ConfigFieldType::boolean:
      return "boolean";
    case ConfigFieldType::choice:
      return "name";
    case ConfigFieldType::text:
      return "text";
  }
  return "?";
}

}  // namespace

#define MEMBER(path) \
  [](Config & c) -> auto& { return c.path; }

const std::vector<ConfigField>& configFields() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  constexpr bool open = true, closed = false;
  static const std::vector<ConfigField> fields = {
      // --- rod: the model of docs/design.md §2 (problems/rod/rod_config.h) ---
      integer("rod.elementsAlongLength", MEMBER(rod.elementsAlongLength), 3, 100000, "1",
              "nx, element columns along the rod (the two end columns stay solid)"),
      integer("rod.elementsThroughHeight", MEMBER(rod.elementsThroughHeight), 2, 10000, "1",
              "ny, element rows through the height; even (the joints sit at mid-height nodes)"),
      real("rod.length", MEMBER(rod.length), 0.0, open, inf, "m", "L, distance between the joints A and B"),
      real("rod.height", MEMBER(rod.height), 0.0, open, inf, "m", "H, height of the rod"),
      real("rod.thickness", MEMBER(rod.thickness), 0.0, open, inf, "m",
           "t, plane-stress thickness (the solid's extent through the thickness)"),
      integer("rod.elementsThroughThickness", MEMBER(rod.elementsThroughThickness), 0, 10000, "1",
              "nz: 0 = the member is the plate (2-D); >= 1 = the solid of hexahedra, nz layers through the "
              "modelled thickness"),
      boolean("rod.midPlaneSymmetry", MEMBER(rod.midPlaneSymmetry),
              "solid only: model the half z >= 0 (in-plane and symmetric modes only)"),
      real("rod.youngsModulus", MEMBER(rod.youngsModulus), 0.0, open, inf, "N/m^2",
           "E0, Young's modulus of solid material"),
      real("rod.density", MEMBER(rod.density), 0.0, open, inf, "kg/m^3", "rho0, density of solid material"),
      real("rod.poissonRatio", MEMBER(rod.poissonRatio), -1.0, open, 0.5, "1",
           "nu, Poisson's ratio (plane stress); below 0.5"),
      real("rod.stiffnessPenalty", MEMBER(rod.stiffnessPenalty), 1.0, closed, 10.0, "1",
           "p of the SIMP law E = x^p E0"),
      real("rod.massLawFactor", MEMBER(rod.massLawFactor), 0.0, open, inf, "1",
           "c of the density law rho = c x^q rho0 below the threshold; must equal threshold^(1 - q)"),
      real("rod.massLawExponent", MEMBER(rod.massLawExponent), 1.0, closed, 20.0, "1",
           "q of the density law rho = c x^q rho0"),
      real("rod.massLawThreshold", MEMBER(rod.massLawThreshold), 0.0, open, 1.0, "1",
           "density below which the law c x^q applies (x rho0 above)"),
      real("rod.designLowerBound", MEMBER(rod.designLowerBound), 0.0, open, 1.0, "1",
           "xMin, the smallest density a design variable takes; below 1"),
      real("rod.initialDesign", MEMBER(rod.initialDesign), 0.0, open, 1.0, "1",
           "x0, the uniform initial design; in [designLowerBound, 1]"),
      integer("rod.modeCount", MEMBER(rod.modeCount), 1, 40, "1", "normal modes kept by the modal reduction"),
      boolean("rod.inertiaReliefModes", MEMBER(rod.inertiaReliefModes),
              "append the three static inertia-relief modes K^-1 M [e_x, e_y, S X]"),
      real("rod.crankRadius", MEMBER(rod.crankRadius), 0.0, open, inf, "m",
           "r, crank radius of the default slider-crank (no mechanism section); below length"),
      real("rod.crankSpeed", MEMBER(rod.crankSpeed), 0.0, open, inf, "rad/s",
           "Omega, crank speed after the ramp (default slider-crank)"),
      real("rod.rampTime", MEMBER(rod.rampTime), 0.0, open, inf, "s",
           "T, duration of the cycloidal speed ramp (default slider-crank)"),
      real("rod.endTime", MEMBER(rod.endTime), 0.0, open, inf, "s", "t1, end of the simulation; >= rampTime"),
      integer("rod.eslSamples", MEMBER(rod.eslSamples), 1, 100000, "1",
              "time points of the equivalent static loads (psi2)"),
      // --- simulation: the time integration and the gradient ---
      text("simulation.integrator", MEMBER(simulation.integrator), integratorMethodNames(),
           "time integrator; generalized-alpha and hht-alpha for the reduced model only", "--integrator"),
      real("simulation.step", MEMBER(simulation.step), 0.0, open, 1.0, "s",
           "fixed step (first step when adaptive), refined so that the ESL times are grid points"),
      boolean("simulation.adaptive", MEMBER(simulation.adaptive),
              "adaptive steps (dopri5, trbdf2); psi2 and optimize need fixed steps"),
      real("simulation.relativeTolerance", MEMBER(simulation.relativeTolerance), 0.0, open, 1.0, "1",
           "relative tolerance of adaptive steps and of the continuous and CVODES routes"),
      real("simulation.absoluteTolerance", MEMBER(simulation.absoluteTolerance), 0.0, open, 1.0, "state",
           "absolute tolerance of adaptive steps and of the continuous and CVODES routes"),
      real("simulation.rhoInfinity", MEMBER(simulation.rhoInfinity), 0.0, closed, 1.0, "1",
           "spectral radius at infinity of generalized-alpha; [0.5, 1] for hht-alpha"),
      text("simulation.storage", MEMBER(simulation.storage), {},
           "trajectory storage spec NAME[:key=value,...], e.g. binomial:checkpoints=50", "--storage"),
      named("simulation.adjoint", MEMBER(simulation.adjoint), adjointMethodNames(), parseAdjointMethod,
            adjointName, "adjoint route (docs/guides/integrators_and_adjoints.md)", "--adjoint"),
      named("simulation.eigenvectorRoute", MEMBER(simulation.eigenvectorRoute), namesOf(kEigenvectorRoutes),
            parseEigenvectorRoute, routeName,
            "eigenvector sensitivities: adjoint-nelson, or nelson (one solve per design variable, the "
            "paper's)"),
      named("simulation.model", MEMBER(simulation.model), namesOf(kModels), parseRodModel, modelName,
            "reduced: the modal slider-crank (docs/design.md §3); full: the unreduced FE rod (§9)",
            "--model"),
      boolean("simulation.fullOrderCoupling", MEMBER(simulation.fullOrderCoupling),
              "full model: keep the relative Coriolis, centrifugal and Euler terms"),
      // --- optimization: the topology optimization (docs/guides/optimizer.md) ---
      named("optimization.objective", MEMBER(optimization.objective), namesOf(kObjectives), parseObjective,
            objectiveName, "psi1 (integral compliance, exact adjoint) or psi2 (equivalent static loads)",
            "--objective"),
      integer("optimization.iterations", MEMBER(optimization.iterations), 0, 100000, "1",
              "the most MMA updates; the stopping rule usually ends the run earlier", "--iterations"),
      real("optimization.volumeFraction", MEMBER(optimization.volumeFraction), 0.0, open, 1.0, "1",
           "upper bound on V/V0; below 1"),
      real("optimization.filterRadius", MEMBER(optimization.filterRadius), 0.0, closed, 1000.0, "elements",
           "density filter radius; 0 = no filter (the paper's choice)", "--filter-radius"),
      integer("optimization.pictureEvery", MEMBER(optimization.pictureEvery), 0, 100000, "1",
              "a picture of every k-th design; 0 = the final design only", "--picture-every"),
      real("optimization.moveLimit", MEMBER(optimization.moveLimit), 0.0, open, 1.0, "1",
           "MMA move limit (Svanberg's move)", "--move-limit"),
      real("optimization.kktTolerance", MEMBER(optimization.kktTolerance), 0.0, closed, 1.0, "1",
           "stopping rule: first-order optimality residual (scaled objective); 0 turns the rule off"),
      real("optimization.changeTolerance", MEMBER(optimization.changeTolerance), 0.0, closed, 1.0, "1",
           "stopping rule: the largest move of a variable; 0 turns the rule off"),
      real("optimization.objectiveTolerance", MEMBER(optimization.objectiveTolerance), 0.0, closed, 1.0, "1",
           "stopping rule: relative range of the objective over the last five designs; 0 = off"),
      boolean("optimization.endGame", MEMBER(optimization.endGame),
              "mma-adaptive: a run still going when only the end game's updates remain refines its best "
              "design in a shrinking trust region and ends by the stopping rule"),
      real("optimization.minAsymptoteDistance", MEMBER(optimization.minAsymptoteDistance), 0.0, open, 0.5,
           "1", "smallest distance of MMA's asymptotes from x, in units of the variable's range"),
      text("optimization.method", MEMBER(optimization.method), {"mma-adaptive", "mma", "gcmma"},
           "MMA with an adaptive move limit, Svanberg's MMA (the paper's), or GCMMA"),
      real("optimization.minFirstFrequency", MEMBER(optimization.minFirstFrequency), 0.0, closed, 1e6, "Hz",
           "lower bound on the first eigenfrequency of the pinned-roller rod; 0 = off"),
      real("optimization.projectionBeta", MEMBER(optimization.projectionBeta), 0.0, closed, 1000.0, "1",
           "initial sharpness beta of the Heaviside projection; 0 = no projection"),
      real("optimization.projectionThreshold", MEMBER(optimization.projectionThreshold), 0.0, open, 1.0, "1",
           "threshold eta of the projection; below 1"),
      real("optimization.projectionBetaMax", MEMBER(optimization.projectionBetaMax), 0.0, open, 1000.0, "1",
           "largest beta; >= projectionBeta"),
      integer("optimization.projectionEvery", MEMBER(optimization.projectionEvery), 1, 100000, "1",
              "beta doubles every this many iterations"),
      named("optimization.aggregate", MEMBER(optimization.aggregate), {"sum", "max"}, parseAggregate,
            aggregateName, "with scenarios: the weighted sum of their relative objectives, or the worst"),
  };
  return fields;
}

#undef MEMBER

std::string ConfigField::section() const { return key.substr(0, key.find('.')); }

std::string ConfigField::name() const { return key.substr(key.find('.') + 1); }

std::string ConfigField::allowed() const {
  switch (type) {
    case ConfigFieldType::real: {
      std::ostringstream range;
      range << (lowerOpen ? "(" : "[") << lower << ", " << upper << "]";
      return range.str();
    }
    case ConfigFieldType::integer:
      return "[" + std::to_string(static_cast<long>(lower)) + ", " +
             std::to_string(static_cast<long>(upper)) + "]";
    case ConfigFieldType::boolean:
      return "true, false";
    case ConfigFieldType::choice: {
      std::string list;
      for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
      return list;
    }
    case ConfigFieldType::text:
      return "text";
  }
  return "";
}

const ConfigField& findConfigField(const std::string& key) {
  const auto dot = key.find('.');
  const std::string section = key.substr(0, dot);
  const std::string name = dot == std::string::npos ? "" : key.substr(dot + 1);
  std::string names;
  for (const ConfigField* f : sectionFields(section)) {
    if (f->name() == name) return *f;
    names += (names.empty() ? "" : ", ") + f->name();
  }
  throw std::invalid_argument("config field '" + section + "." + name + "' is unknown; fields of '" +
                              section + "': " + names);
}

std::string configFieldsText() {
  const Config defaults;
  std::ostringstream out;
  for (const std::string& section : kSections) {
    out << section << ":\n";
    for (const ConfigField* f : sectionFields(section)) {
      out << "  " << f->key << " = " << shown(f->get(defaults)) << "  (" << typeName(f->type);
      if (f->type != ConfigFieldType::boolean && f->type != ConfigFieldType::text)
        out << " in " << f->allowed();
      if (!f->unit.empty() && f->unit != "1") out << ", " << f->unit;
      if (!f->flag.empty()) out << "; flag " << f->flag;
      out << ")\n      " << f->description << "\n";
    }
  }
  return out.str();
}

std::string configFieldsMarkdown() {
  const Config defaults;
  std::ostringstream out;
  for (const std::string& section : kSections) {
    if (section != kSections.front()) out << "\n";
    out << "### `" << section << "`\n\n";
    out << "| field | type | default | allowed | unit | description |\n";
    out << "|---|---|---|---|---|---|\n";
    for (const ConfigField* f : sectionFields(section)) {
      out << "| `" << f->key << "`" << (f->flag.empty() ? "" : " (`" + f->flag + "`)") << " | "
          << typeName(f->type) << " | `" << shown(f->get(defaults)) << "` | " << f->allowed() << " | "
          << (f->unit.empty() ? "" : f->unit) << " | " << f->description << " |\n";
    }
  }
  return out.str();
}

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

namespace {

/// The described mechanism of one scenario: its drivers and gravity replaced (problems/rod/scenarios.h).
/// Throws std::invalid_argument naming the scenario's field (`at` = "scenarios[i]").
mechanism::Mechanism scenarioMechanism(const mechanism::Mechanism& base, const Scenario& scenario,
                                       const std::string& at) {
  const char* builtIn = scenario.crankSpeed    ? "crankSpeed"
                        : scenario.rampTime    ? "rampTime"
                        : scenario.crankRadius ? "crankRadius"
                                               : nullptr;
  if (builtIn != nullptr)
    throw std::invalid_argument(
        at + "." + builtIn +
        " sets the default slider-crank's crank; with a mechanism section a scenario sets "
        "its drivers (\"drivers\": {\"<driver>\": {\"speed\": ...}}) and gravity");
  mechanism::Mechanism out = base;
  for (const auto& [name, change] : scenario.drivers) {
    auto driver = std::find_if(out.drivers.begin(), out.drivers.end(),
                               [&](const mechanism::Driver& d) { return d.name == name; });
    if (driver == out.drivers.end()) {
      std::string names;
      for (const mechanism::Driver& d : out.drivers) names += (names.empty() ? "" : ", ") + d.name;
      throw std::invalid_argument(at + ".drivers." + name + " is not a driver of the mechanism; drivers: " +
                                  (names.empty() ? "(none)" : names));
    }
    if (change.rampTime && driver->law.kind != mechanism::DriverLaw::Kind::CycloidalRamp)
      throw std::invalid_argument(at + ".drivers." + name + ".rampTime: driver '" + name + "' has law " +
                                  mechanism::toString(driver->law.kind) +
                                  "; rampTime is a field of cycloidal-ramp only");
    if (change.speed) driver->law.speed = *change.speed;
    if (change.rampTime) driver->law.rampTime = *change.rampTime;
    if (change.offset) driver->offset = *change.offset;
  }
  if (scenario.gravity) out.gravity = mechanism::Vec2((*scenario.gravity)[0], (*scenario.gravity)[1]);
  return out;
}

}  // namespace

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
          "config field 'simulation.model' = full is the default slider-crank's full-order rod; with a "
          "mechanism section it must be reduced");
    }
    for (std::size_t i = 0; i < scenarios.size(); ++i) {
      const std::string at = "scenarios[" + std::to_string(i) + "]";
      mechanism::Mechanism varied = scenarioMechanism(*mechanism, scenarios[i], at);
      varied.member.length = rod.length;
      try {
        varied.validate();
        const mechanism::MechanismProblem variedAssembly(varied, 1);
        (void)variedAssembly;
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(at + " ('" + scenarios[i].name + "'): " + e.what());
      }
    }
  } else {
    for (std::size_t i = 0; i < scenarios.size(); ++i) {
      const std::string at = "scenarios[" + std::to_string(i) + "]";
      if (!scenarios[i].drivers.empty() || scenarios[i].gravity)
        throw std::invalid_argument(
            at + "." + (scenarios[i].drivers.empty() ? "gravity" : "drivers") +
            " sets a described mechanism and needs a mechanism section; the default "
            "slider-crank's scenarios set crankSpeed, rampTime, crankRadius and endTime");
    }
  }
}

nlohmann::json toJson(const Config& config) {
  json out = json::object();
  for (const ConfigField& f : configFields()) {
    // Without scenarios the default aggregate is not written: such a configuration is the one of
    // before (results files keep their bytes, and older results files resume).
    if (f.key == "optimization.aggregate" && config.scenarios.empty() &&
        config.optimization.aggregate == Aggregate::Sum)
      continue;
    out[f.section()][f.name()] = f.get(config);
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
    sectionFields(section);  // an unknown section is named, even when it is empty
    if (!value.is_object()) {
      throw std::invalid_argument("config section '" + section + "' = " + render(value) +
                                  " must be a JSON object of fields");
    }
    for (const auto& [name, v] : value.items()) {
      const std::string full = section + "." + name;
      readField(config, findConfigField(full), v, {"config field '" + full + "'", render(v), ""});
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
  nlohmann::json json = {{"storage", p.strategy},
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
                         {"hidden_io_cost", p.hiddenIoCost},
                         {"schedule_cost", p.scheduleCost},
                         {"total_cost", p.totalCost}};
  if (!p.warning.empty()) json["warning"] = p.warning;
  if (p.lowerBound >= 0.0) json["lower_bound"] = p.lowerBound;  // --bound: the schedule part's bound
  if (!p.levels.empty()) {  // three or more levels: disk_writes, disk_reads and peak_disk_bytes sum these
    nlohmann::json levels = nlohmann::json::array();
    for (const LevelTraffic& level : p.levels) {
      levels.push_back({{"name", level.name},
                        {"writes", level.writes},
                        {"reads", level.reads},
                        {"peak_bytes", level.peakBytes},
                        {"write_cost", level.write},
                        {"read_cost", level.read}});
    }
    json["levels"] = levels;
  }
  return json;
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
    if (config.mechanism) c.mechanism = scenarioMechanism(*config.mechanism, s, "scenarios[" + s.name + "]");
    out.push_back(c);
  }
  return out;
}

}  // namespace hindsight
