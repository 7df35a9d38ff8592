// Design-dependent finite-element model of the connecting rod as a 3-D solid (docs/design.md, "The solid
// member"): K and M of a design and their element-wise design derivatives. The mechanism's member is
// SolidMember (solid_member.h), which adds the supports of the modal basis; the plate is fe_model.h.
//
// A structured box mesh of nx x ny x nz 8-node hexahedra over [0, L] x [-H/2, H/2] x [-t/2, t/2], or over
// [0, L] x [-H/2, H/2] x [0, t/2] with mid-plane symmetry, 3 DOFs per node ordered (u_x, u_y, u_z).
// Node (i, j, k), 0 <= i <= nx, 0 <= j <= ny, 0 <= k <= nz, has index (i (ny + 1) + j) (nz + 1) + k and
// DOFs 3 node + c. Element (i, j, k) has index (i ny + j) nz + k and the local nodes
//   (i,j,k), (i+1,j,k), (i+1,j+1,k), (i,j+1,k), then the same four at k + 1,
// the plate's counter-clockwise order on the bottom face, repeated on the top face. The first and last
// element columns are solid (x = 1), as on the plate; the inner (nx - 2) ny nz elements are the design
// variables, design index d = ((i - 1) ny + j) nz + k.
//
// Element: trilinear hexahedron with the incompatible modes of Wilson, Taylor, Doherty & Ghaboussi
// (1973), "Incompatible displacement models", in Numerical and Computer Methods in Structural Mechanics,
// Academic Press, 43-57, condensed statically per element; Taylor, Beresford & Wilson (1976), "A
// non-conforming element for stress analysis", Int. J. Numer. Meth. Engng 10, 1211-1219, evaluate the
// incompatible modes' derivatives with the Jacobian at the element centre so that any hexahedron passes
// the patch test. On this mesh every element is a rectangular box, whose Jacobian is constant, so the two
// coincide. The plain trilinear element (HexFormulation::trilinear) locks in bending on slender elements;
// it is kept because with nz = 1 and nu = 0 it is exactly the plate's Q4 element times the thickness
// (tests/problems/rod/solid_model_test.cpp). The consistent mass uses the trilinear shape functions only:
// the incompatible modes are internal strain enhancements, not kinematic DOFs, and carry no mass.
//
// Mid-plane symmetry models the half z >= 0 with u_z = 0 on z = 0 (symmetryConstrainedDofs()): half the
// unknowns, and only the motions symmetric about the mid-plane survive, the in-plane bending and axial
// modes among them. The motions antisymmetric about the mid-plane are removed: the out-of-plane bending
// and the torsion modes. That is a modelling choice, not an approximation: a rod whose modal basis lacks
// out-of-plane bending cannot see a load that excites it, nor lose stiffness in it, so an optimised
// section judged by the symmetric model alone may be thin out of plane (docs/design.md).
//
// The material is the plate's SIMP law (SimpLaw, RodConfig: E0, rho0, nu, p, c, q) in 3-D isotropic
// elasticity. SolidModel is immutable after construction; build a new one for every design. Units are SI.
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/rod_config.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <array>
#include <utility>
#include <vector>

namespace hindsight {
namespace rod {

using HexElementMatrix = Eigen::Matrix<double, 24, 24>;

/// The hexahedron's stiffness formulation.
enum class HexFormulation {
  trilinear,          ///< plain 8-node trilinear, 2 x 2 x 2 Gauss: locks in bending on slender elements
  incompatibleModes,  ///< Wilson-Taylor incompatible modes, condensed per element (the default)
};

/// The third dimension of the solid member; the rest (L, H, t, nx, ny, the material) is the RodConfig.
struct SolidMeshOptions {
  /// nz, element layers over the modelled thickness: the whole of t, or the half t/2 with symmetry. >= 1.
  int elementsThroughThickness = 1;
  /// Model the half z >= 0 with u_z = 0 on the mid-plane (see the top of the file for what it removes).
  bool midPlaneSymmetry = false;
  HexFormulation formulation = HexFormulation::incompatibleModes;

  /// Throws std::invalid_argument naming the field, its value and the allowed range.
  void validate() const;
};

/// Stiffness of one rectangular box element of widths a x b x c [m] with E = 1 and Poisson ratio nu
/// (2 x 2 x 2 Gauss, exact for a box), DOFs ordered (u_x, u_y, u_z) per local node as documented above.
/// Units: m (stiffness per unit Young's modulus). Throws std::invalid_argument for a non-positive width or
/// nu outside (-1, 0.5).
HexElementMatrix hexUnitStiffness(double widthX, double widthY, double widthZ, double poissonRatio,
                                  HexFormulation formulation);
/// Consistent mass of the same element with rho = 1 (2 x 2 x 2 Gauss, exact). Units: m^3.
HexElementMatrix hexUnitConsistentMass(double widthX, double widthY, double widthZ);

class SolidModel : public DesignedMesh {
 public:
  /// Builds the mesh and the assembled sparse K, M on all DOFs for `design`, which has designCount()
  /// entries in [designLowerBound, 1]. The plate's rules apply to config (RodConfig::validate: nx >= 3,
  /// ny even) and to the design. Throws std::invalid_argument for an invalid config or options, or a
  /// design of wrong size, non-finite entries or entries outside [designLowerBound, 1] (naming the index).
  SolidModel(const RodConfig& config, const SolidMeshOptions& options, ConstVectorRef design);

