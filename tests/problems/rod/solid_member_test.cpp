// The solid as the mechanism's member (problems/rod/solid_member.h): its rigid part is the plate's, one
// layer without Poisson coupling reproduces the plate's psi1, and dpsi1/dx through the mechanism, the 3-D
// invariants and the eigenvector sensitivities matches finite differences.
#include <hindsight/problems/rod/solid_member.h>

#include <hindsight/engine/adjoint.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/mechanism/mechanism_problem.h>
#include <hindsight/problems/rod/fe_model.h>
#include <hindsight/problems/rod/invariants.h>
#include <hindsight/problems/rod/modal_reduction.h>
#include <hindsight/problems/rod/parallel.h>
#include <hindsight/problems/topopt/geometry_export.h>
#include <hindsight/storage/hdf5.h>

#include "support/coarse_solid.h"
#include "support/run_cli.h"
#include "support/same_bits.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <random>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

using testing::sameBits;

using testing::coarseSolidConfig;

/// The plate's design extruded through the solid's nz layers (design index d nz + k of the solid).
Vector extruded(const Vector& plate, int layers) {
  Vector solid(plate.size() * layers);
  for (Eigen::Index d = 0; d < plate.size(); ++d) solid.segment(d * layers, layers).setConstant(plate(d));
  return solid;
}

Vector randomDesign(int size, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.2, 1.0);
  Vector x(size);
  for (Eigen::Index i = 0; i < x.size(); ++i) x(i) = u(rng);
  return x;
}

/// psi1 of the configuration's slider-crank with the member's invariants p (PistonRod's path without the
/// model, so that the tests choose the element formulation).
double psi1Of(const Config& config, const rod::InertiaInvariants& invariants) {
  const rod::RodConfig& rc = config.rod;
  mechanism::Mechanism described =
      mechanism::sliderCrank(rc.crankRadius, rc.length, rc.crankSpeed, rc.rampTime);
  described.member.length = rc.length;
  const mechanism::MechanismProblem problem(described, invariants.modeCount(), invariants.spatial());
  return simulate(problem, invariants.pack(), PistonRod(config).integratorOptions()).objective;
}

TEST(SolidMember, ItsRigidPartIsThePlates) {
  // The rigid limit of the mechanism (a member that does not deform) sees m, m c and J0 alone; the solid
  // of any layering and with symmetry has the plate's, so the rigid motion is the plate's.
  for (const bool symmetry : {false, true}) {
    Config config = coarseSolidConfig(symmetry ? 1 : 3);
    config.rod.midPlaneSymmetry = symmetry;
    Config plateConfig = coarseSolidConfig(0);
    const Vector plateDesign = randomDesign(plateConfig.rod.designCount(), 3);
    const rod::FeModel plate(plateConfig.rod, plateDesign);
    const rod::SolidMember solid(config.rod, extruded(plateDesign, config.rod.elementsThroughThickness));
    const rod::ModalReductionOptions options = rod::ModalReductionOptions::fromConfig(config.rod);
    const rod::InertiaInvariants a = rod::computeInvariants(plate, rod::computeModalBasis(plate, options));
    const rod::InertiaInvariants b = rod::computeInvariants(solid, rod::computeModalBasis(solid, options));
    EXPECT_NEAR(b.mass, a.mass, 1e-13 * a.mass) << symmetry;
    EXPECT_LT((b.massTimesCenter - a.massTimesCenter).norm(), 1e-13 * a.mass * config.rod.length) << symmetry;
    EXPECT_NEAR(b.polarMoment, a.polarMoment, 1e-13 * a.polarMoment) << symmetry;
    EXPECT_TRUE(b.spatial());
    EXPECT_FALSE(a.spatial());
  }
}

