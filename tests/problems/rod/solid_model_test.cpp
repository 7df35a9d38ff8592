// The solid member's hexahedral model (problems/rod/solid_model.h) against exact answers: rigid motions
// and the patch test, Timoshenko beam frequencies in and out of the plane, the absence of bending
// locking, and the plate's Q4 model on the same mesh.
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/solid_model.h>

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace hindsight {
namespace rod {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The rod of docs/design.md §2 with nu = 0 (so that a 3-D solid and a Timoshenko beam, and the plane-
// stress plate, describe the same material: no Poisson coupling through the section or at a clamp).
RodConfig rodConfig(int nx, int ny, double poissonRatio = 0.0) {
  RodConfig config;
  config.elementsAlongLength = nx;
  config.elementsThroughHeight = ny;
  config.poissonRatio = poissonRatio;
  return config;
}

SolidModel solidRod(int nx, int ny, int nz, bool symmetric, HexFormulation formulation, double nu = 0.0,
                    double design = 1.0) {
  const RodConfig config = rodConfig(nx, ny, nu);
  SolidMeshOptions options;
  options.elementsThroughThickness = nz;
  options.midPlaneSymmetry = symmetric;
  options.formulation = formulation;
  return SolidModel(config, options, Vector::Constant(SolidModel::designCountOf(config, options), design));
}

std::vector<int> clampedFace(const SolidModel& model) {
  std::vector<int> dofs;
  for (int j = 0; j <= model.elementsThroughHeight(); ++j)
    for (int k = 0; k <= model.elementsThroughThickness(); ++k)
      for (int c = 0; c < 3; ++c) dofs.push_back(3 * model.nodeIndex(0, j, k) + c);
  for (int d : model.symmetryConstrainedDofs()) dofs.push_back(d);
  return dofs;
}

double frequencyOf(double eigenvalue) { return std::sqrt(std::max(eigenvalue, 0.0)) / (2.0 * kPi); }

// The Timoshenko beam's first bending frequency [Hz] for clamped-free or free-free ends, from the exact
// characteristic equation: with w the deflection and psi the section rotation,
//   kGA (w'' - psi') + rho A w^2 w = 0,  EI psi'' + kGA (w' - psi) + rho I w^2 psi = 0,
// solutions e^{s x} with EI kGA s^4 + w^2 (EI rho A + rho I kGA) s^2 + rho A w^2 (rho I w^2 - kGA) = 0
// (Huang 1961, J. Appl. Mech. 28, 579-584; Han, Benaroya & Wei 1999, J. Sound Vib. 225, 935-988, eqs.
// 64-70). Below the cut-off rho I w^2 < kGA the roots are +-alpha, +-i beta, and the four real solutions
//   (cosh ax, r sinh ax), (sinh ax, r cosh ax), (cos bx, q sin bx), (sin bx, -q cos bx)  for (w, psi),
// r = (kGA a^2 + rho A w^2) / (kGA a), q = (rho A w^2 - kGA b^2) / (kGA b), must meet the end conditions:
// clamped w = psi = 0, free shear kGA (w' - psi) = 0 and moment EI psi' = 0. The frequency is the first
// sign change of their 4 x 4 determinant above the Euler-Bernoulli estimate's lower neighbourhood.
struct BeamSection {
  double youngsModulus, shearModulus, shearCoefficient, density, area, secondMoment, length;
};

double timoshenkoDeterminant(const BeamSection& beam, double omega, bool clamped) {
  const double kGA = beam.shearCoefficient * beam.shearModulus * beam.area;
  const double EI = beam.youngsModulus * beam.secondMoment;
  const double rhoA = beam.density * beam.area, rhoI = beam.density * beam.secondMoment;
  const double w2 = omega * omega;
  const double a4 = EI * kGA, a2 = w2 * (EI * rhoA + rhoI * kGA), a0 = rhoA * w2 * (rhoI * w2 - kGA);
  const double root = std::sqrt(a2 * a2 - 4.0 * a4 * a0);
  const double alpha = std::sqrt((-a2 + root) / (2.0 * a4));
  const double beta = std::sqrt((a2 + root) / (2.0 * a4));
  const double r = (kGA * alpha * alpha + rhoA * w2) / (kGA * alpha);
  const double q = (rhoA * w2 - kGA * beta * beta) / (kGA * beta);
  // Rows of (w, psi, w' - psi, psi') for the four solutions at x.
  auto rows = [&](double x) {
    Eigen::Matrix4d m;
    const double ch = std::cosh(alpha * x), sh = std::sinh(alpha * x);
    const double c = std::cos(beta * x), s = std::sin(beta * x);
    m.col(0) << ch, r * sh, alpha * sh - r * sh, r * alpha * ch;
    m.col(1) << sh, r * ch, alpha * ch - r * ch, r * alpha * sh;
    m.col(2) << c, q * s, -beta * s - q * s, q * beta * c;
    m.col(3) << s, -q * c, beta * c + q * c, q * beta * s;
    return m;
  };
  const Eigen::Matrix4d left = rows(0.0), right = rows(beam.length);
  Eigen::Matrix4d conditions;
  conditions.row(0) = clamped ? left.row(0) : left.row(2);
  conditions.row(1) = clamped ? left.row(1) : left.row(3);
  conditions.row(2) = right.row(2);
  conditions.row(3) = right.row(3);
  return conditions.determinant();
}

double timoshenkoFirstFrequency(const BeamSection& beam, bool clamped) {
  // Euler-Bernoulli: (beta L)^2 with beta L = 1.8751 (clamped-free) or 4.7300 (free-free).
  const double betaL = clamped ? 1.87510407 : 4.73004074;
  const double eulerBernoulli =
      betaL * betaL / (beam.length * beam.length) *
      std::sqrt(beam.youngsModulus * beam.secondMoment / (beam.density * beam.area));
  // Shear and rotary inertia lower the frequency; for these slender beams by less than 5 %.
  double low = 0.8 * eulerBernoulli, high = low;
  const double step = 0.001 * eulerBernoulli;
  double valueLow = timoshenkoDeterminant(beam, low, clamped);
  for (high = low + step; high <= 1.0001 * eulerBernoulli; high += step) {
    const double valueHigh = timoshenkoDeterminant(beam, high, clamped);
    if ((valueLow < 0.0) != (valueHigh < 0.0)) break;
    low = high;
    valueLow = valueHigh;
  }
  EXPECT_LE(high, 1.0001 * eulerBernoulli) << "no root of the Timoshenko determinant found";
  for (int iteration = 0; iteration < 100; ++iteration) {
    const double middle = 0.5 * (low + high);
    const double value = timoshenkoDeterminant(beam, middle, clamped);
    if ((value < 0.0) == (valueLow < 0.0)) {
      low = middle;
      valueLow = value;
    } else {
      high = middle;
    }
  }
  return 0.5 * (low + high) / (2.0 * kPi);
}

// The rod's section bent in the plane (about z: depth H) or out of it (about y: depth t), nu = 0, with
// Cowper's (1966) shear coefficient of a rectangle 10 (1 + nu) / (12 + 11 nu) = 5/6.
BeamSection rodSection(bool inPlane) {
  const RodConfig config;
  BeamSection beam{};
  beam.youngsModulus = config.youngsModulus;
  beam.shearModulus = 0.5 * config.youngsModulus;
  beam.shearCoefficient = 5.0 / 6.0;
  beam.density = config.density;
  beam.area = config.height * config.thickness;
  const double depth = inPlane ? config.height : config.thickness;
  beam.secondMoment = beam.area * depth * depth / 12.0;
  beam.length = config.length;
  return beam;
}

// The first bending frequency of the solid rod: with mid-plane symmetry only the in-plane family is
// left, whose lowest non-rigid mode is in-plane bending (the axial and torsion modes lie far above or are
// removed); without it the lowest non-rigid mode of this thin rod (t = H / 6) is out-of-plane bending.
double solidFirstBending(const SolidModel& model, bool clamped) {
  std::vector<int> fixed = clamped ? clampedFace(model) : model.symmetryConstrainedDofs();
  const SparseMatrix stiffness = removeDofs(model.stiffness(), fixed);
  const SparseMatrix mass = removeDofs(model.mass(), fixed);
  const int rigid = clamped ? 0 : (model.options().midPlaneSymmetry ? 3 : 6);
  const Vector values = lowestEigenvalues(stiffness, mass, rigid + 1, -1.0);
  return frequencyOf(values(rigid));
}

TEST(HexElement, HasExactlySixRigidModesInBothFormulations) {
  for (HexFormulation formulation : {HexFormulation::trilinear, HexFormulation::incompatibleModes}) {
    const HexElementMatrix stiffness = hexUnitStiffness(0.01, 0.005, 0.002, 0.3, formulation);
    const Eigen::SelfAdjointEigenSolver<HexElementMatrix> eigen(stiffness);
    const Eigen::VectorXd values = eigen.eigenvalues();
    const double scale = values.maxCoeff();
    for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(values(i)), 1e-12 * scale) << i;
    // The trilinear element has 12 hourglass-free deformation modes beyond the 6 rigid ones; all 18 are
    // stiff (full integration), so the 7th eigenvalue is clearly positive.
    EXPECT_GT(values(6), 1e-6 * scale);
  }
}

TEST(HexElement, MassCarriesTheElementMassOncePerDirection) {
  const double a = 0.01, b = 0.005, c = 0.002;
  const HexElementMatrix mass = hexUnitConsistentMass(a, b, c);
  for (int direction = 0; direction < 3; ++direction) {
    Eigen::Matrix<double, 24, 1> unit = Eigen::Matrix<double, 24, 1>::Zero();
    for (int node = 0; node < 8; ++node) unit(3 * node + direction) = 1.0;
    EXPECT_NEAR(unit.dot(mass * unit), a * b * c, 1e-20);
  }
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<HexElementMatrix>(mass).eigenvalues().minCoeff(), 0.0);
}

TEST(HexElement, RejectsBadWidthsAndPoissonRatio) {
  EXPECT_THROW(hexUnitStiffness(0.0, 1.0, 1.0, 0.3, HexFormulation::incompatibleModes),
               std::invalid_argument);
  EXPECT_THROW(hexUnitStiffness(1.0, -1.0, 1.0, 0.3, HexFormulation::trilinear), std::invalid_argument);
  EXPECT_THROW(hexUnitStiffness(1.0, 1.0, 1.0, 0.5, HexFormulation::trilinear), std::invalid_argument);
  EXPECT_THROW(hexUnitConsistentMass(1.0, 1.0, std::nan("")), std::invalid_argument);
}

TEST(SolidModel, RejectsBadOptionsAndDesigns) {
  const RodConfig config = rodConfig(6, 2);
  SolidMeshOptions options;
  options.elementsThroughThickness = 0;
  EXPECT_THROW(SolidModel(config, options, Vector::Constant(8, 0.5)), std::invalid_argument);
  options.elementsThroughThickness = 2;
  EXPECT_THROW(SolidModel(config, options, Vector::Constant(15, 0.5)), std::invalid_argument);  // 16 expected
  Vector design = Vector::Constant(16, 0.5);
  design(3) = 0.0;  // below designLowerBound
  try {
    SolidModel model(config, options, design);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("design[3]"), std::string::npos) << error.what();
  }
}

