#include <hindsight/problems/rod/config.h>

#include <hindsight/engine/runge_kutta.h>
#include <hindsight/storage/storage_factory.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>

namespace hindsight {
namespace {

using nlohmann::json;

/// One configurable field: its JSON name, how to read it from JSON (with checks), how to write it.
struct Field {
  std::string name;
  std::function<void(Config&, const json&, const std::string&)> read;
  std::function<json(const Config&)> write;
};

// Invalid UTF-8 (a --set value is raw command-line bytes) is replaced: a strict dump would throw
// json::type_error from inside the error message meant to name the field.
std::string render(const json& value) { return value.dump(-1, ' ', false, json::error_handler_t::replace); }

template <typename Member>
Field realField(const std::string& name, Member member, double min, double max, bool openMin = false) {
  return Field{
      name,
      [=](Config& c, const json& v, const std::string& full) {
        if (!v.is_number())
          throw std::invalid_argument("config field '" + full + "' = " + render(v) + " must be a number");
        const double x = v.get<double>();
        const bool low = openMin ? !(x > min) : !(x >= min);
        if (low || !(x <= max) || !std::isfinite(x)) {
          std::ostringstream range;
          range << (openMin ? "(" : "[") << min << ", " << max << "]";
          throw std::invalid_argument("config field '" + full + "' = " + render(v) +
                                      " is outside the allowed range " + range.str());
        }
        member(c) = x;
      },
      [=](const Config& c) { return json(member(const_cast<Config&>(c))); }};
}

template <typename Member>
Field integerField(const std::string& name, Member member, long min, long max) {
  return Field{
      name,
      [=](Config& c, const json& v, const std::string& full) {
        if (!v.is_number_integer())
          throw std::invalid_argument("config field '" + full + "' = " + render(v) + " must be an integer");
        const long x = v.get<long>();
        if (x < min || x > max) {
          throw std::invalid_argument("config field '" + full + "' = " + render(v) +
                                      " is outside the allowed range [" + std::to_string(min) + ", " +
                                      std::to_string(max) + "]");
        }
        member(c) = static_cast<int>(x);
      },
      [=](const Config& c) { return json(member(const_cast<Config&>(c))); }};
}

template <typename Member>
Field boolField(const std::string& name, Member member) {
  return Field{name,
               [=](Config& c, const json& v, const std::string& full) {
                 if (!v.is_boolean())
                   throw std::invalid_argument("config field '" + full + "' = " + render(v) +
                                               " must be true or false");
                 member(c) = v.get<bool>();
               },
               [=](const Config& c) { return json(member(const_cast<Config&>(c))); }};
}

template <typename Member>
Field stringField(const std::string& name, Member member, std::vector<std::string> allowed) {
  return Field{
      name,
      [=](Config& c, const json& v, const std::string& full) {
        if (!v.is_string())
          throw std::invalid_argument("config field '" + full + "' = " + render(v) + " must be a string");
        const std::string s = v.get<std::string>();
        if (!allowed.empty()) {
          bool ok = false;
          std::string list;
          for (const auto& a : allowed) {
            ok = ok || a == s;
            list += (list.empty() ? "" : ", ") + a;
          }
          if (!ok)
            throw std::invalid_argument("config field '" + full + "' = " + render(v) +
                                        " must be one of: " + list);
        }
        member(c) = s;
      },
      [=](const Config& c) { return json(member(const_cast<Config&>(c))); }};
}

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
       {stringField("integrator", MEMBER(simulation.integrator), ButcherTableau::names()),
        realField("step", MEMBER(simulation.step), 0.0, 1.0, true),
        boolField("adaptive", MEMBER(simulation.adaptive)),
        realField("relativeTolerance", MEMBER(simulation.relativeTolerance), 0.0, 1.0, true),
        realField("absoluteTolerance", MEMBER(simulation.absoluteTolerance), 0.0, 1.0, true),
        stringField("storage", MEMBER(simulation.storage), {}),
        stringField("adjoint", MEMBER(simulation.adjoint), {"discrete", "continuous", "cvodes"}),
        stringField("eigenvectorRoute", MEMBER(simulation.eigenvectorRoute), {"adjoint-nelson", "nelson"}),
        stringField("model", MEMBER(simulation.model), {"reduced", "full"}),
        boolField("fullOrderCoupling", MEMBER(simulation.fullOrderCoupling))}},
      {"optimization",
       {stringField("objective", MEMBER(optimization.objective), {"psi1", "psi2"}),
        integerField("iterations", MEMBER(optimization.iterations), 0, 100000),
        realField("volumeFraction", MEMBER(optimization.volumeFraction), 0.0, 1.0, true),
        realField("filterRadius", MEMBER(optimization.filterRadius), 0.0, 1000.0),
        integerField("pictureEvery", MEMBER(optimization.pictureEvery), 0, 100000),
        realField("moveLimit", MEMBER(optimization.moveLimit), 0.0, 1.0, true)}},
  };
  return sections;
}

