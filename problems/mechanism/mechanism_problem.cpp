// A MechanismProblem built from its description (docs/design.md §10): the description validated, the
// coordinates split into independent (free rigid coordinates, q) and dependent ones, the joints and drivers
// turned into constraint rows, the mechanism assembled at t = 0, and the chord system derived from the
// full one; the sizes and the workspaces.
//
// The equations (mechanism_problem.h explains them) are split by concern, the files sharing the internal
// headers of detail/ (not installed): detail/system.h the compiled mechanism and the constraint rows'
// formulas, constraint_blocks.cpp their block-triangular order, constraint_solve.cpp the position solves;
// kinematics.cpp z, z', zeta and R in double and dual numbers; member_forces.cpp the member's
// floating-frame terms (mass matrix, quadratic velocity terms, modal rows) and their projection;
// residual_assembly.cpp the mass matrix, force, Jacobians and state products the integrators ask for;
// design_sensitivities.cpp the parameter product; objective.cpp psi1 and its partials; reference_path.cpp
// the full-coordinate reference of the tests and the energies. The member is only its invariants p
// (detail/member_invariants.h): no file asks whether it is a plate or a solid (docs/design.md §11).
#include <hindsight/problems/mechanism/detail/member_forces.h>

#include <stdexcept>
#include <string>

namespace hindsight::mechanism::detail {

PointRef System::pointRef(const Mechanism& mech, const std::string& body, const std::string& point) const {
  PointRef r;
  if (body == "ground") {
    r.body = kGround;
    r.local = mech.groundPoints.at(point);
    return r;
  }
  if (body == mech.member.name) {
    r.body = nr;
    r.atB = point == "B";
    r.local = r.atB ? Vec2(length, 0.0) : Vec2::Zero();
    return r;
  }
  for (int k = 0; k < nr; ++k) {
    if (mech.rigidBodies[k].name == body) {
      r.body = k;
      r.local = mech.rigidBodies[k].points.at(point);
    }
  }
  return r;
}

int System::bodyIndex(const Mechanism& mech, const std::string& body) const {
  if (body == "ground") return kGround;
  if (body == mech.member.name) return nr;
  for (int k = 0; k < nr; ++k) {
    if (mech.rigidBodies[k].name == body) return k;
  }
  return kGround;
}

}  // namespace hindsight::mechanism::detail