TEST(SolidModel, FreeFreeHasExactlySixZeroEigenvaluesForAnyDesign) {
  const RodConfig config = rodConfig(5, 2, 0.3);
  SolidMeshOptions options;
  options.elementsThroughThickness = 2;
  Vector design(SolidModel::designCountOf(config, options));
  for (Eigen::Index d = 0; d < design.size(); ++d) design(d) = 0.05 + 0.9 * std::fmod(0.37 * d, 1.0);
  for (HexFormulation formulation : {HexFormulation::trilinear, HexFormulation::incompatibleModes}) {
    options.formulation = formulation;
    const SolidModel model(config, options, design);
    const Eigen::MatrixXd stiffness(model.stiffness()), mass(model.mass());
    const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eigen(stiffness, mass);
    const Eigen::VectorXd values = eigen.eigenvalues();
    // The rigid eigenvalues are round-off of the largest; the first deformation mode is far above it.
    const double scale = values.maxCoeff();
    for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(values(i)), 1e-11 * scale) << i;
    EXPECT_GT(values(6), 1e6 * std::abs(values(5)));
  }
}

// The assembly written column by column on the box mesh's pattern against the plain element loop it
// replaced (coeffRef into every pair of an element's DOFs, elements in increasing order): the same
// pattern and the same bits, for a varied design, with and without symmetry, on meshes whose every axis
// has one element or more.
TEST(SolidModel, AssemblyIsTheElementLoopBitForBit) {
  struct Mesh {
    int nx, ny, nz;
    bool symmetric;
  };
  for (const Mesh mesh : {Mesh{3, 2, 1, false}, Mesh{5, 2, 3, true}, Mesh{4, 4, 2, false}}) {
    const RodConfig config = rodConfig(mesh.nx, mesh.ny, 0.3);
    SolidMeshOptions options;
    options.elementsThroughThickness = mesh.nz;
    options.midPlaneSymmetry = mesh.symmetric;
    Vector design(SolidModel::designCountOf(config, options));
    for (Eigen::Index d = 0; d < design.size(); ++d) design(d) = 0.05 + 0.9 * std::fmod(0.61 * d, 1.0);
    const SolidModel model(config, options, design);
    const int dofs = model.dofCount();
    SparseMatrix stiffness(dofs, dofs), mass(dofs, dofs);
    for (int e = 0; e < model.elementCount(); ++e) {
      const double x = model.elementDesignValue(e);
      const std::array<int, 24> elementDofs = model.elementDofs(e);
      for (int b = 0; b < 24; ++b) {
        for (int a = 0; a < 24; ++a) {
          const int row = elementDofs[static_cast<std::size_t>(a)];
          const int column = elementDofs[static_cast<std::size_t>(b)];
          stiffness.coeffRef(row, column) += model.simp().stiffness(x) * model.unitStiffness()(a, b);
          mass.coeffRef(row, column) += model.simp().density(x) * model.unitMass()(a, b);
        }
      }
    }
    stiffness.makeCompressed();
    mass.makeCompressed();
    for (const auto& [assembled, reference] :
         {std::pair{&model.stiffness(), &stiffness}, std::pair{&model.mass(), &mass}}) {
      ASSERT_EQ(assembled->nonZeros(), reference->nonZeros());
      ASSERT_TRUE(std::equal(reference->outerIndexPtr(), reference->outerIndexPtr() + dofs + 1,
                             assembled->outerIndexPtr()));
      ASSERT_TRUE(std::equal(reference->innerIndexPtr(), reference->innerIndexPtr() + reference->nonZeros(),
                             assembled->innerIndexPtr()));
      for (Eigen::Index i = 0; i < reference->nonZeros(); ++i)
        ASSERT_EQ(assembled->valuePtr()[i], reference->valuePtr()[i]) << "entry " << i;
    }
  }
}

