// Design-dependent finite-element model of the flexible piston rod (docs/design.md §2).
//
// A rectangular nx x ny mesh of 4-node bilinear plane-stress quadrilaterals (2 x 2 Gauss points,
// consistent mass), 2 DOFs per node ordered (u_x, u_y). Node (i, j), 0 <= i <= nx, 0 <= j <= ny, sits at
// x = i L / nx, y = -H/2 + j H / ny and has index i (ny + 1) + j; its DOFs are 2 node and 2 node + 1.
// Element (i, j), 0 <= i < nx, 0 <= j < ny, has index i ny + j and local nodes (i,j), (i+1,j), (i+1,j+1),
// (i,j+1) (counter-clockwise). The first and last element columns are solid (x = 1); the inner
// (nx - 2) ny elements are the design variables, design index d = (i - 1) ny + j.
//
// Joint A is the mid-height node of the left face, pinned (u_x = u_y = 0); joint B is the mid-height
// node of the right face, on a roller (u_y = 0). "Full" quantities live on all 2 (nx+1)(ny+1) DOFs and
// are unconstrained; "free" quantities live on the remaining DOFs, in increasing full-DOF order.
//
// The material follows the SIMP law of Olhoff & Du (2005), "Topological design of continuum structures
// subjected to forced vibration", with the parameters of Held, Knüfer & Seifried (reference/, eq. 4).
//
// FeModel is immutable after construction; build a new one for every design. Units are SI.
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/member.h>
#include <hindsight/problems/rod/rod_config.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <array>
#include <vector>

namespace hindsight {
namespace rod {

using ElementMatrix = Eigen::Matrix<double, 8, 8>;
using ElementVector = Eigen::Matrix<double, 8, 1>;

/// The SIMP material interpolation (docs/design.md §2): E(x) = x^p E0; rho(x) = c x^q rho0 for x < threshold,
/// x rho0 for x >= threshold. The density law has a kink at the threshold; there the derivative is the
/// right-hand one (the linear branch). Inputs are not range-checked (FeModel checks the design).
class SimpLaw {
 public:
  explicit SimpLaw(const RodConfig& config);
  double stiffness(double x) const;            ///< E(x) [N/m^2]
  double stiffnessDerivative(double x) const;  ///< dE/dx
  double density(double x) const;              ///< rho(x) [kg/m^3]
  double densityDerivative(double x) const;    ///< drho/dx

 private:
  double youngsModulus_, density_, penalty_, factor_, exponent_, threshold_;
};

/// Stiffness matrix of one rectangular plane-stress Q4 element with E = 1 (2 x 2 Gauss, exact for a
/// rectangle), DOFs ordered (u_x, u_y) for the local nodes (0,0), (a,0), (a,b), (0,b). Units: m (thickness).
ElementMatrix planeStressQuadUnitStiffness(double width, double height, double poissonRatio,
                                           double thickness);
/// Consistent mass matrix of the same element with rho = 1 (2 x 2 Gauss, exact). Units: m^3.
ElementMatrix quadUnitConsistentMass(double width, double height, double thickness);

/// Applies S = [[0, -1], [1, 0]] to every node's (u_x, u_y) pair of a full DOF vector (rotation by +90 deg).
/// With components = 3 (the solid's (u_x, u_y, u_z)), S = [[0, -1, 0], [1, 0, 0], [0, 0, 0]]: the
/// derivative of a rotation about z, which sees neither u_z nor moves anything along z (docs/design.md,
/// "The solid member in the mechanism").
Vector rotateNodewise(ConstVectorRef full, int components = 2);
/// Applies S^T node-wise.
Vector rotateNodewiseTransposed(ConstVectorRef full, int components = 2);
/// Column-wise versions of the two above.
Matrix rotateNodewiseColumns(ConstMatrixRef full, int components = 2);
Matrix rotateNodewiseTransposedColumns(ConstMatrixRef full, int components = 2);

/// Throws std::invalid_argument naming `who`, the entry and the range when a design variable is not in
/// [designLowerBound, 1] or not finite: the one check of every member model's design (plate and solid).
void requireDesignInRange(const char* who, ConstVectorRef design, double designLowerBound);

/// The design bookkeeping of the plate (FeModel) and the solid (SolidModel): the configuration, its SIMP
/// law, the design and the maps between design variables and elements. Both meshes number element
/// (i, j, k) (i ny + j) nz + k, the plate with nz = 1, and make the elements of the inner columns
/// 1 <= i <= nx - 2 the design variables in that order: d = ((i - 1) ny + j) nz + k.
class DesignedMesh {
 public:
  const RodConfig& config() const { return config_; }
  const SimpLaw& simp() const { return simp_; }
  const Vector& design() const { return design_; }

  int elementCount() const { return elementCount_; }
  int designCount() const { return static_cast<int>(design_.size()); }
  /// Element index of design variable d, and design index of an element (-1 for the solid end columns).
  int designToElement(int designIndex) const {
    return designToElement_[static_cast<std::size_t>(designIndex)];
  }
  int elementToDesign(int element) const { return elementToDesign_[static_cast<std::size_t>(element)]; }
  /// Design value of an element (1 for the solid end columns).
  double elementDesignValue(int element) const;

  /// V(x)/V0 over all elements (the solid end columns count with x = 1; all elements have equal size),
  /// and its gradient (constant 1 / elementCount).
  double volumeFraction() const;
  Vector volumeFractionGradient() const;

 protected:
  explicit DesignedMesh(const RodConfig& config) : config_(config), simp_(config) {}
  /// Takes `design`, already checked, and numbers the nx ny layers elements as above.
  void placeDesign(ConstVectorRef design, int layers);

  RodConfig config_;
  SimpLaw simp_;
  Vector design_;
  int elementCount_ = 0;
  std::vector<int> designToElement_, elementToDesign_;
};

/// The plate member (problems/rod/member.h); its free-DOF map is the pinned (A) / roller (B) support's.
class FeModel : public DesignedMesh, public MemberMatrices<ElementMatrix> {
 public:
  static constexpr int kComponents = 2;
  static constexpr int kElementDofs = 8;
  using ElementMatrixType = ElementMatrix;
  using ElementVectorType = ElementVector;

  /// Builds mesh, element matrices and the assembled sparse K, M (full and constrained) for `design`.
  /// `design` has config.designCount() entries in [designLowerBound, 1].
  /// Throws std::invalid_argument for an invalid config (RodConfig::validate) or a design of wrong size,
  /// non-finite entries or entries outside [designLowerBound, 1] (naming the index and the value).
  FeModel(const RodConfig& config, ConstVectorRef design);

  int nodeCount() const { return nodeCount_; }

  int nodeIndex(int i, int j) const { return i * (config_.elementsThroughHeight + 1) + j; }
  /// Full DOF indices of an element, local node order as documented at the top of the file.
  std::array<int, 8> elementDofs(int element) const;

  int jointANode() const;
  int jointBNode() const;
  /// Full DOF of u_x at B, and its free-DOF index (u_x at B is free: roller).
  int jointBAxialDof() const { return 2 * jointBNode(); }
  int jointBAxialFreeDof() const { return fullToFree()[jointBAxialDof()]; }
  /// The member interface's B (member.h): the one node's u_x.
  std::vector<int> jointBAxialDofs() const { return {jointBAxialDof()}; }

 private:
  void assemble();

  int nodeCount_ = 0;
};

}  // namespace rod
}  // namespace hindsight
