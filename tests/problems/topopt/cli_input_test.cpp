// The command line's handling of careless input beyond the option checks of optimizer_test.cpp:
// parse errors of CLI11 exit 2 like every input error; --threads 0; --set and flags applied before
// the checks across fields (their order does not matter); evaluate refuses a configuration with
// scenarios instead of ignoring them; --resume with another configuration names every difference.
#include "support/fresh_directory.h"
#include "support/run_cli.h"

#include <gtest/gtest.h>
#include <hdf5.h>

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace hindsight {
namespace {

#ifdef HINDSIGHT_CLI_PATH
namespace fs = std::filesystem;
using testing::CliResult;
using testing::runCli;

// A fresh, existing folder for one test (tests/support/fresh_directory.h removes it at the end).
std::string freshFolder(const std::string& name) {
  const std::string dir = testing::freshDirectory("cli_input_" + name);
  fs::create_directories(dir);
  return dir;
}

TEST(CliInput, ParseErrorsExitWithCodeTwo) {
  const struct {
    std::string arguments;
    std::string message;
  } cases[] = {
      {"optimize --threads abc", "--threads"},
      {"evaluate --bogus", "--bogus"},
      {"evaluate --threads 0", "--threads = 0 is outside the allowed range [1, inf)"},
      {"optimize --threads 0 --out " + ::testing::TempDir() + "/hindsight_cli_never", "--threads = 0"},
      {"nonsense-command", "A subcommand is required"},
  };
  for (const auto& c : cases) {
    const CliResult result = runCli(c.arguments);
    EXPECT_EQ(result.exitCode, 2) << c.arguments << "\n" << result.output;
    EXPECT_NE(result.output.find(c.message), std::string::npos) << c.arguments << "\n" << result.output;
  }
  EXPECT_FALSE(fs::exists(::testing::TempDir() + "/hindsight_cli_never"));
  EXPECT_EQ(runCli("--help").exitCode, 0);
  EXPECT_EQ(runCli("--version").exitCode, 0);
  EXPECT_EQ(runCli("evaluate --help").exitCode, 0);
}

TEST(CliInput, SettingsAreCheckedTogetherWhateverTheirOrder) {
  // rod.rampTime = 5 alone exceeds the default endTime (3); with endTime = 6 it is valid in any order.
  for (const std::string order :
       {"--set rod.rampTime=5 --set rod.endTime=6", "--set rod.endTime=6 --set rod.rampTime=5"}) {
    const CliResult result = runCli("evaluate --print-config " + order);
    EXPECT_EQ(result.exitCode, 0) << order << "\n" << result.output;
    EXPECT_NE(result.output.find("\"rampTime\": 5.0"), std::string::npos) << result.output;
  }
  const CliResult invalid = runCli("evaluate --print-config --set rod.rampTime=5 --set rod.endTime=4");
  EXPECT_EQ(invalid.exitCode, 2) << invalid.output;
  EXPECT_NE(invalid.output.find("rampTime"), std::string::npos) << invalid.output;
}

TEST(CliInput, EvaluateRefusesScenariosInsteadOfIgnoringThem) {
  const std::string dir = freshFolder("scenarios");
  std::ofstream(dir + "/s.json") << R"({"scenarios": [{"name": "a"}, {"name": "b", "crankSpeed": 20}]})";
  const CliResult result = runCli("evaluate --config " + dir + "/s.json");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("config field 'scenarios' has 2 scenarios"), std::string::npos)
      << result.output;
  EXPECT_EQ(result.output.find("psi1"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("--rod-only"), std::string::npos) << result.output;
  const CliResult rodOnly =
      runCli("evaluate --rod-only --config " + dir +
             "/s.json --set rod.elementsAlongLength=8 --set rod.elementsThroughHeight=2 "
             "--set rod.modeCount=2 --set rod.endTime=0.02 --set rod.rampTime=0.01 --set rod.eslSamples=4 "
             "--set simulation.step=1e-3");
  EXPECT_EQ(rodOnly.exitCode, 0) << rodOnly.output;
  EXPECT_NE(rodOnly.output.find("psi1"), std::string::npos) << rodOnly.output;
}

TEST(CliInput, ResumeWithAnotherConfigurationNamesEveryDifference) {
  const std::string dir = freshFolder("resume");
  const std::string tiny =
      R"("rod": {"elementsAlongLength": 8, "elementsThroughHeight": 2, "modeCount": 2, "endTime": 0.02,
                 "rampTime": 0.01, "eslSamples": 4}, "simulation": {"step": 1e-3})";
  std::ofstream(dir + "/with.json") << "{" << tiny
                                    << R"(, "scenarios": [{"name": "a"}, {"name": "b", "weight": 2}]})";
  std::ofstream(dir + "/without.json") << "{" << tiny << "}";
  CliResult result = runCli("optimize --config " + dir + "/with.json --iterations 1 --out " + dir + "/run");
  ASSERT_EQ(result.exitCode, 0) << result.output;
  // The stored run has scenarios, the requested one none: the list names them (it used to be empty).
  result = runCli("optimize --resume --config " + dir + "/without.json --iterations 2 --out " + dir + "/run");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("differs from the one stored in"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("scenarios (requested absent, stored [{"), std::string::npos) << result.output;
  result = runCli("optimize --resume --config " + dir +
                  "/with.json --iterations 2 --set rod.modeCount=3 --out " + dir + "/run");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("rod.modeCount (requested 3, stored 2)"), std::string::npos) << result.output;
  // The fingerprint of the agreed configuration is in the results file; verify reports it.
  result = runCli("verify " + dir + "/run");
  EXPECT_EQ(result.exitCode, 0) << result.output;
  EXPECT_NE(result.output.find("configuration fingerprint fnv1a64:"), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("agreed by 1 rank(s)"), std::string::npos) << result.output;

  // export: a negative --iteration is an error (it exported the last one).
  for (const char* iteration : {"-2", "-1", "5"}) {
    result = runCli("export " + dir + "/run --iteration " + iteration + " --out " + dir + "/shape");
    EXPECT_EQ(result.exitCode, 2) << iteration << "\n" << result.output;
    EXPECT_NE(result.output.find("--iteration " + std::string(iteration) + " must be in [0, 1]"),
              std::string::npos)
        << result.output;
  }
  EXPECT_FALSE(fs::exists(dir + "/shape.svg"));
  // plot: not over a run's files without --force, only .png, and never of a corrupted file (exit 3).
  const auto finalPicture = fs::last_write_time(dir + "/run/design_final.png");
  result = runCli("plot " + dir + "/run --out " + dir + "/run/design_final.png");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("exists; use --force"), std::string::npos) << result.output;
  EXPECT_EQ(fs::last_write_time(dir + "/run/design_final.png"), finalPicture);
  result = runCli("plot " + dir + "/run --out " + dir + "/history.svg");
  EXPECT_EQ(result.exitCode, 2) << result.output;
  EXPECT_NE(result.output.find("must name a .png file"), std::string::npos) << result.output;
  fs::create_directories(dir + "/broken");
  fs::copy_file(dir + "/run/results.h5", dir + "/broken/results.h5");
  {
    // A changed attribute (through HDF5, so Fletcher32 cannot see it): the root's content hash does.
    const hid_t file = H5Fopen((dir + "/broken/results.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hid_t attribute = H5Aopen(file, "objective_scale", H5P_DEFAULT);
    ASSERT_GE(attribute, 0);
    const double changed = 12345.0;
    ASSERT_GE(H5Awrite(attribute, H5T_NATIVE_DOUBLE, &changed), 0);
    H5Aclose(attribute);
    H5Fclose(file);
  }
  ASSERT_EQ(runCli("verify " + dir + "/broken").exitCode, 3);
  result = runCli("plot " + dir + "/broken --out " + dir + "/broken.png");
  EXPECT_EQ(result.exitCode, 3) << result.output;
  EXPECT_NE(result.output.find(dir + "/broken/results.h5"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(dir + "/broken.png"));
}
TEST(CliInput, AFileSizeLimitIsAReportedStorageFailure) {
  const std::string dir = freshFolder("ulimit");
  // 4 KiB (ulimit -f counts 512-byte blocks in POSIX sh): the results file does not fit.
  const std::string command =
      "sh -c 'ulimit -f 8; exec " + std::string(HINDSIGHT_CLI_PATH) +
      " optimize --iterations 1 --set rod.elementsAlongLength=8 --set rod.elementsThroughHeight=2"
      " --set rod.modeCount=2 --set rod.endTime=0.02 --set rod.rampTime=0.01"
      " --set rod.eslSamples=4 --set simulation.step=1e-3 --out " +
      dir + "/run' 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) output += buffer;
  const int status = pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status)) << "ended by a signal (SIGXFSZ?): " << output;
  EXPECT_EQ(WEXITSTATUS(status), 3) << output;
  EXPECT_NE(output.find("results.h5"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(dir + "/run/results.h5"));
}
#endif

}  // namespace
}  // namespace hindsight