// removeDofs keeps the other rows and columns in order with their values, the explicit zeros included.
TEST(SolidModel, RemoveDofsKeepsTheRestInOrder) {
  Eigen::MatrixXd dense(5, 5);
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) dense(i, j) = (i + j) % 3 == 0 ? 0.0 : 1.0 + i + 10.0 * j;
  SparseMatrix matrix = dense.sparseView();
  matrix.coeffRef(4, 4) = 0.0;  // an explicit zero survives
  matrix.makeCompressed();
  const SparseMatrix reduced = removeDofs(matrix, {3, 1, 3});
  const std::vector<int> kept = {0, 2, 4};
  ASSERT_EQ(reduced.rows(), 3);
  ASSERT_TRUE(reduced.isCompressed());
  Eigen::Index expectedNonZeros = 0;
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) {
      const auto source = static_cast<std::size_t>(r), target = static_cast<std::size_t>(c);
      EXPECT_EQ(Eigen::MatrixXd(reduced)(r, c), Eigen::MatrixXd(matrix)(kept[source], kept[target]));
    }
    for (SparseMatrix::InnerIterator it(matrix, kept[static_cast<std::size_t>(c)]); it; ++it)
      expectedNonZeros += (it.row() == 1 || it.row() == 3) ? 0 : 1;
  }
  EXPECT_EQ(reduced.nonZeros(), expectedNonZeros);
  EXPECT_THROW(removeDofs(matrix, {5}), std::invalid_argument);
}

