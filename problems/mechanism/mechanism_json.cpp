#include <hindsight/problems/mechanism/mechanism_json.h>

#include <cmath>
#include <set>
#include <stdexcept>

namespace hindsight::mechanism {
namespace {

using nlohmann::json;

std::string render(const json& value) {
  // dump() writes a non-finite double (from a Python dict) as null, which is not what was given.
  if (value.is_number_float() && !std::isfinite(value.get<double>())) {
    const double x = value.get<double>();
    return std::isnan(x) ? "nan" : (x > 0 ? "inf" : "-inf");
  }
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

void onlyKeys(const json& object, const std::string& where, const std::set<std::string>& allowed) {
  if (!object.is_object()) throw std::invalid_argument(where + " must be a JSON object");
  for (auto it = object.begin(); it != object.end(); ++it) {
    if (allowed.count(it.key()) == 0) {
      std::string list;
      for (const std::string& k : allowed) list += (list.empty() ? "" : ", ") + k;
      throw std::invalid_argument(where + "." + it.key() + " is not a field; fields: " + list);
    }
  }
}

double number(const json& object, const std::string& where, const std::string& key, double fallback) {
  if (!object.contains(key)) return fallback;
  const json& v = object.at(key);
  if (!v.is_number() || !std::isfinite(v.get<double>())) {
    throw std::invalid_argument(where + "." + key + " = " + render(v) + " must be a finite number");
  }
  return v.get<double>();
}

std::string text(const json& object, const std::string& where, const std::string& key, bool required = true) {
  if (!object.contains(key)) {
    if (required) throw std::invalid_argument(where + "." + key + " is missing");
    return "";
  }
  const json& v = object.at(key);
  if (!v.is_string())
    throw std::invalid_argument(where + "." + key + " = " + render(v) + " must be a string");
  return v.get<std::string>();
}

Vec2 vec2(const json& object, const std::string& where, const std::string& key, const Vec2& fallback) {
  if (!object.contains(key)) return fallback;
  const json& v = object.at(key);
  if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number()) {
    throw std::invalid_argument(where + "." + key + " = " + render(v) +
                                " must be an array of two numbers [x, y]");
  }
  return Vec2(v[0].get<double>(), v[1].get<double>());
}

std::map<std::string, Vec2> points(const json& object, const std::string& where) {
  std::map<std::string, Vec2> out;
  if (!object.contains("points")) return out;
  const json& p = object.at("points");
  if (!p.is_object()) throw std::invalid_argument(where + ".points must be an object {name: [x, y]}");
  for (auto it = p.begin(); it != p.end(); ++it)
    out[it.key()] = vec2(p, where + ".points", it.key(), Vec2::Zero());
  return out;
}

const json& array(const json& object, const std::string& where, const std::string& key) {
  static const json empty = json::array();
  if (!object.contains(key)) return empty;
  const json& v = object.at(key);
  if (!v.is_array()) throw std::invalid_argument(where + "." + key + " must be an array");
  return v;
}

/// "mechanism.joints[crankPin]" when the element has a name, else "mechanism.joints[2]".
std::string element(const std::string& where, const json& e, std::size_t index) {
  if (e.is_object() && e.contains("name") && e.at("name").is_string()) {
    return where + "[" + e.at("name").get<std::string>() + "]";
  }
  return where + "[" + std::to_string(index) + "]";
}

json toJson(const Vec2& v) { return json::array({v(0), v(1)}); }

json toJson(const std::map<std::string, Vec2>& points) {
  json out = json::object();
  for (const auto& [name, p] : points) out[name] = toJson(p);
  return out;
}

}  // namespace

Mechanism mechanismFromJson(const json& in, double memberLength) {
  const std::string root = "mechanism";
  onlyKeys(in, root,
           {"gravity", "ground", "rigidBodies", "flexibleMember", "joints", "drivers", "springs", "free"});
  Mechanism m;
  m.member.length = memberLength;
  m.gravity = vec2(in, root, "gravity", Vec2::Zero());
  if (in.contains("ground")) {
    onlyKeys(in.at("ground"), root + ".ground", {"points"});
    m.groundPoints = points(in.at("ground"), root + ".ground");
  }
  const json& bodies = array(in, root, "rigidBodies");
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const json& b = bodies[i];
    const std::string where = element(root + ".rigidBodies", b, i);
    onlyKeys(b, where, {"name", "mass", "inertia", "position", "angle", "points"});
    RigidBody body;
    body.name = text(b, where, "name");
    body.mass = number(b, where, "mass", 0.0);
    body.inertia = number(b, where, "inertia", 0.0);
    body.position = vec2(b, where, "position", Vec2::Zero());
    body.angle = number(b, where, "angle", 0.0);
    body.points = points(b, where);
    m.rigidBodies.push_back(body);
  }
  if (!in.contains("flexibleMember")) {
    throw std::invalid_argument(root +
                                ".flexibleMember is missing (the design member, with its joints A and B)");
  }
  {
    const json& f = in.at("flexibleMember");
    const std::string where = root + ".flexibleMember";
    onlyKeys(f, where, {"name", "position", "angle"});
    m.member.name = f.contains("name") ? text(f, where, "name") : std::string("rod");
    m.member.position = vec2(f, where, "position", Vec2::Zero());
    m.member.angle = number(f, where, "angle", 0.0);
  }
  const json& joints = array(in, root, "joints");
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const json& j = joints[i];
    const std::string where = element(root + ".joints", j, i);
    onlyKeys(j, where, {"name", "type", "body1", "point1", "body2", "point2", "axis"});
    Joint joint;
    joint.name = text(j, where, "name");
    const std::string type = text(j, where, "type");
    if (type == "revolute") {
      joint.type = JointType::Revolute;
    } else if (type == "prismatic") {
      joint.type = JointType::Prismatic;
    } else if (type == "fixed") {
      joint.type = JointType::Fixed;
    } else {
      throw std::invalid_argument(where + ".type = '" + type +
                                  "' must be one of: revolute, prismatic, fixed");
    }
    joint.body1 = text(j, where, "body1");
    joint.point1 = text(j, where, "point1");
    joint.body2 = text(j, where, "body2");
    joint.point2 = text(j, where, "point2");
    if (j.contains("axis") && joint.type != JointType::Prismatic) {
      throw std::invalid_argument(where + ".axis is a field of prismatic joints only");
    }
    joint.axis = vec2(j, where, "axis", Vec2(1.0, 0.0));
    m.joints.push_back(joint);
  }
  const json& drivers = array(in, root, "drivers");
  for (std::size_t i = 0; i < drivers.size(); ++i) {
    const json& d = drivers[i];
    const std::string where = element(root + ".drivers", d, i);
    onlyKeys(d, where, {"name", "joint", "law", "speed", "rampTime", "offset"});
    Driver driver;
    driver.name = text(d, where, "name");
    driver.joint = text(d, where, "joint");
    const std::string law = text(d, where, "law");
    if (law == "cycloidal-ramp") {
      driver.law.kind = DriverLaw::Kind::CycloidalRamp;
    } else if (law == "constant-speed") {
      driver.law.kind = DriverLaw::Kind::ConstantSpeed;
      if (d.contains("rampTime"))
        throw std::invalid_argument(where + ".rampTime is a field of cycloidal-ramp only");
    } else {
      throw std::invalid_argument(where + ".law = '" + law +
                                  "' must be one of: cycloidal-ramp, constant-speed");
    }
    driver.law.speed = number(d, where, "speed", 0.0);
    driver.law.rampTime = number(d, where, "rampTime", 1.0);
    driver.offset = number(d, where, "offset", 0.0);
    m.drivers.push_back(driver);
  }
  const json& springs = array(in, root, "springs");
  for (std::size_t i = 0; i < springs.size(); ++i) {
    const json& s = springs[i];
    const std::string where = element(root + ".springs", s, i);
    onlyKeys(s, where, {"name", "body1", "point1", "body2", "point2", "stiffness", "restLength", "damping"});
    Spring spring;
    spring.name = text(s, where, "name");
    spring.body1 = text(s, where, "body1");
    spring.point1 = text(s, where, "point1");
    spring.body2 = text(s, where, "body2");
    spring.point2 = text(s, where, "point2");
    spring.stiffness = number(s, where, "stiffness", 0.0);
    spring.restLength = number(s, where, "restLength", 0.0);
    spring.damping = number(s, where, "damping", 0.0);
    m.springs.push_back(spring);
  }
  const json& free = array(in, root, "free");
  for (std::size_t i = 0; i < free.size(); ++i) {
    const json& f = free[i];
    const std::string where = root + ".free[" + std::to_string(i) + "]";
    onlyKeys(f, where, {"body", "coordinate", "velocity"});
    FreeCoordinate c;
    c.body = text(f, where, "body");
    const std::string coordinate = text(f, where, "coordinate");
    if (coordinate == "x") {
      c.coordinate = CoordinateKind::X;
    } else if (coordinate == "y") {
      c.coordinate = CoordinateKind::Y;
    } else if (coordinate == "angle") {
      c.coordinate = CoordinateKind::Angle;
    } else {
      throw std::invalid_argument(where + ".coordinate = '" + coordinate + "' must be one of: x, y, angle");
    }
    c.velocity = number(f, where, "velocity", 0.0);
    m.free.push_back(c);
  }
  m.validate();
  return m;
}

