#include <hindsight/problems/mechanism/mechanism.h>

#include <hindsight/engine/deterministic_math.h>

#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>

namespace hindsight::mechanism {

void DriverLaw::at(double t, double& s, double& sDot, double& sDdot) const {
  if (kind == Kind::ConstantSpeed) {
    s = speed * t;
    sDot = speed;
    sDdot = 0.0;
    return;
  }
  // rod::CrankMotion::at (problems/rod/crank_motion.h) evaluates this law too, so the described, the
  // full-order and the tests' closed-form slider-crank see the crank angle's same bits.
  if (t < rampTime) {
    const double tau = t / rampTime;
    const double twoPi = 2.0 * M_PI;
    double sine, cosine;
    dmath::sincos(twoPi * tau, &sine, &cosine);
    sDot = speed * (tau - sine / twoPi);
    sDdot = speed / rampTime * (1.0 - cosine);
    s = speed * rampTime * (tau * tau / 2.0 + (cosine - 1.0) / (twoPi * twoPi));
  } else {
    sDot = speed;
    sDdot = 0.0;
    s = speed * rampTime / 2.0 + speed * (t - rampTime);
  }
}

Mechanism& Mechanism::addGroundPoint(const std::string& point, const Vec2& position) {
  groundPoints[point] = position;
  return *this;
}

Mechanism& Mechanism::addRigidBody(const RigidBody& body) {
  rigidBodies.push_back(body);
  return *this;
}

Mechanism& Mechanism::setMember(const std::string& name, const Vec2& positionOfA, double angle) {
  member.name = name;
  member.position = positionOfA;
  member.angle = angle;
  return *this;
}

namespace {
Joint makeJoint(const std::string& name, JointType type, const std::string& body1, const std::string& point1,
                const std::string& body2, const std::string& point2) {
  Joint j;
  j.name = name;
  j.type = type;
  j.body1 = body1;
  j.point1 = point1;
  j.body2 = body2;
  j.point2 = point2;
  return j;
}
}  // namespace

Mechanism& Mechanism::addRevolute(const std::string& name, const std::string& body1,
                                  const std::string& point1, const std::string& body2,
                                  const std::string& point2) {
  joints.push_back(makeJoint(name, JointType::Revolute, body1, point1, body2, point2));
  return *this;
}

Mechanism& Mechanism::addPrismatic(const std::string& name, const std::string& body1,
                                   const std::string& point1, const std::string& body2,
                                   const std::string& point2, const Vec2& axis) {
  joints.push_back(makeJoint(name, JointType::Prismatic, body1, point1, body2, point2));
  joints.back().axis = axis;
  return *this;
}

Mechanism& Mechanism::addFixed(const std::string& name, const std::string& body1, const std::string& point1,
                               const std::string& body2, const std::string& point2) {
  joints.push_back(makeJoint(name, JointType::Fixed, body1, point1, body2, point2));
  return *this;
}

Mechanism& Mechanism::addDriver(const std::string& name, const std::string& joint, const DriverLaw& law,
                                double offset) {
  drivers.push_back(Driver{name, joint, law, offset});
  return *this;
}

Mechanism& Mechanism::addSpring(const Spring& spring) {
  springs.push_back(spring);
  return *this;
}

Mechanism& Mechanism::addFree(const std::string& body, CoordinateKind coordinate, double velocity) {
  free.push_back(FreeCoordinate{body, coordinate, velocity});
  return *this;
}

int Mechanism::constraintCount() const {
  int count = static_cast<int>(drivers.size());
  for (const Joint& j : joints) count += j.type == JointType::Fixed ? 3 : 2;
  return count;
}

std::string toString(JointType type) {
  switch (type) {
    case JointType::Revolute:
      return "revolute";
    case JointType::Prismatic:
      return "prismatic";
    case JointType::Fixed:
      return "fixed";
  }
  return "?";
}

std::string toString(CoordinateKind kind) {
  switch (kind) {
    case CoordinateKind::X:
      return "x";
    case CoordinateKind::Y:
      return "y";
    case CoordinateKind::Angle:
      return "angle";
  }
  return "?";
}

std::string toString(DriverLaw::Kind kind) {
  return kind == DriverLaw::Kind::CycloidalRamp ? "cycloidal-ramp" : "constant-speed";
}

namespace {

bool finite(const Vec2& v) { return std::isfinite(v(0)) && std::isfinite(v(1)); }

std::string show(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

}  // namespace

void Mechanism::validate() const {
  const std::string root = "mechanism";
  if (rigidBodies.size() > static_cast<std::size_t>(kMaxRigidBodies)) {
    throw std::invalid_argument(root + ".rigidBodies lists " + std::to_string(rigidBodies.size()) +
                                " bodies; at most " + std::to_string(kMaxRigidBodies) + " are supported");
  }
  // Bodies and their names.
  std::vector<std::string> bodyNames{"ground"};
  std::set<std::string> names{"ground"};
  auto needName = [&](const std::string& where, const std::string& name) {
    if (name.empty()) throw std::invalid_argument(where + ".name must not be empty");
    if (!names.insert(name).second) {
      throw std::invalid_argument(where + ".name = '" + name + "' is used twice (body names are unique; " +
                                  "'ground' is the fixed body)");
    }
    bodyNames.push_back(name);
  };
  for (const auto& [point, position] : groundPoints) {
    if (!finite(position)) throw std::invalid_argument(root + ".ground.points." + point + " must be finite");
  }
  for (const RigidBody& b : rigidBodies) {
    const std::string where = root + ".rigidBodies[" + b.name + "]";
    needName(where, b.name);
    if (!(b.mass >= 0.0) || !std::isfinite(b.mass)) {
      throw std::invalid_argument(where + ".mass = " + show(b.mass) +
                                  " is outside the allowed range [0, inf)");
    }
    if (!(b.inertia >= 0.0) || !std::isfinite(b.inertia)) {
      throw std::invalid_argument(where + ".inertia = " + show(b.inertia) +
                                  " is outside the allowed range [0, inf)");
    }
    if (!finite(b.position) || !std::isfinite(b.angle)) {
      throw std::invalid_argument(where + ".position and .angle must be finite");
    }
    for (const auto& [point, position] : b.points) {
      if (!finite(position)) throw std::invalid_argument(where + ".points." + point + " must be finite");
    }
  }
  needName(root + ".flexibleMember", member.name);
  if (!(member.length > 0.0))
    throw std::invalid_argument(root + ".flexibleMember: the length must be positive");
  if (!finite(member.position) || !std::isfinite(member.angle)) {
    throw std::invalid_argument(root + ".flexibleMember.position and .angle must be finite");
  }
  std::string bodyList;
  for (const std::string& n : bodyNames) bodyList += (bodyList.empty() ? "" : ", ") + n;

  auto checkPoint = [&](const std::string& where, const std::string& bodyField, const std::string& body,
                        const std::string& pointField, const std::string& point) {
    if (names.count(body) == 0) {
      throw std::invalid_argument(where + "." + bodyField + " = '" + body +
                                  "' is not a body; bodies: " + bodyList);
    }
    if (body == member.name) {
      if (point != "A" && point != "B") {
        throw std::invalid_argument(where + "." + pointField + " = '" + point +
                                    "' is not a point of the flexible " + "member '" + body +
                                    "'; its points are A and B (the joints that define its frame)");
      }
      return;
    }
    const std::map<std::string, Vec2>* points = &groundPoints;
    for (const RigidBody& b : rigidBodies) {
      if (b.name == body) points = &b.points;
    }
    if (points->count(point) == 0) {
      std::string list;
      for (const auto& [name, position] : *points) list += (list.empty() ? "" : ", ") + name;
      throw std::invalid_argument(where + "." + pointField + " = '" + point + "' is not a point of body '" +
                                  body + "'; its points: " + (list.empty() ? "(none)" : list));
    }
  };

  std::set<std::string> jointNames;
  for (const Joint& j : joints) {
    const std::string where = root + ".joints[" + j.name + "]";
    if (j.name.empty()) throw std::invalid_argument(root + ".joints: a joint has an empty name");
    if (!jointNames.insert(j.name).second) throw std::invalid_argument(where + ".name is used twice");
    checkPoint(where, "body1", j.body1, "point1", j.point1);
    checkPoint(where, "body2", j.body2, "point2", j.point2);
    if (j.body1 == j.body2)
      throw std::invalid_argument(where + ": body1 and body2 are the same body '" + j.body1 + "'");
    if (j.type == JointType::Prismatic && !(finite(j.axis) && j.axis.norm() > 0.0)) {
      throw std::invalid_argument(where + ".axis must be a finite non-zero vector");
    }
  }
  std::set<std::string> driverNames, drivenJoints;
  for (const Driver& d : drivers) {
    const std::string where = root + ".drivers[" + d.name + "]";
    if (d.name.empty()) throw std::invalid_argument(root + ".drivers: a driver has an empty name");
    if (!driverNames.insert(d.name).second) throw std::invalid_argument(where + ".name is used twice");
    const Joint* joint = nullptr;
    for (const Joint& j : joints) {
      if (j.name == d.joint) joint = &j;
    }
    if (joint == nullptr) throw std::invalid_argument(where + ".joint = '" + d.joint + "' is not a joint");
    if (joint->type == JointType::Fixed) {
      throw std::invalid_argument(where + ".joint = '" + d.joint +
                                  "' is a fixed joint; a driver needs a revolute " + "or prismatic joint");
    }
    if (!drivenJoints.insert(d.joint).second) {
      throw std::invalid_argument(where + ".joint = '" + d.joint + "' has a driver already");
    }
    if (!std::isfinite(d.law.speed)) throw std::invalid_argument(where + ".speed must be finite");
    if (d.law.kind == DriverLaw::Kind::CycloidalRamp &&
        !(d.law.rampTime > 0.0 && std::isfinite(d.law.rampTime))) {
      throw std::invalid_argument(where + ".rampTime = " + show(d.law.rampTime) +
                                  " is outside the allowed range (0, inf)");
    }
    if (!std::isfinite(d.offset)) throw std::invalid_argument(where + ".offset must be finite");
  }
  std::set<std::string> springNames;
  for (const Spring& s : springs) {
    const std::string where = root + ".springs[" + s.name + "]";
    if (s.name.empty()) throw std::invalid_argument(root + ".springs: a spring has an empty name");
    if (!springNames.insert(s.name).second) throw std::invalid_argument(where + ".name is used twice");
    checkPoint(where, "body1", s.body1, "point1", s.point1);
    checkPoint(where, "body2", s.body2, "point2", s.point2);
    for (const auto& [field, value] :
         {std::pair{"stiffness", s.stiffness}, std::pair{"restLength", s.restLength},
          std::pair{"damping", s.damping}}) {
      if (!(value >= 0.0) || !std::isfinite(value)) {
        throw std::invalid_argument(where + "." + field + " = " + show(value) +
                                    " is outside the allowed range [0, inf)");
      }
    }
  }
  std::set<std::pair<std::string, int>> freeSeen;
  for (const FreeCoordinate& f : free) {
    const std::string where = root + ".free[" + f.body + "." + toString(f.coordinate) + "]";
    bool rigid = false;
    for (const RigidBody& b : rigidBodies) rigid = rigid || b.name == f.body;
    if (!rigid) {
      throw std::invalid_argument(
          where + ".body = '" + f.body + "' is not a rigid body (free coordinates are " +
          "rigid bodies' x, y or angle; the flexible member's frame follows its joints)");
    }
    if (!freeSeen.insert({f.body, static_cast<int>(f.coordinate)}).second) {
      throw std::invalid_argument(where + " is listed twice");
    }
    if (!std::isfinite(f.velocity)) throw std::invalid_argument(where + ".velocity must be finite");
  }
  const int rigidCoordinates = 3 * static_cast<int>(rigidBodies.size()) + 3;
  const int dof = rigidCoordinates - constraintCount();
  if (dof != static_cast<int>(free.size())) {
    throw std::invalid_argument(
        root + ": the rigid bodies and the member's frame have " + std::to_string(rigidCoordinates) +
        " coordinates and the joints and drivers " + std::to_string(constraintCount()) + " constraints, so " +
        root + ".free must list " + std::to_string(dof) + " coordinate(s), not " +
        std::to_string(free.size()));
  }
}

Mechanism sliderCrank(double crankRadius, double length, double speed, double rampTime, double sliderMass) {
  Mechanism m;
  m.addGroundPoint("O", Vec2::Zero());
  RigidBody crank;
  crank.name = "crank";
  crank.points = {{"O", Vec2::Zero()}, {"pin", Vec2(crankRadius, 0.0)}};
  m.addRigidBody(crank);
  RigidBody slider;
  slider.name = "slider";
  slider.mass = sliderMass;
  slider.position = Vec2(crankRadius + length, 0.0);
  slider.points = {{"center", Vec2::Zero()}};
  m.addRigidBody(slider);
  m.member.length = length;
  m.setMember("rod", Vec2(crankRadius, 0.0), 0.0);
  DriverLaw law;
  law.speed = speed;
  law.rampTime = rampTime;
  m.addRevolute("bearing", "ground", "O", "crank", "O")
      .addRevolute("crankPin", "crank", "pin", "rod", "A")
      .addRevolute("wristPin", "rod", "B", "slider", "center")
      .addPrismatic("guide", "ground", "O", "slider", "center", Vec2(1.0, 0.0))
      .addDriver("motor", "bearing", law);
  return m;
}

}  // namespace hindsight::mechanism