// One layer, nu = 0 and the plain trilinear hexahedron: an in-plane motion uniform through the thickness
// has no strain that couples it to u_z (lambda = 0), and the element's in-plane stiffness and mass are
// the Q4's times the thickness (solid_model.h), so the half model with mid-plane symmetry (doubled) has
// the plate's in-plane modes exactly and psi1 equals the plate's to the eigen-solve's round-off. With the
// incompatible modes (the default element) the solid is the better discretisation: the Q4 locks in
// bending (its parasitic shear), the enhanced element does not, so the solid is softer and its psi1
// larger; that difference is the plate's discretisation error on this 12 x 4 mesh, measured here.
TEST(SolidMember, OneLayerWithoutPoissonReproducesThePlatesPsi1) {
  Config plateConfig = coarseSolidConfig(0);
  plateConfig.rod.poissonRatio = 0.0;
  Config solidConfig = coarseSolidConfig(1);
  solidConfig.rod.poissonRatio = 0.0;
  solidConfig.rod.midPlaneSymmetry = true;
  const Vector plateDesign = randomDesign(plateConfig.rod.designCount(), 5);
  const rod::ModalReductionOptions options = rod::ModalReductionOptions::fromConfig(plateConfig.rod);
  const rod::FeModel plate(plateConfig.rod, plateDesign);
  const rod::ModalBasis plateBasis = rod::computeModalBasis(plate, options);
  const double platePsi = psi1Of(plateConfig, rod::computeInvariants(plate, plateBasis));
  double psi[2];
  for (const rod::HexFormulation formulation :
       {rod::HexFormulation::trilinear, rod::HexFormulation::incompatibleModes}) {
    const rod::SolidMember solid(solidConfig.rod, extruded(plateDesign, 1), formulation);
    const rod::ModalBasis basis = rod::computeModalBasis(solid, options);
    const int which = formulation == rod::HexFormulation::trilinear ? 0 : 1;
    psi[which] = psi1Of(solidConfig, rod::computeInvariants(solid, basis));
    if (which == 0) {
      for (int i = 0; i < options.modeCount; ++i)
        EXPECT_NEAR(basis.eigenvalues(i), plateBasis.eigenvalues(i), 1e-10 * plateBasis.eigenvalues(i)) << i;
    }
  }
  std::cout << "[ solid ] psi1: plate " << platePsi << ", solid trilinear " << psi[0] << " (relative "
            << (psi[0] - platePsi) / platePsi << "), incompatible modes " << psi[1] << " (relative "
            << (psi[1] - platePsi) / platePsi << ")\n";
  EXPECT_NEAR(psi[0], platePsi, 1e-9 * platePsi);
  // The locking-free element is softer: a larger psi1, by the plate's discretisation error, which on
  // this coarse mesh (elements 5.6 times longer than high, one of four rows per half-height) is large:
  // measured +151 % (the Q4 locks in bending, its first frequency far too high).
  EXPECT_GT(psi[1], platePsi * 1.1);
  EXPECT_LT(psi[1], platePsi * 4.0);
}

// dpsi1/dx of the solid (12 x 4 x 2, no symmetry: in-plane and out-of-plane modes) against central
// differences with relative steps 1e-5 and 1e-6, at a design that is not symmetric through the thickness
// so that the two families couple and the rotational modal mass M_ee^xy differs from M_ee. A wrong or
// missing term (the M_ee^xy block, the mean of B's axis, the z components of X) changes a component by
// far more than the tolerance (measured: the differences' error is below ~1e-7 relative).
TEST(SolidMember, Psi1GradientMatchesFiniteDifferences) {
  Config config = coarseSolidConfig(2);
  config.rod.modeCount = 6;
  const PistonRod rod{config};
  const Vector x = randomDesign(rod.designCount(), 7);
  const PistonRod::Request withGradient{true, false, false}, forwardOnly{false, false, false};
  const auto result = rod.evaluate(x, withGradient);
  ASSERT_EQ(result.dpsi1.size(), rod.designCount());
  const double scale = result.dpsi1.cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0.0);
  std::cout << "[ solid ] psi1 = " << result.psi1 << ", frequencies [Hz]:";
  for (double f : result.frequenciesHz) std::cout << " " << f;
  std::cout << "\n";
  for (const double relativeStep : {1e-5, 1e-6}) {
    double worst = 0.0;
    for (int d = 0; d < rod.designCount(); d += 7) {
      const double h = relativeStep * x(d);
      Vector plus = x, minus = x;
      plus(d) += h;
      minus(d) -= h;
      const double fd =
          (rod.evaluate(plus, forwardOnly).psi1 - rod.evaluate(minus, forwardOnly).psi1) / (2 * h);
      const double error = std::abs(fd - result.dpsi1(d));
      worst = std::max(worst, error / scale);
      EXPECT_LE(error, 1e-5 * scale + 1e-4 * std::abs(result.dpsi1(d)))
          << "design " << d << " step " << relativeStep << ": adjoint " << result.dpsi1(d) << ", differences "
          << fd;
    }
    std::cout << "[ solid ] step " << relativeStep << ": largest |fd - adjoint| / max |g| = " << worst
              << "\n";
  }
}

