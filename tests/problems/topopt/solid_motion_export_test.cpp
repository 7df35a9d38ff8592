// The solid member over the motion (problems/topopt/solid_motion_export.h): the frame's points are the
// reference shape moved by the rigid planar motion and the magnified modal displacement (mirrored with
// mid-plane symmetry), the recorded motion is the run's (its psi1 bit for bit, the joints on the crank
// circle and the guide), and the written time series reads back with its sizes and times.
#include <hindsight/problems/topopt/solid_motion_export.h>

#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/topopt/results_file.h>

#include "support/coarse_solid.h"
#include "support/run_cli.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace hindsight {
namespace {

namespace fs = std::filesystem;

// 3 x 2 x 2 boxes of 10 x 5 x 2.5 mm, the half z >= 0 of a body 10 mm thick.
BoxDensityField smallField() {
  BoxDensityField field;
  field.nx = 3;
  field.ny = 2;
  field.nz = 2;
  field.midPlaneSymmetry = true;
  field.values = Vector::LinSpaced(12, 0.1, 1.0);
  field.cellWidthMm = 10.0;
  field.cellHeightMm = 5.0;
  field.cellDepthMm = 2.5;
  return field;
}

Eigen::Index column(const BoxDensityField& f, int i, int j, int layer) {
  return (static_cast<Eigen::Index>(i) * (f.ny + 1) + j) * (f.layers() + 1) + layer;
}

int modelDof(const BoxDensityField& f, int i, int j, int k, int component) {
  return 3 * ((i * (f.ny + 1) + j) * (f.nz + 1) + k) + component;
}

TEST(SolidMotionExport, UndeformedFrameAtRestIsTheReferenceShape) {
  const BoxDensityField field = smallField();
  std::mt19937 random(7);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const Matrix modes = Matrix::NullaryExpr(3 * 4 * 3 * 3, 2, [&] { return uniform(random); });
  const Matrix points = solidFramePoints(field, modes, Vector::Zero(3), Vector::Zero(2), 100.0);
  ASSERT_EQ(points.cols(), 4 * 3 * 5);
  for (int i = 0; i <= 3; ++i) {
    for (int j = 0; j <= 2; ++j) {
      for (int layer = 0; layer <= 4; ++layer) {
        const Eigen::Vector3d expected(10.0 * i, -5.0 + 5.0 * j, -5.0 + 2.5 * layer);
        EXPECT_LT((points.col(column(field, i, j, layer)) - expected).norm(), 1e-12) << i << j << layer;
      }
    }
  }
}

TEST(SolidMotionExport, ARigidQuarterTurnMovesEveryPointAboutTheFramesOrigin) {
  const BoxDensityField field = smallField();
  const Matrix modes = Matrix::Zero(3 * 4 * 3 * 3, 1);
  const Matrix reference = solidFramePoints(field, modes, Vector::Zero(3), Vector::Zero(1), 1.0);
  const Eigen::Vector3d pose(0.15, -0.02, 0.5 * M_PI);  // m, m, rad
  const Matrix turned = solidFramePoints(field, modes, pose, Vector::Zero(1), 1.0);
  for (Eigen::Index c = 0; c < reference.cols(); ++c) {
    // (x, y, z) -> (x_R - y, y_R + x, z), in mm.
    const Eigen::Vector3d expected(150.0 - reference(1, c), -20.0 + reference(0, c), reference(2, c));
    EXPECT_LT((turned.col(c) - expected).norm(), 1e-12) << c;
  }
}

TEST(SolidMotionExport, TheModalDisplacementIsMagnifiedRotatedAndMirrored) {
  const BoxDensityField field = smallField();
  Matrix modes = Matrix::Zero(3 * 4 * 3 * 3, 1);
  // Node (2, 1, 1) of the half model, above the mid-plane: u = (1, 2, 3) um per unit q.
  modes(modelDof(field, 2, 1, 1, 0), 0) = 1e-6;
  modes(modelDof(field, 2, 1, 1, 1), 0) = 2e-6;
  modes(modelDof(field, 2, 1, 1, 2), 0) = 3e-6;
  const Vector q = Vector::Constant(1, 2.0);
  const Eigen::Vector3d pose(0.0, 0.0, 0.5 * M_PI);
  const Matrix reference = solidFramePoints(field, modes, pose, Vector::Zero(1), 1000.0);
  Matrix displacement;
  const Matrix deformed = solidFramePoints(field, modes, pose, q, 1000.0, &displacement);
  // Magnified 1000 times, q = 2: (2, 4, 6) mm in the member frame, (-4, 2, 6) mm after the quarter turn;
  // the mirror image below the mid-plane (whole-body layer 1) moves by (-4, 2, -6).
  const Eigen::Index above = column(field, 2, 1, 3), below = column(field, 2, 1, 1);
  EXPECT_LT((deformed.col(above) - reference.col(above) - Eigen::Vector3d(-4.0, 2.0, 6.0)).norm(), 1e-9);
  EXPECT_LT((deformed.col(below) - reference.col(below) - Eigen::Vector3d(-4.0, 2.0, -6.0)).norm(), 1e-9);
  EXPECT_LT((displacement.col(above) - Eigen::Vector3d(-4.0, 2.0, 6.0)).norm(), 1e-9);
  EXPECT_EQ((deformed - reference).cwiseAbs().colwise().sum().array().cast<bool>().count(), 2);
  EXPECT_THROW(solidFramePoints(field, modes.topRows(10), pose, q, 1.0), std::invalid_argument);
}

TEST(SolidMotionExport, TheDefaultMagnificationIsOneTwoOrFiveTimesAPowerOfTen) {
  EXPECT_DOUBLE_EQ(defaultMagnification(1e-3, 1.0), 50.0);      // 0.05 / 1e-3 = 50
  EXPECT_DOUBLE_EQ(defaultMagnification(3e-4, 1.0), 100.0);     // 166.7 -> 100
  EXPECT_DOUBLE_EQ(defaultMagnification(1.5e-5, 1.0), 2000.0);  // 3333 -> 2000
  EXPECT_DOUBLE_EQ(defaultMagnification(0.0, 1.0), 1.0);
  EXPECT_EQ(magnificationLabel(2000.0), "2000");
  EXPECT_EQ(magnificationLabel(5e6), "5e+06");
}

BoxDensityField fieldOf(const Config& config, ConstVectorRef values) {
  BoxDensityField field;
  field.nx = config.rod.elementsAlongLength;
  field.ny = config.rod.elementsThroughHeight;
  field.nz = config.rod.elementsThroughThickness;
  field.midPlaneSymmetry = config.rod.midPlaneSymmetry;
  field.values = values;
  field.cellWidthMm = 1000.0 * config.rod.length / field.nx;
  field.cellHeightMm = 1000.0 * config.rod.height / field.ny;
  field.cellDepthMm = 1000.0 * config.rod.thickness / field.layers();
  return field;
}

TEST(SolidMotionExport, TheRecordedMotionIsTheRunsAndKeepsTheJointsOnTheirPaths) {
  const Config config = testing::coarseSolidConfig(2, /*midPlaneSymmetry=*/true);
  const PistonRod rod(config);
  const Vector design = rod.initialDesign();
  const MemberMotion motion = recordMemberMotion(rod, design, 5);
  PistonRod::Request valuesOnly;
  valuesOnly.psi1Gradient = valuesOnly.psi2 = valuesOnly.psi2Gradient = false;
  EXPECT_EQ(motion.psi1, rod.evaluate(design, valuesOnly).psi1);  // the observer changes no bit
  ASSERT_EQ(motion.times.size(), 5u);
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(motion.times[static_cast<std::size_t>(k)], 0.25 * k, 1e-12) << k;
  EXPECT_EQ(motion.modal.col(0).norm(), 0.0);  // at rest and undeformed at t = 0
  EXPECT_GT(motion.modal.col(4).norm(), 0.0);
  const BoxDensityField field = fieldOf(config, Vector::Ones(12 * 4 * 2));
  const double r = config.rod.crankRadius;
  for (Eigen::Index k = 0; k < 5; ++k) {
    // A is the crank pin, on the circle of radius r; B slides on the guide y = 0 through the crank
    // pivot: the mean of B's axis, where the modes hold u_y = 0 and c = b q is the mean u_x.
    EXPECT_NEAR(std::hypot(motion.poses(0, k), motion.poses(1, k)), r, 1e-12) << k;
    const Matrix points =
        solidFramePoints(field, motion.modes, motion.poses.col(k), motion.modal.col(k), 1.0);
    double meanY = 0.0;
    for (int layer = 0; layer <= field.layers(); ++layer)
      meanY += points(1, column(field, field.nx, field.ny / 2, layer)) / (field.layers() + 1);
    EXPECT_NEAR(meanY, 0.0, 1e-7) << k;  // mm: the position solve's round-off (a sign error in beta: mm)
  }
  EXPECT_THROW(recordMemberMotion(rod, design, 1), std::invalid_argument);
}

std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(SolidMotionExport, TheTimeSeriesReadsBackWithItsSizesAndTimes) {
  const Config config = testing::coarseSolidConfig(2, /*midPlaneSymmetry=*/true);
  const PistonRod rod(config);
  const MemberMotion motion = recordMemberMotion(rod, rod.initialDesign(), 3);
  const BoxDensityField field = fieldOf(config, Vector::LinSpaced(12 * 4 * 2, 0.2, 1.0));
  const std::string dir = ::testing::TempDir() + "/solid_motion";
  fs::remove_all(dir);
  const std::string pvd = writeSolidMotion(dir, field, motion, 500.0);
  EXPECT_EQ(pvd, dir + "/motion_x500.pvd");
  const std::string collection = slurp(pvd);
  const std::regex dataSet("<DataSet timestep=\"([^\"]+)\" group=\"\" part=\"0\" file=\"([^\"]+)\"/>");
  std::vector<std::string> files;
  std::size_t k = 0;
  for (auto it = std::sregex_iterator(collection.begin(), collection.end(), dataSet);
       it != std::sregex_iterator(); ++it, ++k) {
    ASSERT_LT(k, motion.times.size());
    EXPECT_EQ(std::stod((*it)[1]), motion.times[k]);
    files.push_back((*it)[2]);
  }
  ASSERT_EQ(files.size(), 3u);
  const long points = 13L * 5 * 5, cells = 12L * 4 * 4;
  for (std::size_t f = 0; f < files.size(); ++f) {
    const std::string text = slurp(fs::path(dir) / files[f]);
    EXPECT_NE(text.find("NumberOfPoints=\"" + std::to_string(points) + "\" NumberOfCells=\"" +
                        std::to_string(cells) + "\""),
              std::string::npos)
        << files[f];
    EXPECT_NE(text.find("Name=\"displacement_x500\""), std::string::npos);
    EXPECT_NE(text.find("</VTKFile>"), std::string::npos);
    if (f == 0) {
      // Frame 0 (q = 0): its points are the reference shape at the initial pose.
      const Matrix expected =
          solidFramePoints(field, motion.modes, motion.poses.col(0), Vector::Zero(motion.modal.rows()), 1.0);
      std::istringstream in(text.substr(text.find('>', text.find("<DataArray")) + 1));
      double largest = 0.0;
      for (long c = 0; c < points; ++c) {
        for (int d = 0; d < 3; ++d) {
          double value = 0.0;
          in >> value;
          largest = std::max(largest, std::abs(value - expected(d, c)));
        }
      }
      EXPECT_LT(largest, 1e-5);  // %.9g of coordinates up to 1150 mm: 5e-6
    }
  }
  EXPECT_THROW(writeSolidMotion(dir, field, motion, 500.0), std::invalid_argument);  // exists
  EXPECT_THROW(writeSolidMotion(dir + "2", field, motion, 0.0), std::invalid_argument);
  EXPECT_NO_THROW(writeSolidMotion(dir, field, motion, 20.0, true));
  EXPECT_TRUE(fs::exists(dir + "/motion_x20.pvd"));
  EXPECT_FALSE(fs::exists(dir + "/motion_x500.pvd"));
  fs::remove_all(dir);
}

#ifdef HINDSIGHT_CLI_PATH
TEST(SolidMotionExport, ExportMotionDrawsTheRunsFinalDesign) {
  const std::string dir = ::testing::TempDir() + "/solid_motion_cli";
  fs::remove_all(dir);
  const std::string solid =
      "--set rod.elementsAlongLength=12 --set rod.elementsThroughHeight=4 --set "
      "rod.elementsThroughThickness=2 "
      "--set rod.midPlaneSymmetry=true --set rod.modeCount=4 --set rod.endTime=1 --set rod.rampTime=1 ";
  const auto optimized = testing::runCli("optimize " + solid + "--iterations 2 --out " + dir + "/run");
  ASSERT_EQ(optimized.exitCode, 0) << optimized.output;
  const auto exported = testing::runCli("export " + dir + "/run --motion --frames 4");
  ASSERT_EQ(exported.exitCode, 0) << exported.output;
  // The series shows the design of the run's final evaluation: its psi1 is the history's last.
  const ResultsData data = readResultsFile(dir + "/run/results.h5");
  const std::size_t at = exported.output.find("psi1 ");
  ASSERT_NE(at, std::string::npos) << exported.output;
  EXPECT_EQ(std::stod(exported.output.substr(at + 5)), data.history.back().psi1) << exported.output;
  EXPECT_TRUE(fs::exists(dir + "/run/design_final_motion/frame_0003.vtu")) << exported.output;
  // The densities export draws the same design: byte for byte the .vtu optimize wrote at its end.
  const auto densities = testing::runCli("export " + dir + "/run --out " + dir + "/again");
  ASSERT_EQ(densities.exitCode, 0) << densities.output;
  EXPECT_EQ(slurp(dir + "/again.vtu"), slurp(dir + "/run/design_final.vtu"));
  const auto again = testing::runCli("export " + dir + "/run --motion --frames 4");
  EXPECT_EQ(again.exitCode, 2) << again.output;
  EXPECT_NE(again.output.find("--force"), std::string::npos) << again.output;
  const auto badFrames = testing::runCli("export " + dir + "/run --motion --frames 1 --force");
  EXPECT_EQ(badFrames.exitCode, 2) << badFrames.output;
  EXPECT_NE(badFrames.output.find("--frames"), std::string::npos) << badFrames.output;
  const auto plate = testing::runCli(
      "optimize --set rod.elementsAlongLength=20 --set rod.elementsThroughHeight=4 "
      "--set rod.endTime=1 --set rod.rampTime=1 --iterations 1 --out " +
      dir + "/plate");
  ASSERT_EQ(plate.exitCode, 0) << plate.output;
  const auto refused = testing::runCli("export " + dir + "/plate --motion");
  EXPECT_EQ(refused.exitCode, 2) << refused.output;
  EXPECT_NE(refused.output.find("solid member"), std::string::npos) << refused.output;
  fs::remove_all(dir);
}
#endif

}  // namespace
}  // namespace hindsight
