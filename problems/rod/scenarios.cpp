#include <hindsight/problems/rod/scenarios.h>

#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace {

using nlohmann::json;

std::string render(const json& value) { return value.dump(-1, ' ', false, json::error_handler_t::replace); }

double readPositive(const json& value, const std::string& who) {
  if (!value.is_number())
    throw std::invalid_argument(who + " = " + render(value) + " must be a number in (0, inf)");
  const double x = value.get<double>();
  if (!(std::isfinite(x) && x > 0.0))
    throw std::invalid_argument(who + " = " + render(value) + " is outside the allowed range (0, inf)");
  return x;
}

double readFinite(const json& value, const std::string& who) {
  if (!value.is_number() || !std::isfinite(value.get<double>()))
    throw std::invalid_argument(who + " = " + render(value) + " must be a finite number");
  return value.get<double>();
}

std::map<std::string, DriverOverride> readDrivers(const json& value, const std::string& who) {
  if (!value.is_object() || value.empty())
    throw std::invalid_argument(
        who + " = " + render(value) +
        " must be a non-empty object of drivers by name, e.g. {\"crank\": {\"speed\": "
        "62.8}}");
  std::map<std::string, DriverOverride> out;
  for (const auto& [name, fields] : value.items()) {
    const std::string at = who + "." + name;
    if (!fields.is_object() || fields.empty())
      throw std::invalid_argument(at + " = " + render(fields) +
                                  " must be a non-empty object with speed, rampTime or offset");
    DriverOverride d;
    for (const auto& [field, x] : fields.items()) {
      if (field == "speed") {
        d.speed = readFinite(x, at + ".speed");
      } else if (field == "rampTime") {
        d.rampTime = readPositive(x, at + ".rampTime");
      } else if (field == "offset") {
        d.offset = readFinite(x, at + ".offset");
      } else {
        throw std::invalid_argument(at + "." + field +
                                    " is unknown; fields of a driver in a scenario: speed, "
                                    "rampTime, offset");
      }
    }
    out[name] = d;
  }
  return out;
}

std::array<double, 2> readGravity(const json& value, const std::string& who) {
  if (!value.is_array() || value.size() != 2)
    throw std::invalid_argument(who + " = " + render(value) + " must be an array [gx, gy] of two numbers");
  return {readFinite(value[0], who + "[0]"), readFinite(value[1], who + "[1]")};
}

}  // namespace

std::string toString(Aggregate aggregate) { return aggregate == Aggregate::Max ? "max" : "sum"; }

Aggregate parseAggregate(const std::string& name) {
  if (name == "sum") return Aggregate::Sum;
  if (name == "max") return Aggregate::Max;
  throw std::invalid_argument("config field 'optimization.aggregate' = \"" + name +
                              "\" must be one of: sum, max");
}

std::vector<Scenario> scenariosFromJson(const json& in) {
  if (!in.is_array())
    throw std::invalid_argument("config field 'scenarios' = " + render(in) + " must be an array of objects");
  std::vector<Scenario> out;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const std::string at = "scenarios[" + std::to_string(i) + "]";
    const json& entry = in[i];
    if (!entry.is_object())
      throw std::invalid_argument(at + " = " + render(entry) + " must be a JSON object of fields");
    Scenario s;
    for (const auto& [field, value] : entry.items()) {
      const std::string who = at + "." + field;
      if (field == "name") {
        if (!value.is_string() || value.get<std::string>().empty())
          throw std::invalid_argument(who + " = " + render(value) + " must be a non-empty string");
        s.name = value.get<std::string>();
      } else if (field == "crankSpeed") {
        s.crankSpeed = readPositive(value, who);
      } else if (field == "rampTime") {
        s.rampTime = readPositive(value, who);
      } else if (field == "endTime") {
        s.endTime = readPositive(value, who);
      } else if (field == "crankRadius") {
        s.crankRadius = readPositive(value, who);
      } else if (field == "weight") {
        s.weight = readPositive(value, who);
      } else if (field == "drivers") {
        s.drivers = readDrivers(value, who);
      } else if (field == "gravity") {
        s.gravity = readGravity(value, who);
      } else {
        throw std::invalid_argument(who +
                                    " is unknown; fields of a scenario: name, crankSpeed, rampTime, "
                                    "endTime, crankRadius, weight (built-in slider-crank), drivers, gravity "
                                    "(described mechanism)");
      }
    }
    if (s.name.empty()) throw std::invalid_argument(at + ".name is missing (every scenario needs a name)");
    out.push_back(s);
  }
  return out;
}