json toJson(const Mechanism& m) {
  json out;
  out["gravity"] = toJson(m.gravity);
  out["ground"] = json{{"points", toJson(m.groundPoints)}};
  out["rigidBodies"] = json::array();
  for (const RigidBody& b : m.rigidBodies) {
    out["rigidBodies"].push_back(json{{"name", b.name},
                                      {"mass", b.mass},
                                      {"inertia", b.inertia},
                                      {"position", toJson(b.position)},
                                      {"angle", b.angle},
                                      {"points", toJson(b.points)}});
  }
  out["flexibleMember"] =
      json{{"name", m.member.name}, {"position", toJson(m.member.position)}, {"angle", m.member.angle}};
  out["joints"] = json::array();
  for (const Joint& j : m.joints) {
    json e{{"name", j.name},     {"type", toString(j.type)}, {"body1", j.body1},
           {"point1", j.point1}, {"body2", j.body2},         {"point2", j.point2}};
    if (j.type == JointType::Prismatic) e["axis"] = toJson(j.axis);
    out["joints"].push_back(e);
  }
  out["drivers"] = json::array();
  for (const Driver& d : m.drivers) {
    json e{{"name", d.name},
           {"joint", d.joint},
           {"law", toString(d.law.kind)},
           {"speed", d.law.speed},
           {"offset", d.offset}};
    if (d.law.kind == DriverLaw::Kind::CycloidalRamp) e["rampTime"] = d.law.rampTime;
    out["drivers"].push_back(e);
  }
  out["springs"] = json::array();
  for (const Spring& s : m.springs) {
    out["springs"].push_back(json{{"name", s.name},
                                  {"body1", s.body1},
                                  {"point1", s.point1},
                                  {"body2", s.body2},
                                  {"point2", s.point2},
                                  {"stiffness", s.stiffness},
                                  {"restLength", s.restLength},
                                  {"damping", s.damping}});
  }
  out["free"] = json::array();
  for (const FreeCoordinate& f : m.free) {
    out["free"].push_back(
        json{{"body", f.body}, {"coordinate", toString(f.coordinate)}, {"velocity", f.velocity}});
  }
  return out;
}

}  // namespace hindsight::mechanism
