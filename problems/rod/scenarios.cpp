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
      } else {
        throw std::invalid_argument(who +
                                    " is unknown; fields of a scenario: name, crankSpeed, rampTime, "
                                    "endTime, crankRadius, weight");
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