namespace hindsight::mechanism {

using namespace detail;

MechanismProblem::MechanismProblem(const Mechanism& mechanism, int modeCount, bool spatialMember)
    : mechanism_(mechanism), modes_(modeCount), impl_(std::make_unique<Impl>()) {
  impl_->spatial = spatialMember;
  if (modeCount < 1 || modeCount > kMaxModes) {
    throw std::invalid_argument("modeCount = " + std::to_string(modeCount) + " must be in [1, " +
                                std::to_string(kMaxModes) + "]");
  }
  mechanism_.validate();
  if (static_cast<int>(mechanism_.free.size()) > kMaxFree) {
    throw std::invalid_argument("mechanism.free lists " + std::to_string(mechanism_.free.size()) +
                                " coordinates; at most " + std::to_string(kMaxFree) + " are supported");
  }
  Impl& I = *impl_;
  const Mechanism& M = mechanism_;
  I.nr = static_cast<int>(M.rigidBodies.size());
  I.n = modeCount;
  I.base = 3 * I.nr;
  I.nz = I.base + 3 + I.n;
  I.m = M.constraintCount();
  I.nFree = static_cast<int>(M.free.size());
  I.f = I.nFree + I.n;
  I.length = M.member.length;
  I.gravity = M.gravity;
  for (const RigidBody& b : M.rigidBodies) {
    I.mass.push_back(b.mass);
    I.inertia.push_back(b.inertia);
  }
  I.zInitial = Vector::Zero(I.nz);
  for (int k = 0; k < I.nr; ++k) {
    I.zInitial.segment<2>(3 * k) = M.rigidBodies[k].position;
    I.zInitial(3 * k + 2) = M.rigidBodies[k].angle;
  }
  I.zInitial.segment<2>(I.base) = M.member.position;
  I.zInitial(I.base + 2) = M.member.angle;
  std::vector<bool> isFree(I.nz, false);
  I.vInitial = Vector::Zero(I.f);
  for (int k = 0; k < I.nFree; ++k) {
    const FreeCoordinate& fc = M.free[k];
    const int index = 3 * I.bodyIndex(M, fc.body) + static_cast<int>(fc.coordinate);
    I.independent.push_back(index);
    isFree[index] = true;
    I.vInitial(k) = fc.velocity;
  }
  for (int i = 0; i < I.n; ++i) {
    I.independent.push_back(I.base + 3 + i);
    isFree[I.base + 3 + i] = true;
  }
  for (int i = 0; i < I.base + 3; ++i) {
    if (!isFree[i]) I.dependent.push_back(i);
  }
  auto angleOf = [&](const std::string& body) {
    if (body == "ground") return 0.0;
    if (body == M.member.name) return M.member.angle;
    for (const RigidBody& b : M.rigidBodies) {
      if (b.name == body) return b.angle;
    }
    return 0.0;
  };
  for (const Joint& j : M.joints) {
    Row r;
    r.p1 = I.pointRef(M, j.body1, j.point1);
    r.p2 = I.pointRef(M, j.body2, j.point2);
    r.body1 = I.bodyIndex(M, j.body1);
    r.body2 = I.bodyIndex(M, j.body2);
    r.axis = j.axis.normalized();
    const Driver* driver = nullptr;
    for (const Driver& d : M.drivers) {
      if (d.joint == j.name) driver = &d;
    }
    r.name = j.name;
    const double relative = angleOf(j.body2) - angleOf(j.body1);
    if (j.type == JointType::Revolute || j.type == JointType::Fixed) {
      r.kind = Row::Revolute;
      I.rows.push_back(r);
      if (j.type == JointType::Fixed) {
        r.kind = Row::Angle;
        r.offset = relative;
        I.rows.push_back(r);
      }
      if (driver != nullptr) {
        r.kind = Row::DriveAngle;
        r.offset = driver->offset;
        r.law = driver->law;
        r.name = driver->name;
        I.rows.push_back(r);
      }
    } else {
      r.kind = Row::Angle;
      r.offset = relative;
      I.rows.push_back(r);
      r.kind = Row::Line;
      I.rows.push_back(r);
      if (driver != nullptr) {
        r.kind = Row::DriveLine;
        r.offset = driver->offset;
        r.law = driver->law;
        r.name = driver->name;
        I.rows.push_back(r);
      }
    }
  }
  for (int r = 0, i = 0; r < static_cast<int>(I.rows.size()); ++r) {
    const Row& row = I.rows[r];
    I.rowFirst.push_back(i);
    i += row.kind == Row::Revolute ? 2 : 1;
    I.rowOf.resize(i, r);
    switch (row.kind) {
      case Row::Revolute:
        I.equationNames.push_back(row.name + ".x");
        I.equationNames.push_back(row.name + ".y");
        break;
      case Row::Angle:
        I.equationNames.push_back(row.name + ".angle");
        break;
      case Row::Line:
        I.equationNames.push_back(row.name + ".line");
        break;
      default:
        I.equationNames.push_back(row.name);
    }
  }
  for (int k = 0; k <= I.nr; ++k) {
    const std::string& body = k == I.nr ? M.member.name : M.rigidBodies[k].name;
    for (const char* c : {".x", ".y", ".angle"}) I.coordinateNames.push_back(body + c);
  }
  for (int i = 0; i < I.n; ++i) I.coordinateNames.push_back(M.member.name + ".q" + std::to_string(i));
  for (const Spring& s : M.springs) {
    I.springs.push_back(SpringRef{I.pointRef(M, s.body1, s.point1), I.pointRef(M, s.body2, s.point2),
                                  s.stiffness, s.restLength, s.damping});
  }
  I.yInitial = Vector::Zero(I.f);
  for (int k = 0; k < I.nFree; ++k) I.yInitial(k) = I.zInitial(I.independent[k]);
  // Assemble at t = 0 from the described positions (q = 0, so b does not enter).
  Buffers<double> assembly(I.nz, I.m, I.f, I.n);
  for (int i = 0; i < I.nz; ++i) assembly.z[i] = I.zInitial(i);
  for (int i = 0; i < I.n; ++i) assembly.b[i] = 0.0;
  try {
    I.newton(0.0, assembly, -1, 1e-12);
  } catch (const NumericalError& e) {
    throw std::invalid_argument(std::string("mechanism: the initial positions do not assemble at t = 0: ") +
                                e.what());
  }
  for (int i = 0; i < I.nz; ++i) I.zInitial(i) = assembly.z[i];
  // The chord system: the same bodies and constraints with one coordinate c = b q in place of q (one
  // "mode" whose displacement row at B is 1), independent like the free coordinates.
  chord_ = std::make_unique<Impl>(I);
  Impl& C = *chord_;
  C.n = 1;
  C.nz = I.base + 4;
  C.f = I.nFree + 1;
  C.independent.assign(I.independent.begin(), I.independent.begin() + I.nFree);
  C.independent.push_back(I.base + 3);
  C.zInitial = I.zInitial.head(I.base + 4);
  C.zInitial(I.base + 3) = 0.0;
  C.yInitial = Vector::Zero(C.f);
  C.yInitial.head(I.nFree) = I.yInitial.head(I.nFree);
  C.vInitial = Vector::Zero(C.f);
  C.buildBlocks();
}

MechanismProblem::~MechanismProblem() = default;

int MechanismProblem::coordinateCount() const { return impl_->f; }
int MechanismProblem::freeCount() const { return impl_->nFree; }
int MechanismProblem::parameterSize() const {
  return 4 + 5 * modes_ + (impl_->spatial ? 4 : 3) * modes_ * modes_;
}
int MechanismProblem::fullCoordinateCount() const { return impl_->nz; }
int MechanismProblem::memberOffset() const { return impl_->base; }

std::unique_ptr<ProblemWorkspace> MechanismProblem::createModelWorkspace() const {
  return std::make_unique<Work>(*impl_, *chord_);
}

std::unique_ptr<ProblemWorkspace> MechanismProblem::createModelWorkspaceFor(ConstVectorRef p) const {
  auto w = std::make_unique<Work>(*impl_, *chord_);
  meeOf(View(modes_, p.data(), impl_->spatial), *w);
  w->parametersFixed = true;
  return w;
}

void MechanismProblem::initialCoordinates(ConstVectorRef, VectorRef y0, VectorRef v0) const {
  y0 = impl_->yInitial;
  v0 = impl_->vInitial;
}

}  // namespace hindsight::mechanism