// A linear displacement field u = A X + c is reproduced exactly by the element, so a uniform body under it
// is in equilibrium at every interior node: the patch test (Taylor et al. 1976), which the incompatible
// modes pass on boxes. The design is 1 everywhere: the solid end columns would otherwise be a material
// jump, at which a uniform strain is not in equilibrium.
TEST(SolidModel, PassesThePatchTest) {
  for (HexFormulation formulation : {HexFormulation::trilinear, HexFormulation::incompatibleModes}) {
    const SolidModel model = solidRod(5, 4, 3, false, formulation, 0.3, 1.0);
    Eigen::Matrix3d gradient;
    gradient << 1e-3, 2e-4, -3e-4, 5e-4, -2e-3, 1e-4, -4e-4, 3e-4, 1.5e-3;
    Vector displacement(model.dofCount());
    const Vector& X = model.referenceCoordinates();
    for (int node = 0; node < model.nodeCount(); ++node)
      displacement.segment<3>(3 * node) = gradient * X.segment<3>(3 * node) + Eigen::Vector3d(1e-3, 0, -2e-3);
    const Vector force = model.stiffness() * displacement;
    double interior = 0.0, boundary = 0.0;
    for (int i = 0; i <= 5; ++i)
      for (int j = 0; j <= 4; ++j)
        for (int k = 0; k <= 3; ++k) {
          const double size = force.segment<3>(3 * model.nodeIndex(i, j, k)).norm();
          const bool inside = i > 0 && i < 5 && j > 0 && j < 4 && k > 0 && k < 3;
          if (inside) {
            interior = std::max(interior, size);
          } else {
            boundary = std::max(boundary, size);
          }
        }
    EXPECT_GT(boundary, 0.0);
    EXPECT_LT(interior, 1e-12 * boundary);
  }
}

