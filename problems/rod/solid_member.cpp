#include <hindsight/problems/rod/solid_member.h>

#include <stdexcept>
#include <string>

namespace hindsight {
namespace rod {

SolidMeshOptions solidMeshOptions(const RodConfig& config, HexFormulation formulation) {
  if (!config.isSolid())
    throw std::invalid_argument("SolidMember: RodConfig.elementsThroughThickness = " +
                                std::to_string(config.elementsThroughThickness) +
                                " is outside the allowed range [1, 10000] (0 is the plate, FeModel)");
  SolidMeshOptions options;
  options.elementsThroughThickness = config.elementsThroughThickness;
  options.midPlaneSymmetry = config.midPlaneSymmetry;
  options.formulation = formulation;
  return options;
}

namespace {

std::vector<int> supportedDofs(const SolidModel& solid) {
  std::vector<int> fixed = solid.symmetryConstrainedDofs();
  for (int node : solid.jointANodes()) {
    for (int c = 0; c < 3; ++c) fixed.push_back(3 * node + c);
  }
  for (int node : solid.jointBNodes()) {
    fixed.push_back(3 * node + 1);
    fixed.push_back(3 * node + 2);
  }
  return fixed;
}

}  // namespace

SolidMember::SolidMember(const RodConfig& config, ConstVectorRef design, HexFormulation formulation)
    : solid_(config, solidMeshOptions(config, formulation), design) {
  symmetryFactor_ = config.midPlaneSymmetry ? 2.0 : 1.0;
  unitStiffness_ = symmetryFactor_ * solid_.unitStiffness();
  unitMass_ = symmetryFactor_ * solid_.unitMass();
  solid_.releaseMatrices(stiffnessFull_, massFull_);
  if (symmetryFactor_ != 1.0) {  // exact in floating point
    stiffnessFull_ *= symmetryFactor_;
    massFull_ *= symmetryFactor_;
  }
  const std::vector<int> fixed = supportedDofs(solid_);
  static_cast<SupportedDofs&>(*this) = SupportedDofs(solid_.dofCount(), fixed);
  // Swapped in: assigning a returned SparseMatrix copies it in Eigen 3.4 (no move assignment), 150 MB
  // each at 51 200 elements.
  SparseMatrix freeStiffness = removeDofs(stiffnessFull_, fixed), freeMass = removeDofs(massFull_, fixed);
  stiffness_.swap(freeStiffness);
  mass_.swap(freeMass);
  stiffness_.makeCompressed();
  mass_.makeCompressed();
  const int dofs = solid_.dofCount();
  referenceCoordinates_ = solid_.referenceCoordinates();
  unitTranslationX_ = Vector::Zero(dofs);
  unitTranslationY_ = Vector::Zero(dofs);
  for (int node = 0; node < solid_.nodeCount(); ++node) {
    referenceCoordinates_(3 * node + 2) = 0.0;
    unitTranslationX_(3 * node) = 1.0;
    unitTranslationY_(3 * node + 1) = 1.0;
  }
}

std::vector<int> SolidMember::jointBAxialDofs() const {
  std::vector<int> dofs;
  for (int node : solid_.jointBNodes()) dofs.push_back(3 * node);
  return dofs;
}

}  // namespace rod
}  // namespace hindsight