#undef MEMBER

const Field& findField(const std::string& section, const std::string& name) {
  for (const auto& [sectionName, fields] : schema()) {
    if (sectionName != section) continue;
    std::string names;
    for (const Field& f : fields) {
      if (f.name == name) return f;
      names += (names.empty() ? "" : ", ") + f.name;
    }
    throw std::invalid_argument("config field '" + section + "." + name + "' is unknown; fields of '" +
                                section + "': " + names);
  }
  throw std::invalid_argument("config section '" + section +
                              "' is unknown; sections: rod, simulation, optimization");
}

}  // namespace

void Config::validate() const {
  rod.validate();
  if (optimization.volumeFraction >= 1.0 || optimization.volumeFraction <= 0.0) {
    throw std::invalid_argument("config field 'optimization.volumeFraction' = " +
                                std::to_string(optimization.volumeFraction) + " must be in (0, 1)");
  }
  if (!(optimization.moveLimit > 0.0 && optimization.moveLimit <= 1.0)) {
    throw std::invalid_argument("config field 'optimization.moveLimit' = " +
                                std::to_string(optimization.moveLimit) + " must be in (0, 1]");
  }
  if (simulation.adaptive && simulation.integrator != "dopri5" && simulation.integrator != "trbdf2") {
    throw std::invalid_argument(
        "config field 'simulation.adaptive' = true needs simulation.integrator dopri5 or "
        "trbdf2, not '" +
        simulation.integrator + "'");
  }
  createStorage(simulation.storage);  // throws naming the bad part of the spec
}

nlohmann::json toJson(const Config& config) {
  json out = json::object();
  for (const auto& [section, fields] : schema()) {
    json s = json::object();
    for (const Field& f : fields) s[f.name] = f.write(config);
    out[section] = s;
  }
  return out;
}

Config configFromJson(const nlohmann::json& in) {
  if (!in.is_object()) throw std::invalid_argument("configuration must be a JSON object");
  Config config;
  for (const auto& [section, value] : in.items()) {
    if (!value.is_object()) {
      findField(section, "");  // throws for an unknown section
      throw std::invalid_argument("config section '" + section + "' must be a JSON object");
    }
    for (const auto& [name, v] : value.items())
      findField(section, name).read(config, v, section + "." + name);
  }
  config.validate();
  return config;
}

Config readConfigFile(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw std::invalid_argument("cannot read configuration file '" + path + "'");
  json parsed;
  try {
    parsed = json::parse(file);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for numbers such as 1e400
    throw std::invalid_argument("configuration file '" + path + "' is not valid JSON: " + e.what());
  }
  return configFromJson(parsed);
}

void applySetting(Config& config, const std::string& assignment) {
  const auto eq = assignment.find('=');
  const auto dot = assignment.find('.');
  if (eq == std::string::npos || dot == std::string::npos || dot > eq) {
    throw std::invalid_argument("--set '" + assignment + "' must have the form section.field=value");
  }
  const std::string section = assignment.substr(0, dot);
  const std::string name = assignment.substr(dot + 1, eq - dot - 1);
  const std::string text = assignment.substr(eq + 1);
  json value;
  try {
    value = json::parse(text);
  } catch (const json::exception&) {  // parse_error, and out_of_range for numbers such as 1e400
    value = text;                     // a bare word such as rk4
  }
  findField(section, name).read(config, value, section + "." + name);
  config.validate();
}

}  // namespace hindsight