// Discretisation error of the first bending frequency against the Timoshenko beam, each mesh halving the
// element length. The incompatible-mode hexahedron is exact in pure bending of a box, so what is left is
// the consistent mass's O(h^2) error: the error must fall by at least 3 per refinement (4 for second
// order; measured 3.6-4.0) and end below `finalTolerance`. With nu = 0 the 3-D solid and the beam differ
// only by Cowper's k = 5/6 and the clamp, below 1e-4 here (the measured errors keep falling like h^2 to
// 2e-5), so the tolerance bounds the mesh's error, not the beam theory's.
void expectConvergence(const std::vector<double>& solid, double reference, double finalTolerance) {
  std::vector<double> errors;
  for (double f : solid) errors.push_back(std::abs(f - reference) / reference);
  for (std::size_t m = 0; m < errors.size(); ++m) {
    ::testing::Test::RecordProperty("relative_error_" + std::to_string(m), std::to_string(errors[m]));
    if (m > 0) EXPECT_GT(errors[m - 1], 3.0 * errors[m]) << "refinement " << m;
  }
  EXPECT_LT(errors.back(), finalTolerance)
      << "solid " << solid.back() << " Hz, Timoshenko " << reference << " Hz";
}

TEST(SolidModel, CantileverInPlaneBendingConvergesToTimoshenko) {
  const double reference = timoshenkoFirstFrequency(rodSection(true), true);
  std::vector<double> solid;
  for (int refinement : {1, 2, 4})
    solid.push_back(solidFirstBending(
        solidRod(20 * refinement, 2 * refinement, 1, true, HexFormulation::incompatibleModes), true));
  expectConvergence(solid, reference, 1e-3);
}

TEST(SolidModel, FreeFreeInPlaneBendingConvergesToTimoshenko) {
  const double reference = timoshenkoFirstFrequency(rodSection(true), false);
  std::vector<double> solid;
  for (int refinement : {1, 2, 4})
    solid.push_back(solidFirstBending(
        solidRod(20 * refinement, 2 * refinement, 1, true, HexFormulation::incompatibleModes), false));
  expectConvergence(solid, reference, 1e-3);
}