// The solid's K is factorised in METIS's nested-dissection ordering (rod::stiffnessOrdering), the plate's
// in AMD's. The ordering changes only the rounding of the factor, and the eigenpairs are refined with
// residuals in twice the working precision (ModalReductionOptions::refinementSteps), so the eigenvalues,
// the modes and psi1 with either factor agree to round-off. Measured on this 24 x 6 x 4 half: eigenvalues
// 1.5e-15 relative, modes 1.2e-14 of their largest entry, psi1 1.2e-15 relative. The tolerances (1e-12,
// 1e-10, 1e-12) leave about three orders of magnitude for other compilers and designs; a factor of
// another matrix (a permutation applied the wrong way round) would make the eigen-solve's operator
// another one and its eigenpairs wrong.
TEST(SolidMember, TheMetisOrderedFactorGivesAmdsEigenpairsAndPsi1ToRoundOff) {
  Config config = coarseSolidConfig(4);
  config.rod.elementsAlongLength = 24;
  config.rod.elementsThroughHeight = 6;
  config.rod.midPlaneSymmetry = true;
  const rod::SolidMember solid(config.rod, randomDesign(config.rod.designCount(), 11));
  ASSERT_EQ(rod::stiffnessOrdering(solid), rod::FillOrdering::Metis);
  const rod::ModalReductionOptions options = rod::ModalReductionOptions::fromConfig(config.rod);
  const rod::StiffnessFactorization metis(solid.stiffness(), rod::FillOrdering::Metis);
  const rod::StiffnessFactorization amd(solid.stiffness(), rod::FillOrdering::Amd);
  // Two different orderings, or the test would compare a factor with itself.
  ASSERT_TRUE((metis.permutationP().indices().array() != amd.permutationP().indices().array()).any());
  const rod::ModalBasis withMetis = rod::computeModalBasis(solid, options, metis);
  const rod::ModalBasis withAmd = rod::computeModalBasis(solid, options, amd);
  // The solid's own path (its factorisation made inside) is the METIS one, bit for bit.
  EXPECT_TRUE(sameBits(rod::computeModalBasis(solid, options).eigenvalues, withMetis.eigenvalues));
  double eigenvalues = 0.0, modes = 0.0;
  for (int i = 0; i < withAmd.eigenmodeCount; ++i) {
    eigenvalues = std::max(
        eigenvalues, std::abs(withMetis.eigenvalues(i) - withAmd.eigenvalues(i)) / withAmd.eigenvalues(i));
    modes = std::max(modes, (withMetis.modesFree.col(i) - withAmd.modesFree.col(i)).cwiseAbs().maxCoeff() /
                                withAmd.modesFree.col(i).cwiseAbs().maxCoeff());
  }
  const double psiMetis = psi1Of(config, rod::computeInvariants(solid, withMetis));
  const double psiAmd = psi1Of(config, rod::computeInvariants(solid, withAmd));
  const double psi = std::abs(psiMetis - psiAmd) / std::abs(psiAmd);
  std::cout << "[ solid ] METIS against AMD: eigenvalues " << eigenvalues << ", modes " << modes << ", psi1 "
            << psi << " (relative)\n";
  EXPECT_LE(eigenvalues, 1e-12);
  EXPECT_LE(modes, 1e-10);
  EXPECT_LE(psi, 1e-12);
}