json toJson(const std::vector<Scenario>& scenarios) {
  json out = json::array();
  for (const Scenario& s : scenarios) {
    json entry = json::object();
    entry["name"] = s.name;
    if (s.crankSpeed) entry["crankSpeed"] = *s.crankSpeed;
    if (s.rampTime) entry["rampTime"] = *s.rampTime;
    if (s.endTime) entry["endTime"] = *s.endTime;
    if (s.crankRadius) entry["crankRadius"] = *s.crankRadius;
    entry["weight"] = s.weight;
    if (!s.drivers.empty()) {
      json drivers = json::object();
      for (const auto& [name, d] : s.drivers) {
        json fields = json::object();
        if (d.speed) fields["speed"] = *d.speed;
        if (d.rampTime) fields["rampTime"] = *d.rampTime;
        if (d.offset) fields["offset"] = *d.offset;
        drivers[name] = fields;
      }
      entry["drivers"] = drivers;
    }
    if (s.gravity) entry["gravity"] = json::array({(*s.gravity)[0], (*s.gravity)[1]});
    out.push_back(entry);
  }
  return out;
}

rod::RodConfig scenarioRod(const rod::RodConfig& rod, const Scenario& scenario) {
  rod::RodConfig out = rod;
  if (scenario.crankSpeed) out.crankSpeed = *scenario.crankSpeed;
  if (scenario.rampTime) out.rampTime = *scenario.rampTime;
  if (scenario.endTime) out.endTime = *scenario.endTime;
  if (scenario.crankRadius) out.crankRadius = *scenario.crankRadius;
  return out;
}

void validateScenarios(const std::vector<Scenario>& scenarios, const rod::RodConfig& rod) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < scenarios.size(); ++i) {
    const Scenario& s = scenarios[i];
    const std::string at = "scenarios[" + std::to_string(i) + "]";
    if (!names.insert(s.name).second)
      throw std::invalid_argument(at + ".name = \"" + s.name +
                                  "\" is used by an earlier scenario; names must be unique");
    if (!(s.weight > 0.0 && std::isfinite(s.weight))) {
      std::ostringstream m;
      m << at << ".weight = " << s.weight << " is outside the allowed range (0, inf)";
      throw std::invalid_argument(m.str());
    }
    const rod::RodConfig r = scenarioRod(rod, s);
    if (!(r.crankSpeed > 0.0 && std::isfinite(r.crankSpeed))) {
      std::ostringstream m;
      m << at << ".crankSpeed = " << r.crankSpeed << " is outside the allowed range (0, inf)";
      throw std::invalid_argument(m.str());
    }
    if (!(r.crankRadius > 0.0 && r.crankRadius < r.length)) {
      std::ostringstream m;
      m << at << ".crankRadius = " << r.crankRadius << " is outside the allowed range (0, rod.length) = (0, "
        << r.length << ")";
      throw std::invalid_argument(m.str());
    }
    if (!(r.endTime >= r.rampTime)) {
      std::ostringstream m;
      m << at << ".endTime = " << r.endTime << " is outside the allowed range [rampTime, inf) = ["
        << r.rampTime << ", inf) (fields a scenario omits take the rod's values)";
      throw std::invalid_argument(m.str());
    }
    try {
      r.validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(at + " ('" + s.name + "'): " + e.what());
    }
  }
}

}  // namespace hindsight