TEST(SolidModel, CantileverOutOfPlaneBendingConvergesToTimoshenko) {
  const double reference = timoshenkoFirstFrequency(rodSection(false), true);
  std::vector<double> solid;
  for (int refinement : {1, 2, 4})
    solid.push_back(solidFirstBending(
        solidRod(20 * refinement, 2, refinement, false, HexFormulation::incompatibleModes), true));
  expectConvergence(solid, reference, 1e-3);
}

TEST(SolidModel, FreeFreeOutOfPlaneBendingConvergesToTimoshenko) {
  const double reference = timoshenkoFirstFrequency(rodSection(false), false);
  std::vector<double> solid;
  for (int refinement : {1, 2, 4})
    solid.push_back(solidFirstBending(
        solidRod(20 * refinement, 2, refinement, false, HexFormulation::incompatibleModes), false));
  expectConvergence(solid, reference, 1e-3);
}

// Mid-plane symmetry keeps exactly the symmetric family: every frequency of the clamped half model
// (nu = 0.3, so the in-plane motions do move in z) is a frequency of the full model with the same
// elements, while the full model's lowest mode, out-of-plane bending, is absent from the half.
TEST(SolidModel, MidPlaneSymmetryKeepsTheSymmetricModesOnly) {
  const SolidModel half = solidRod(12, 2, 1, true, HexFormulation::incompatibleModes, 0.3);
  const SolidModel full = solidRod(12, 2, 2, false, HexFormulation::incompatibleModes, 0.3);
  EXPECT_EQ(half.symmetryConstrainedDofs().size(), 13u * 3u);
  EXPECT_TRUE(full.symmetryConstrainedDofs().empty());
  const std::vector<int> halfFixed = clampedFace(half), fullFixed = clampedFace(full);
  const Vector halfValues =
      lowestEigenvalues(removeDofs(half.stiffness(), halfFixed), removeDofs(half.mass(), halfFixed), 4, -1.0);
  const Vector fullValues = lowestEigenvalues(removeDofs(full.stiffness(), fullFixed),
                                              removeDofs(full.mass(), fullFixed), 16, -1.0);
  for (int mode = 0; mode < 4; ++mode) {
    const double nearest = (fullValues.array() - halfValues(mode)).abs().minCoeff();
    EXPECT_LT(nearest, 1e-8 * halfValues(mode)) << mode;
  }
  EXPECT_LT(fullValues(0), 0.5 * halfValues(0));
}

// Ten slender elements along the rod (aspect 10 : 3 in the plane, 10 : 1 out of it): the plain trilinear
// element's parasitic shear stiffens bending, the incompatible modes remove it.
TEST(SolidModel, IncompatibleModesRemoveBendingLocking) {
  const double reference = timoshenkoFirstFrequency(rodSection(true), true);
  const double locked = solidFirstBending(solidRod(10, 2, 1, true, HexFormulation::trilinear), true);
  const double unlocked =
      solidFirstBending(solidRod(10, 2, 1, true, HexFormulation::incompatibleModes), true);
  const double lockedError = std::abs(locked - reference) / reference;
  const double unlockedError = std::abs(unlocked - reference) / reference;
  RecordProperty("trilinear_error", std::to_string(lockedError));
  RecordProperty("incompatible_modes_error", std::to_string(unlockedError));
  EXPECT_GT(locked, reference);
  EXPECT_GT(lockedError, 0.2);
  EXPECT_LT(unlockedError, 0.02);
}

// The pinned-roller plate (fe_model.h) and the solid with one element through the thickness, nu = 0 and
// u_z held, on the same mesh: the in-plane motions of that solid are the plate's, u independent of z. The
// plain trilinear hexahedron then is the Q4 element times the thickness, so the frequencies agree to
// round-off. With the incompatible modes the solid is lower: the plate's Q4 has the parasitic shear of
// full integration, which falls like the squared element length, so the gap shrinks with the mesh.
Vector pinnedRollerFrequencies(const SolidModel& model, int count) {
  std::vector<int> fixed;
  for (int node = 0; node < model.nodeCount(); ++node) fixed.push_back(3 * node + 2);
  for (int node : model.jointANodes()) {
    fixed.push_back(3 * node);
    fixed.push_back(3 * node + 1);
  }
  for (int node : model.jointBNodes()) fixed.push_back(3 * node + 1);
  const Vector values =
      lowestEigenvalues(removeDofs(model.stiffness(), fixed), removeDofs(model.mass(), fixed), count, -1.0);
  return values.unaryExpr([](double v) { return frequencyOf(v); });
}

