// A planar mechanism with one flexible SIMP member (the design member) and rigid bodies, described as
// data: the `mechanism` section of the configuration (problems/mechanism/mechanism_json.h) or the same
// built in C++ with the add* methods below. docs/tutorials/own_mechanism.md shows both.
//
// Bodies. `ground` is the fixed body (its points are global coordinates). A rigid body has a mass, a
// moment of inertia about its centre of mass, a body frame with origin at the centre of mass, an
// initial position and angle, and named points in its body frame (a point mass is a rigid body with
// inertia 0). The flexible member is the rod of the `rod` section of the configuration (rectangle,
// mesh, material, SIMP law, modes): its body frame is the chord of its two joints A (body-frame (0, 0),
// pinned in the FE model) and B ((L, 0), on a roller u_y = 0 in the FE model), so its modal basis and
// inertia invariants are those of problems/rod/invariants.h and joints attach to it at A and B only.
//
// Joints (each removes the stated number of degrees of freedom):
//   revolute  (2)  point1 of body1 and point2 of body2 coincide;
//   prismatic (2)  body2 does not rotate relative to body1, and point2 stays on the line through point1
//                  along `axis` (body1's frame);
//   fixed     (3)  the two points coincide and the relative angle is kept.
// Drivers prescribe a revolute joint's relative angle theta2 - theta1 = offset + s(t) or a prismatic
// joint's displacement along its axis (point2 - point1) . axis = offset + s(t) (1 each), with s(t) one
// of the laws of DriverLaw. Springs (linear, with a rest length and a parallel viscous damper) act
// between two points; gravity acts on every body.
//
// The remaining degrees of freedom are the modal coordinates of the flexible member and the `free`
// rigid coordinates the description lists (body x, y or angle); their number must equal
// 3 (bodies) + 3 (member) - constraints. validate() checks names, references, ranges and this count and
// throws std::invalid_argument naming the body, joint, driver, spring or field.
#pragma once

#include <Eigen/Core>

#include <map>
#include <string>
#include <vector>

namespace hindsight::mechanism {

using Vec2 = Eigen::Vector2d;

/// s(t) of a driver. CycloidalRamp: s' = speed (tau - sin(2 pi tau) / (2 pi)), tau = t / rampTime, for
/// t <= rampTime, then s' = speed; s(0) = 0 (the crank of docs/design.md §2). ConstantSpeed: s = speed t.
struct DriverLaw {
  enum class Kind { CycloidalRamp, ConstantSpeed };
  Kind kind = Kind::CycloidalRamp;
  double speed = 0.0;     ///< [rad/s] or [m/s]
  double rampTime = 1.0;  ///< [s], CycloidalRamp only, > 0
  /// s, s', s'' at time t.
  void at(double t, double& s, double& sDot, double& sDdot) const;
};

struct RigidBody {
  std::string name;
  double mass = 0.0;     ///< [kg], >= 0
  double inertia = 0.0;  ///< [kg m^2] about the centre of mass, >= 0
  Vec2 position = Vec2::Zero();
  double angle = 0.0;  ///< initial angle [rad] (the assembly starts from it)
  std::map<std::string, Vec2> points;
};

struct FlexibleMember {
  std::string name = "rod";
  double length = 1.0;           ///< L [m]: set from the rod section (rod.length)
  Vec2 position = Vec2::Zero();  ///< initial position of A
  double angle = 0.0;            ///< initial angle of the chord A-B [rad]
};

enum class JointType { Revolute, Prismatic, Fixed };

struct Joint {
  std::string name;
  JointType type = JointType::Revolute;
  std::string body1, point1, body2, point2;
  Vec2 axis = Vec2(1.0, 0.0);  ///< prismatic: direction in body1's frame (normalised by validate's user)
};

struct Driver {
  std::string name;
  std::string joint;  ///< a revolute or prismatic joint
  DriverLaw law;
  double offset = 0.0;  ///< the joint's angle [rad] or displacement [m] at t = 0
};

struct Spring {
  std::string name;
  std::string body1, point1, body2, point2;
  double stiffness = 0.0;   ///< [N/m], >= 0
  double restLength = 0.0;  ///< [m], >= 0
  double damping = 0.0;     ///< [N s/m], >= 0
};

enum class CoordinateKind { X, Y, Angle };

/// A rigid coordinate that is a degree of freedom (minimal coordinate) of the mechanism.
struct FreeCoordinate {
  std::string body;
  CoordinateKind coordinate = CoordinateKind::Angle;
  double velocity = 0.0;  ///< initial velocity; the initial value is the body's position/angle
};

/// Rigid bodies a description may have. The model solves its constraints with dense Jacobians in dual
/// numbers (problems/mechanism/mechanism_problem.h), whose memory grows with the square and whose work
/// with the cube of the coordinates: 32 bodies take a few megabytes, 400 took gigabytes and minutes
/// before the first step. validate() refuses more, naming mechanism.rigidBodies.
constexpr int kMaxRigidBodies = 32;

struct Mechanism {
  Vec2 gravity = Vec2::Zero();  ///< [m/s^2]
  std::map<std::string, Vec2> groundPoints;
  std::vector<RigidBody> rigidBodies;
  FlexibleMember member;
  std::vector<Joint> joints;
  std::vector<Driver> drivers;
  std::vector<Spring> springs;
  std::vector<FreeCoordinate> free;

  // The C++ builder: each call appends and returns *this; validate() checks the whole.
  Mechanism& addGroundPoint(const std::string& point, const Vec2& position);
  Mechanism& addRigidBody(const RigidBody& body);
  Mechanism& setMember(const std::string& name, const Vec2& positionOfA, double angle);
  Mechanism& addRevolute(const std::string& name, const std::string& body1, const std::string& point1,
                         const std::string& body2, const std::string& point2);
  Mechanism& addPrismatic(const std::string& name, const std::string& body1, const std::string& point1,
                          const std::string& body2, const std::string& point2, const Vec2& axis);
  Mechanism& addFixed(const std::string& name, const std::string& body1, const std::string& point1,
                      const std::string& body2, const std::string& point2);
  Mechanism& addDriver(const std::string& name, const std::string& joint, const DriverLaw& law,
                       double offset = 0.0);
  Mechanism& addSpring(const Spring& spring);
  Mechanism& addFree(const std::string& body, CoordinateKind coordinate, double velocity = 0.0);

  /// Number of constraint equations (joints and drivers).
  int constraintCount() const;
  /// Throws std::invalid_argument naming the element and field ("mechanism.joints[crankPin].body2 =
  /// 'rood' is not a body; bodies: ground, crank, rod, slider").
  void validate() const;
};

std::string toString(JointType type);
std::string toString(CoordinateKind kind);
std::string toString(DriverLaw::Kind kind);

/// The slider-crank of docs/design.md §2 with the guide through the crank pivot: a massless crank of
/// radius r driven by the cycloidal ramp, the member from the crank pin (A) to the slider (B), the
/// slider of the given mass on a prismatic joint along x. With sliderMass = 0 this is the tests'
/// closed-form model (tests/support/slider_crank.h).
Mechanism sliderCrank(double crankRadius, double length, double speed, double rampTime,
                      double sliderMass = 0.0);

}  // namespace hindsight::mechanism