// Above SupernodalOptions::smallest free DOFs the solid's supernodal factorisation and its
// back-substitutions run on the subtrees of its supernodal tree in parallel; the gradient of psi1, psi2
// and its gradient are the same bits on one and two threads (the factor, the eigen-solve, ESL and the
// chain all solve with it).
TEST(SolidMember, TheGradientHasTheSameBitsForAnyThreadCount) {
  Config config = coarseSolidConfig(4);
  config.rod.elementsAlongLength = 110;
  config.rod.elementsThroughHeight = 10;
  config.rod.midPlaneSymmetry = true;
  const Vector x = randomDesign(config.rod.designCount(), 13);
  {
    const rod::SolidMember solid(config.rod, x);
    ASSERT_GT(solid.freeDofCount(), rod::SupernodalOptions{}.smallest);
  }
  if (!threadsSupported() || availableThreads() < 2) GTEST_SKIP() << "one thread only on this machine";
  std::vector<PistonRodEvaluation> results;
  for (const int threads : {1, 2}) {
    const ThreadLimit limit(threads);
    if (threads == 2) {
      // The parallel factorisation and sweep run: the supernodal tree is split into subtrees.
      const rod::SolidMember solid(config.rod, x);
      EXPECT_GT(rod::StiffnessFactorization(solid.stiffness(), rod::stiffnessOrdering(solid)).parallelShare(),
                0.5);
    }
    results.push_back(PistonRod(config).evaluate(x, PistonRod::Request{}));
  }
  EXPECT_TRUE(sameBits(results[0].eigenvalues, results[1].eigenvalues));
  EXPECT_TRUE(sameBits(results[0].psi1, results[1].psi1));
  EXPECT_TRUE(sameBits(results[0].psi2, results[1].psi2));
  EXPECT_TRUE(sameBits(results[0].dpsi1, results[1].dpsi1));
  EXPECT_TRUE(sameBits(results[0].dpsi2, results[1].dpsi2));
}

TEST(SolidMember, TheConfigurationFieldsAreChecked) {
  rod::RodConfig config;
  config.elementsThroughThickness = -1;
  try {
    config.validate();
    FAIL() << "a negative elementsThroughThickness was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("elementsThroughThickness"), std::string::npos) << e.what();
  }
  config.elementsThroughThickness = 0;
  config.midPlaneSymmetry = true;
  try {
    config.validate();
    FAIL() << "midPlaneSymmetry on the plate was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("midPlaneSymmetry"), std::string::npos) << e.what();
  }
  config.midPlaneSymmetry = false;
  EXPECT_THROW(rod::SolidMember(config, Vector::Constant(config.designCount(), 0.5)), std::invalid_argument);
  config.elementsThroughThickness = 2;
  EXPECT_EQ(config.designCount(), 198 * 12 * 2);
  EXPECT_THROW(rod::FeModel(config, Vector::Constant(config.designCount(), 0.5)), std::invalid_argument);
}

/// Every directed edge's count minus its reverse's (0 for a closed, consistently oriented surface), the
/// largest number of triangles on one undirected edge, and the enclosed volume by the divergence theorem
/// (positive for outward normals).
struct SurfaceCheck {
  int unbalanced = 0, fewest = 1 << 30, most = 0;
  double volume = 0.0;
};

SurfaceCheck checkSurface(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> directed;
  SurfaceCheck out;
  for (const auto& t : mesh.triangles) {
    for (int e = 0; e < 3; ++e) ++directed[{t[e], t[(e + 1) % 3]}];
    const Eigen::Vector3d &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
    out.volume += a.dot(b.cross(c)) / 6.0;
  }
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    const int back = reverse == directed.end() ? 0 : reverse->second;
    if (back != count) ++out.unbalanced;
    out.fewest = std::min(out.fewest, count + back);
    out.most = std::max(out.most, count + back);
  }
  return out;
}