  const SolidMeshOptions& options() const { return options_; }

  int elementsAlongLength() const { return config_.elementsAlongLength; }
  int elementsThroughHeight() const { return config_.elementsThroughHeight; }
  int elementsThroughThickness() const { return options_.elementsThroughThickness; }
  int nodeCount() const { return nodeCount_; }
  int dofCount() const { return 3 * nodeCount_; }
  /// Designs of the solid: (nx - 2) ny nz.
  static int designCountOf(const RodConfig& config, const SolidMeshOptions& options);

  int nodeIndex(int i, int j, int k) const {
    return (i * (config_.elementsThroughHeight + 1) + j) * (options_.elementsThroughThickness + 1) + k;
  }
  int elementIndex(int i, int j, int k) const {
    return (i * config_.elementsThroughHeight + j) * options_.elementsThroughThickness + k;
  }
  /// Full DOF indices of an element, local node order as documented at the top of the file.
  std::array<int, 24> elementDofs(int element) const;

  /// Element widths [m]: L / nx, H / ny, and t / nz (t / (2 nz) with mid-plane symmetry).
  double elementWidthX() const;
  double elementWidthY() const;
  double elementWidthZ() const;

  /// Ke0 (E = 1) and Me0 (rho = 1): every element is the same box.
  const HexElementMatrix& unitStiffness() const { return unitStiffness_; }
  const HexElementMatrix& unitMass() const { return unitMass_; }

  /// K [N/m] and M [kg] on all DOFs, unconstrained (with symmetry: of the half model). Empty after
  /// releaseMatrices().
  const SparseMatrix& stiffness() const { return stiffness_; }
  const SparseMatrix& mass() const { return mass_; }
  /// Moves K and M into `stiffness` and `mass`, leaving this model's empty: the member keeps them scaled
  /// by its symmetry factor, and a second copy of each is 150 MB at 51 200 elements.
  /// (By swap: Eigen 3.4's SparseMatrix has no move assignment, and std::move would copy.)
  void releaseMatrices(SparseMatrix& stiffness, SparseMatrix& mass) {
    stiffness.swap(stiffness_);
    mass.swap(mass_);
    stiffness_ = SparseMatrix();
    mass_ = SparseMatrix();
  }

  /// dK/dx_d = E'(x) Ke0 and dM/dx_d = rho'(x) Me0 of design variable d on the element's DOFs
  /// (elementDofs(designToElement(d))); every other entry of the derivative is zero.
  HexElementMatrix stiffnessDerivative(int designIndex) const;
  HexElementMatrix massDerivative(int designIndex) const;

  /// Nodal reference coordinates X as a full DOF vector [m].
  const Vector& referenceCoordinates() const { return referenceCoordinates_; }

  /// u_z of every node on z = 0 with mid-plane symmetry (ascending), empty without it.
  const std::vector<int>& symmetryConstrainedDofs() const { return symmetryConstrainedDofs_; }
  /// The nodes of the joint axes through the thickness at mid-height of the end faces, (0, 0, z) for A
  /// and (L, 0, z) for B, for every z of the mesh, ascending in z. The plane mechanism's pin is an axis.
  std::vector<int> jointANodes() const;
  std::vector<int> jointBNodes() const;

 private:
  void assemble();

  SolidMeshOptions options_;
  int nodeCount_ = 0;
  HexElementMatrix unitStiffness_, unitMass_;
  SparseMatrix stiffness_, mass_;
  Vector referenceCoordinates_;
  std::vector<int> symmetryConstrainedDofs_;
};

/// A square matrix with the rows and columns of `fixedDofs` removed (a support u = 0 on those DOFs).
/// fixedDofs need not be sorted and may repeat; throws std::invalid_argument for an index out of range.
SparseMatrix removeDofs(const SparseMatrix& matrix, const std::vector<int>& fixedDofs);

/// The `count` smallest eigenvalues lambda of K v = lambda M v, ascending, by Spectra's shift-and-invert
/// Lanczos about `shift` with a sparse LDL^T of K - shift M (shift < 0 for a model with rigid motions,
/// which K - shift M then no longer has). K, M symmetric, M positive definite. Throws
/// std::invalid_argument for bad sizes or count outside [1, n - 1], std::runtime_error when the
/// factorisation or Spectra fails (with its status).
Vector lowestEigenvalues(const SparseMatrix& stiffness, const SparseMatrix& mass, int count, double shift);

}  // namespace rod
}  // namespace hindsight
