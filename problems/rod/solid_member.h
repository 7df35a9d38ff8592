// The solid as the mechanism's member (problems/rod/member.h): the hexahedral model of solid_model.h with
// the supports of the modal basis and the quantities the rotation about z sees (docs/design.md, "The
// solid member in the mechanism").
//
// Supports. The plate's pin A and roller B become axes of nodes through the thickness (the plane
// mechanism's pins are axes): u_x = u_y = 0 on every node of A's axis, u_y = 0 on every node of B's, and
// u_z = 0 on both axes: the pins' bosses hold the member along z at both ends. (u_z on A's axis alone
// would remove the translation along z, the axes already hold the rotations about x and y, but would
// leave the member a cantilever out of its plane, clamped by A's axis and free at B, with a first mode
// of 2 Hz on the default section where the in-plane one has 43 Hz.) With mid-plane symmetry, u_z = 0 on
// the mid-plane as well. The modal basis then holds the in-plane modes and, without symmetry, the
// out-of-plane ones (bending about y, torsion).
//
// Symmetry. The half model's K and M are doubled: the symmetric motions of the whole rod have twice the
// half's energies, so the eigenvalues are the half model's and the invariants (mass, J0, the modal mass)
// are those of the whole rod, as the mechanism needs. Doubling is exact in floating point.
//
// The plane of motion. referenceCoordinates() and the unit translations carry zero z components: the
// rotation of the member frame about z moves a point at X by beta S X with S's z row and column zero, so
// J0 = X^T M X, C2, a0 and Ct see only the x and y components (invariants.h). B's stretch c = b q is the
// mean u_x of B's axis (jointBAxialDofs()).
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/member.h>
#include <hindsight/problems/rod/solid_model.h>

#include <array>
#include <vector>

namespace hindsight {
namespace rod {

using HexElementVector = Eigen::Matrix<double, 24, 1>;

class SolidMember : public MemberMatrices<HexElementMatrix> {
 public:
  static constexpr int kComponents = 3;
  static constexpr int kElementDofs = 24;
  using ElementMatrixType = HexElementMatrix;
  using ElementVectorType = HexElementVector;

  /// config.elementsThroughThickness >= 1 layers, config.midPlaneSymmetry; `design` has
  /// config.designCount() entries in [designLowerBound, 1]. Throws std::invalid_argument for a plate
  /// configuration (elementsThroughThickness = 0) and as SolidModel does.
  SolidMember(const RodConfig& config, ConstVectorRef design,
              HexFormulation formulation = HexFormulation::incompatibleModes);

  /// The hexahedral model; its K and M have moved to stiffnessFull() and massFull() (scaled there).
  const SolidModel& solid() const { return solid_; }
  const RodConfig& config() const { return solid_.config(); }
  const SimpLaw& simp() const { return solid_.simp(); }
  const Vector& design() const { return solid_.design(); }
  int designCount() const { return solid_.designCount(); }
  int elementCount() const { return solid_.elementCount(); }
  int nodeCount() const { return solid_.nodeCount(); }
  int designToElement(int designIndex) const { return solid_.designToElement(designIndex); }
  int elementToDesign(int element) const { return solid_.elementToDesign(element); }
  double elementDesignValue(int element) const { return solid_.elementDesignValue(element); }
  std::array<int, 24> elementDofs(int element) const { return solid_.elementDofs(element); }

  /// 2 for the half model of mid-plane symmetry, else 1: K, M and the element matrices are the
  /// SolidModel's times this.
  double symmetryFactor() const { return symmetryFactor_; }
  // MemberMatrices holds K, M, the element matrices and the vectors; referenceCoordinates() is (x, y, 0).

  /// u_x of every node of B's axis.
  std::vector<int> jointBAxialDofs() const;

  double volumeFraction() const { return solid_.volumeFraction(); }
  Vector volumeFractionGradient() const { return solid_.volumeFractionGradient(); }

 private:
  SolidModel solid_;
  double symmetryFactor_ = 1.0;
};

/// The solid's mesh options of a configuration (elementsThroughThickness, midPlaneSymmetry).
SolidMeshOptions solidMeshOptions(const RodConfig& config,
                                  HexFormulation formulation = HexFormulation::incompatibleModes);

}  // namespace rod
}  // namespace hindsight
