// The flexible member of the mechanism: what the modal reduction (modal_reduction.h), the inertia
// invariants (invariants.h), the chain to the design (design_gradient.h), the frequency guard
// (eigen_constraint.h) and psi2 (esl.h) ask of a finite-element model, so that none of them, and nothing
// after them, knows whether the member is the plate or the solid (docs/design.md, "The member
// interface"). Two models provide it:
//   FeModel      the plate: plane-stress Q4, 2 DOFs per node (fe_model.h)
//   SolidMember  the solid: hexahedra, 3 DOFs per node (solid_member.h)
// The interface is static (the functions above are templates instantiated for both, declared for both
// in their headers): the element loops work on fixed-size element matrices (8 x 8, 24 x 24), which a
// virtual call per element would turn into dynamic ones, slower and with other bits for the plate.
// The mechanism itself (problems/mechanism/mechanism_problem.h) sees only the invariants p.
//
// A member model M provides:
//   M::kComponents (2 or 3), M::kElementDofs (8 or 24), M::ElementMatrixType, M::ElementVectorType
//   config(), simp(), design(), designCount(), designToElement(d), elementCount(), elementDesignValue(e)
//   elementDofs(e) -> std::array<int, kElementDofs>, unitStiffness(), unitMass() (E = 1, rho = 1)
//   stiffnessFull(), massFull() (all DOFs), stiffness(), mass() (the free DOFs of its supports)
//   the free-DOF map of SupportedDofs below (dofCount(), freeDofCount(), restrict/extend)
//   (MemberMatrices below stores the matrices, vectors and the free-DOF map for both models)
//   referenceCoordinates(), unitTranslationX(), unitTranslationY(): full vectors of the positions and
//     translations in the plane of motion (a solid's z components are zero: the rotation about z does
//     not see them)
//   jointBAxialDofs(): the u_x DOFs of B whose mean is the chord's stretch c (one node of the plate, the
//     axis of nodes through the solid's thickness)
//   volumeFraction(), volumeFractionGradient()
#pragma once

#include <hindsight/engine/types.h>

#include <Eigen/SparseCore>

#include <vector>

namespace hindsight {
namespace rod {

using SparseMatrix = Eigen::SparseMatrix<double>;

/// The DOFs of a supported member: which are free (not held at zero by a support) and the maps between
/// vectors on all DOFs ("full") and on the free DOFs, in increasing full-DOF order.
class SupportedDofs {
 public:
  SupportedDofs() = default;
  /// constrained: the supported DOFs, in any order, repeats allowed; each in [0, dofCount).
  SupportedDofs(int dofCount, const std::vector<int>& constrained);

  int dofCount() const { return static_cast<int>(fullToFree_.size()); }
  int freeDofCount() const { return static_cast<int>(freeToFull_.size()); }
  /// freeToFull()[k] is the full DOF of free DOF k; fullToFree()[d] is -1 for constrained DOFs.
  const std::vector<int>& freeToFull() const { return freeToFull_; }
  const std::vector<int>& fullToFree() const { return fullToFree_; }
  Vector restrictToFree(ConstVectorRef full) const;
  Matrix restrictColumnsToFree(ConstMatrixRef full) const;
  /// Extends free-DOF vectors/matrices by zeros at the constrained DOFs.
  Vector extendToFull(ConstVectorRef free) const;
  Matrix extendColumnsToFull(ConstMatrixRef free) const;

 private:
  std::vector<int> freeToFull_, fullToFree_;
};

/// What both member models store of the interface above, filled in by their constructors: the free-DOF
/// map, the unit element matrices, K and M on all DOFs and on the free DOFs, and the vectors of the plane
/// of motion. ElementMatrixType is the model's fixed-size element matrix (8 x 8 or 24 x 24).
template <typename ElementMatrixType>
class MemberMatrices : public SupportedDofs {
 public:
  /// Ke0 (E = 1) and Me0 (rho = 1): every element of the mesh is the same rectangle or box.
  const ElementMatrixType& unitStiffness() const { return unitStiffness_; }
  const ElementMatrixType& unitMass() const { return unitMass_; }
  /// K [N/m] and M [kg] on all DOFs, unconstrained.
  const SparseMatrix& stiffnessFull() const { return stiffnessFull_; }
  const SparseMatrix& massFull() const { return massFull_; }
  /// K and M restricted to the free DOFs of the supports.
  const SparseMatrix& stiffness() const { return stiffness_; }
  const SparseMatrix& mass() const { return mass_; }
  /// Nodal reference coordinates X [m] and the unit translations e_x, e_y as full DOF vectors (in the
  /// plane of motion: a solid's z components are zero).
  const Vector& referenceCoordinates() const { return referenceCoordinates_; }
  const Vector& unitTranslationX() const { return unitTranslationX_; }
  const Vector& unitTranslationY() const { return unitTranslationY_; }

 protected:
  ElementMatrixType unitStiffness_, unitMass_;
  SparseMatrix stiffnessFull_, massFull_, stiffness_, mass_;
  Vector referenceCoordinates_, unitTranslationX_, unitTranslationY_;
};

}  // namespace rod
}  // namespace hindsight