// The STL export of the solid: an I-section (flanges through the whole thickness, a web in the middle
// layer) is a closed 2-manifold (every edge on exactly two triangles, each direction once) whose enclosed
// volume is the solid elements' with outward normals; a random field is closed too (edges where elements
// touch along an edge only carry four triangles) with the right volume; mirrored by symmetry, the half
// gives the whole body's.
TEST(SolidMember, TheVoxelSurfaceIsClosedWithOutwardNormals) {
  BoxDensityField field;
  field.nx = 6;
  field.ny = 5;
  field.nz = 3;
  field.cellWidthMm = 2.0;
  field.cellHeightMm = 1.5;
  field.cellDepthMm = 0.5;
  field.values = Vector::Constant(6 * 5 * 3, 0.01);
  int solid = 0;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 5; ++j) {
      for (int k = 0; k < 3; ++k) {
        if (j == 0 || j == 4 || k == 1) {
          field.values((i * 5 + j) * 3 + k) = 0.9;
          ++solid;
        }
      }
    }
  }
  const double cell = 2.0 * 1.5 * 0.5;
  SurfaceCheck check = checkSurface(voxelSurface(field, 0.5));
  EXPECT_EQ(check.unbalanced, 0);
  EXPECT_EQ(check.fewest, 2);
  EXPECT_EQ(check.most, 2);
  EXPECT_NEAR(check.volume, solid * cell, 1e-9 * solid * cell);
  field.values = randomDesign(6 * 5 * 3, 9);
  const int above = static_cast<int>((field.values.array() >= 0.6).count());
  check = checkSurface(voxelSurface(field, 0.6));
  EXPECT_EQ(check.unbalanced, 0);
  EXPECT_EQ(check.most % 2, 0);
  EXPECT_NEAR(check.volume, above * cell, 1e-9 * above * cell);
  field.midPlaneSymmetry = true;
  check = checkSurface(voxelSurface(field, 0.6));
  EXPECT_EQ(check.unbalanced, 0);
  EXPECT_NEAR(check.volume, 2 * above * cell, 1e-9 * above * cell);
  EXPECT_THROW(voxelSurface(field, 1.0), std::invalid_argument);
}

#ifdef HINDSIGHT_CLI_PATH
// The solid from the command line: the switch is a configuration field, evaluate writes its gradient as
// (nz, ny, nx), optimize runs a few iterations of it, and a bad value is refused naming the field.
const std::string kCoarseSolid =
    "--set rod.elementsAlongLength=12 --set rod.elementsThroughHeight=4 --set rod.elementsThroughThickness=2 "
    "--set rod.modeCount=6 --set rod.endTime=1 --set rod.rampTime=1 ";

TEST(SolidMember, EvaluateAndOptimizeRunFromTheCommandLine) {
  namespace fs = std::filesystem;
  const std::string dir = ::testing::TempDir() + "/solid_member_cli";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const auto evaluated = testing::runCli("evaluate " + kCoarseSolid + "--json --gradient " + dir + "/g.h5");
  ASSERT_EQ(evaluated.exitCode, 0) << evaluated.output;
  const auto report = nlohmann::json::parse(evaluated.output.substr(evaluated.output.find('{')));
  EXPECT_GT(report.at("psi1").get<double>(), 0.0) << evaluated.output;
  {
    const hdf5::Handle file = hdf5::openFileReadOnly(dir + "/g.h5");
    const std::vector<hsize_t> shape = {2, 4, 12};
    EXPECT_EQ(hdf5::shape(hdf5::openDataset(file.get(), "dpsi1_dx").get()), shape);
  }
  const auto optimized = testing::runCli("optimize " + kCoarseSolid + "--iterations 2 --out " + dir + "/run");
  EXPECT_EQ(optimized.exitCode, 0) << optimized.output;
  EXPECT_TRUE(fs::exists(dir + "/run/results.h5")) << optimized.output;
  const auto exported = testing::runCli("export " + dir + "/run --out " + dir + "/solid");
  EXPECT_EQ(exported.exitCode, 0) << exported.output;
  EXPECT_TRUE(fs::exists(dir + "/solid.stl") && fs::exists(dir + "/solid.vtu")) << exported.output;
  const auto refused = testing::runCli("evaluate --set rod.elementsThroughThickness=-1");
  EXPECT_EQ(refused.exitCode, 2) << refused.output;
  EXPECT_NE(refused.output.find("rod.elementsThroughThickness"), std::string::npos) << refused.output;
  fs::remove_all(dir);
}
#endif

}  // namespace
}  // namespace hindsight