Vector plateFrequencies(int nx, int ny, int count) {
  const RodConfig config = rodConfig(nx, ny);
  const FeModel plate(config, Vector::Constant(config.designCount(), 1.0));
  const Vector values = lowestEigenvalues(plate.stiffness(), plate.mass(), count, -1.0);
  return values.unaryExpr([](double v) { return frequencyOf(v); });
}

TEST(SolidModel, TrilinearWithOneLayerIsThePlate) {
  const Vector plate = plateFrequencies(24, 4, 4);
  const Vector solid = pinnedRollerFrequencies(solidRod(24, 4, 1, false, HexFormulation::trilinear), 4);
  for (int mode = 0; mode < 4; ++mode) EXPECT_NEAR(solid(mode), plate(mode), 1e-9 * plate(mode)) << mode;
}

TEST(SolidModel, IncompatibleModesApproachThePlateUnderRefinement) {
  double previous = 1.0;
  for (int refinement : {1, 2, 4}) {
    const int nx = 50 * refinement, ny = 2 * refinement + 2 * (refinement / 2);  // 50x2, 100x6, 200x12
    const Vector plate = plateFrequencies(nx, ny, 2);
    const Vector solid =
        pinnedRollerFrequencies(solidRod(nx, ny, 1, false, HexFormulation::incompatibleModes), 2);
    const double gap = (plate(0) - solid(0)) / plate(0);
    RecordProperty("gap_" + std::to_string(nx) + "x" + std::to_string(ny), std::to_string(gap));
    EXPECT_GT(gap, 0.0) << nx << " x " << ny;
    EXPECT_LT(gap, previous) << nx << " x " << ny;
    previous = gap;
  }
  EXPECT_LT(previous, 5e-3);
}

// dK/dx_d and dM/dx_d against central differences of the assembled matrices (STYLE.md rule 5), on both
// sides of the density law's kink at 0.1.
TEST(SolidModel, ElementDerivativesMatchFiniteDifferences) {
  const RodConfig config = rodConfig(4, 2, 0.3);
  SolidMeshOptions options;
  options.elementsThroughThickness = 2;
  options.midPlaneSymmetry = true;
  Vector design = Vector::Constant(SolidModel::designCountOf(config, options), 0.6);
  design(1) = 0.05;
  design(5) = 0.4;
  const SolidModel model(config, options, design);
  for (int d : {1, 5}) {
    const double h = std::cbrt(std::numeric_limits<double>::epsilon()) * 0.1 * design(d);
    Vector up = design, down = design;
    up(d) += h;
    down(d) -= h;
    const SolidModel plus(config, options, up), minus(config, options, down);
    const SparseMatrix stiffnessDifference = (plus.stiffness() - minus.stiffness()) / (2.0 * h);
    const SparseMatrix massDifference = (plus.mass() - minus.mass()) / (2.0 * h);
    const HexElementMatrix stiffness = model.stiffnessDerivative(d), mass = model.massDerivative(d);
    const std::array<int, 24> dofs = model.elementDofs(model.designToElement(d));
    Eigen::MatrixXd expectedStiffness = Eigen::MatrixXd::Zero(model.dofCount(), model.dofCount());
    Eigen::MatrixXd expectedMass = expectedStiffness;
    for (int a = 0; a < 24; ++a)
      for (int b = 0; b < 24; ++b) {
        expectedStiffness(dofs[a], dofs[b]) += stiffness(a, b);
        expectedMass(dofs[a], dofs[b]) += mass(a, b);
      }
    EXPECT_LT((Eigen::MatrixXd(stiffnessDifference) - expectedStiffness).norm(),
              1e-6 * expectedStiffness.norm())
        << d;
    EXPECT_LT((Eigen::MatrixXd(massDifference) - expectedMass).norm(), 1e-6 * expectedMass.norm()) << d;
  }
  EXPECT_THROW(model.stiffnessDerivative(model.designCount()), std::invalid_argument);
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
