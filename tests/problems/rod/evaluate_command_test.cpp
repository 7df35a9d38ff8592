// `hindsight evaluate` as a user runs it: output paths are checked before any work, an existing
// gradient file is kept without --force (the --design input always), and adaptive steps give psi1
// with psi2 skipped.
#include <hindsight/problems/rod/design_io.h>
#include <hindsight/storage/hdf5.h>

#include "support/run_cli.h"
#include "support/storage_fixtures.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

#ifdef HINDSIGHT_CLI_PATH
namespace hindsight {
namespace {

using testing::runCli;

const std::string kCoarse =
    "--set rod.elementsAlongLength=20 --set rod.elementsThroughHeight=4 --set rod.modeCount=4 ";

rod::RodConfig coarseRod() {
  rod::RodConfig config;
  config.elementsAlongLength = 20;
  config.elementsThroughHeight = 4;
  config.modeCount = 4;
  return config;
}

std::string fileBytes(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
}

TEST(EvaluateCommand, UnwritableGradientPathIsRefusedBeforeAnyWork) {
  const auto result = runCli("evaluate " + kCoarse + "--gradient /proc/nope/g.h5");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("--gradient '/proc/nope/g.h5': directory '/proc/nope' does not exist"),
            std::string::npos)
      << result.output;
  EXPECT_EQ(result.output.find("psi1"), std::string::npos) << "work was done:\n" << result.output;
}

TEST(EvaluateCommand, ExistingGradientFileNeedsForceAndTheDesignInputIsNeverOverwritten) {
  const testing::ScratchDirectory scratch;
  const std::string& dir = scratch.path();
  const std::string gradient = dir + "/g.h5";
  std::ofstream(gradient) << "keep me";
  auto result = runCli("evaluate " + kCoarse + "--gradient " + gradient);
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("--gradient '" + gradient + "' exists; use --force"), std::string::npos)
      << result.output;
  EXPECT_EQ(fileBytes(gradient), "keep me");
  result = runCli("evaluate " + kCoarse + "--gradient " + gradient + " --force");
  EXPECT_EQ(result.exitCode, 0) << result.output;
  EXPECT_NE(result.output.find("gradients written to"), std::string::npos) << result.output;

  const rod::RodConfig config = coarseRod();
  const std::string design = dir + "/design.h5";
  writeDesignFields(design, config, {{"x", Vector::Constant(config.designCount(), 0.6)}}, 1.0);
  const std::string before = fileBytes(design);
  for (const std::string& same : {design, dir + "/./design.h5"}) {
    result = runCli("evaluate " + kCoarse + "--design " + design + " --gradient " + same + " --force");
    EXPECT_EQ(result.exitCode, 2) << result.output;
    EXPECT_NE(result.output.find("is the --design input"), std::string::npos) << result.output;
  }
  EXPECT_EQ(fileBytes(design), before);
}

TEST(EvaluateCommand, DesignWithAnInterfaceColumnOtherThanOneIsBadInput) {
  const testing::ScratchDirectory scratch;
  const std::string& dir = scratch.path();
  const rod::RodConfig config = coarseRod();
  writeDesignFields(dir + "/design.h5", config, {{"x", Vector::Constant(config.designCount(), 0.6)}}, 0.5);
  const auto result = runCli("evaluate " + kCoarse + "--design " + dir + "/design.h5");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("x[0][0] (row 0, interface column 0) = 0.5 must be 1"), std::string::npos)
      << result.output;
}

// Every evaluation used to compute psi2, so no adaptive integrator could serve the rod.
TEST(EvaluateCommand, AdaptiveStepsGivePsi1AndSayWhyPsi2WasSkipped) {
  const auto adaptive = runCli("evaluate --json " + kCoarse +
                               "--set simulation.integrator=dopri5 --set simulation.adaptive=true "
                               "--storage online:checkpoints=20");
  ASSERT_EQ(adaptive.exitCode, 0) << adaptive.output;
  const auto fixed =
      runCli("evaluate --json --set simulation.integrator=rk4 --set simulation.step=1e-4 " + kCoarse);
  ASSERT_EQ(fixed.exitCode, 0) << fixed.output;
  const auto a = nlohmann::json::parse(adaptive.output);
  const auto f = nlohmann::json::parse(fixed.output);
  EXPECT_TRUE(a["psi2"].is_null());
  EXPECT_NE(a["psi2_skipped"].get<std::string>().find("fixed steps"), std::string::npos);
  EXPECT_FALSE(f.contains("psi2_skipped"));
  EXPECT_TRUE(f["psi2"].is_number());
  // dopri5 at its default tolerances (relative 1e-8) against RK4 on the fixed grid.
  const double psi1 = f["psi1"].get<double>();
  EXPECT_NEAR(a["psi1"].get<double>(), psi1, 1e-7 * psi1);
  EXPECT_EQ(a["summary"]["method"], "dopri5");
}

}  // namespace
}  // namespace hindsight
#endif
