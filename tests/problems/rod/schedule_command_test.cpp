// `hindsight schedule` against `hindsight evaluate` on the rod (reduced model, rk4, 30000 fixed steps,
// 64-byte states, 112 bytes of rhs data per stage: 4 modes, the acceleration and the 4 x 4 Cholesky factor's
// lower triangle): the counters a real gradient run reports equal the schedule's prediction.
#include "support/run_cli.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

#ifdef HINDSIGHT_CLI_PATH
namespace hindsight {
namespace {

using testing::runCli;

const std::string kCoarse =
    "--set rod.elementsAlongLength=20 --set rod.elementsThroughHeight=4 --set rod.modeCount=4 ";

nlohmann::json lastJson(const std::string& output) {
  return nlohmann::json::parse(output.substr(output.find('{')));
}

TEST(ScheduleCommand, PredictsTheCountersOfARealRodRun) {
  const std::string dir = ::testing::TempDir() + "/schedule_command";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  for (const std::string storage :
       {std::string("binomial:checkpoints=20"), std::string("full"), std::string("full:stages=1"),
        std::string("binomial:checkpoints=20,stages=1"), std::string("online:checkpoints=20,stages=1"),
        std::string("cams:checkpoints=20"), "multilevel:ram=2KiB,disk=64KiB,costs=1:1:0.2:0.2,dir=" + dir,
        "multilevel:ram=2KiB,disk=1KiB,costs=1:1:0:0,dir=" + dir}) {
    SCOPED_TRACE(storage);
    const std::string gradient = dir + "/g.h5";
    std::filesystem::remove(gradient);
    // RK4 (4 stages, the --stages below): the schedule tool counts explicit stage evaluations.
    const auto run = runCli("evaluate " + kCoarse +
                            "--set simulation.integrator=rk4 --set simulation.step=1e-4 --storage " +
                            storage + " --gradient " + gradient + " --json");
    ASSERT_EQ(run.exitCode, 0) << run.output;
    const nlohmann::json summary = lastJson(run.output)["summary"];
    const std::int64_t steps = summary["steps"].get<std::int64_t>();
    const auto predicted = runCli("schedule --storage " + storage + " --steps " + std::to_string(steps) +
                                  " --state-bytes 64 --stages 4 --stage-bytes 112 --json");
    ASSERT_EQ(predicted.exitCode, 0) << predicted.output;
    const nlohmann::json p = lastJson(predicted.output);
    EXPECT_EQ(p["recomputed_steps"], summary["recomputed_steps"]);
    EXPECT_EQ(p["rhs_evaluations"], summary["rhs_evaluations"]);
    EXPECT_EQ(p["states_stored"], summary["states_stored"]);
    if (storage == "full:stages=1") EXPECT_EQ(p["rhs_evaluations"], 4 * steps);  // no adjoint step evaluates
    // The run's peak also holds the time grid, N + 1 doubles.
    EXPECT_EQ(p["peak_ram_bytes"].get<std::int64_t>() + (steps + 1) * 8,
              summary["peak_bytes_in_memory"].get<std::int64_t>());
    if (storage.rfind("multilevel", 0) == 0) {
      EXPECT_DOUBLE_EQ(p["schedule_cost"].get<double>(), summary["predicted_storage_seconds"].get<double>());
      EXPECT_GT(summary["measured_storage_seconds"].get<double>(), 0.0);
    }
  }
  std::filesystem::remove_all(dir);
}

TEST(ScheduleCommand, BadFlagsNameTheFlagAndTheRange) {
  const auto steps = runCli("schedule --storage full --steps 2.5 --state-bytes 64");
  EXPECT_EQ(steps.exitCode, 2);
  EXPECT_NE(steps.output.find("--steps"), std::string::npos) << steps.output;
  const auto bytes = runCli("schedule --storage full --steps 10 --state-bytes 12");
  EXPECT_EQ(bytes.exitCode, 2);
  EXPECT_NE(bytes.output.find("--state-bytes"), std::string::npos) << bytes.output;
  const auto stages = runCli("schedule --storage full --steps 10 --state-bytes 64 --stages 0");
  EXPECT_EQ(stages.exitCode, 2);
  EXPECT_NE(stages.output.find("--stages"), std::string::npos) << stages.output;
  for (const char* stageBytes : {"12", "-8", "x"}) {
    const auto rhsData =
        runCli(std::string("schedule --storage full:stages=1 --steps 10 --state-bytes 64 --stage-bytes ") +
               stageBytes);
    EXPECT_EQ(rhsData.exitCode, 2) << stageBytes;
    EXPECT_NE(rhsData.output.find("--stage-bytes"), std::string::npos) << rhsData.output;
  }
  const auto notMultiple =
      runCli("schedule --storage full:stages=1 --steps 10 --state-bytes 64 --stage-bytes 12 --json");
  EXPECT_NE(notMultiple.output.find("must be a multiple of 8"), std::string::npos) << notMultiple.output;
  const auto costs = runCli("schedule --storage full --steps 10 --state-bytes 64 --costs 1:2:3");
  EXPECT_EQ(costs.exitCode, 2);
  EXPECT_NE(costs.output.find("--costs"), std::string::npos) << costs.output;
  const auto needsCosts =
      runCli("schedule --storage multilevel:ram=1KiB,disk=1MiB --steps 1000 --state-bytes 64");
  EXPECT_EQ(needsCosts.exitCode, 2);
  EXPECT_NE(needsCosts.output.find("--costs"), std::string::npos) << needsCosts.output;
  const auto unknown = runCli("schedule --storage revolve:checkpoints=3 --steps 10 --state-bytes 64");
  EXPECT_EQ(unknown.exitCode, 2);
  EXPECT_NE(unknown.output.find("unknown storage strategy"), std::string::npos) << unknown.output;
}

TEST(ScheduleCommand, ActionsAndABillionSteps) {
  const auto actions =
      runCli("schedule --storage binomial:checkpoints=2 --steps 5 --state-bytes 16 --actions");
  ASSERT_EQ(actions.exitCode, 0) << actions.output;
  EXPECT_NE(actions.output.find("restore 0\nload ram 0\n"), std::string::npos) << actions.output;
  const auto billion = runCli(
      "schedule --storage multilevel:ram=64MiB,disk=1TiB,costs=1e-4:2e-4:2e-5:1e-5 --steps 1e9 "
      "--state-bytes 8000 --json");
  ASSERT_EQ(billion.exitCode, 0) << billion.output;
  EXPECT_EQ(lastJson(billion.output)["steps"].get<std::int64_t>(), 1'000'000'000);
}

// --bound: the lower bound on H-Revolve's family (KLevelPlan::lowerBound) below the plan's synchronous
// schedule part, for two and three levels, text and JSON; strategies without one are refused by the flag.
TEST(ScheduleCommand, BoundIsBelowThePlanAndOnlyForMultilevel) {
  const auto three = runCli(
      "schedule --storage 'multilevel:ram=24,levels=ssd:80@1:1;hdd:1600@2:2,costs=1:1' --steps 3000 "
      "--state-bytes 8 --bound --json");
  ASSERT_EQ(three.exitCode, 0) << three.output;
  const nlohmann::json j = lastJson(three.output);
  EXPECT_LE(j["lower_bound"].get<double>(), j["schedule_cost"].get<double>());
  EXPECT_GE(j["lower_bound"].get<double>(), j["schedule_cost"].get<double>() / 1.01);
  const auto two = runCli(
      "schedule --storage multilevel:ram=32,disk=320,costs=1:1:0.5:0.5 --steps 5000 --state-bytes 8 --bound");
  ASSERT_EQ(two.exitCode, 0) << two.output;
  EXPECT_NE(two.output.find("lower bound:"), std::string::npos) << two.output;
  EXPECT_NE(two.output.find("without overlapped I/O"), std::string::npos) << two.output;
  // Levels out of order: the exact programme's plan beats the family (docs/theory/storage.md), and says so.
  const auto outside = runCli(
      "schedule --storage 'multilevel:ram=8,levels=a:32@0.25:3.25;b:16@1.5:0.5,costs=1:1' --steps 65 "
      "--state-bytes 8 --bound");
  ASSERT_EQ(outside.exitCode, 0) << outside.output;
  EXPECT_NE(outside.output.find("lower bound:       166.5"), std::string::npos) << outside.output;
  EXPECT_NE(outside.output.find("151.5 without overlapped I/O, is 9.009 % below it"), std::string::npos)
      << outside.output;
  const auto withActions = runCli(
      "schedule --storage multilevel:ram=32,disk=320,costs=1:1:0.5:0.5 --steps 100 --state-bytes 8 --bound "
      "--actions");
  EXPECT_EQ(withActions.exitCode, 2);
  EXPECT_NE(withActions.output.find("--bound and --actions"), std::string::npos) << withActions.output;
  const auto none = runCli("schedule --storage binomial:checkpoints=3 --steps 100 --state-bytes 8 --bound");
  EXPECT_EQ(none.exitCode, 2);
  EXPECT_NE(none.output.find("--bound"), std::string::npos) << none.output;
  const auto huge = runCli(
      "schedule --storage multilevel:ram=16,disk=800000,costs=1:1:2:2 --steps 1e5 --state-bytes 8 --bound");
  EXPECT_EQ(huge.exitCode, 2);
  EXPECT_NE(huge.output.find("--bound"), std::string::npos) << huge.output;
}

// Inputs are read completely (1e17 is 10^17, not 1), counted without overflow, refused by name with exit 2.
TEST(ScheduleCommand, ExtremeInputsAreReadExactlyOrRefusedByName) {
  const auto big = runCli(
      "schedule --storage binomial:checkpoints=1000 "
      "--steps 1e17 --state-bytes 8 --json");
  ASSERT_EQ(big.exitCode, 0) << big.output;
  EXPECT_EQ(lastJson(big.output)["steps"].get<std::int64_t>(), 100'000'000'000'000'000);
  const auto exact = runCli("schedule --storage full --steps 9.5e3 --state-bytes 8 --json");
  ASSERT_EQ(exact.exitCode, 0) << exact.output;
  EXPECT_EQ(lastJson(exact.output)["steps"].get<std::int64_t>(), 9500);
  struct Case {
    std::string arguments, flag;
  };
  for (const Case& c : std::vector<Case>{
           {"--storage full --steps 1e17x --state-bytes 8", "--steps"},
           {"--storage full --steps 4.1e18 --state-bytes 8", "--steps"},
           {"--storage full --steps 99999999999999999999 --state-bytes 8", "--steps"},
           {"--storage full --steps 10 --state-bytes 8 --stages 2.5", "--stages"},
           {"--storage full --steps 10 --state-bytes 8 --stages 1e3", "--stages"},
           // once a division by zero (an int of doubles per state overflowing)
           {"--storage full --steps 10 --state-bytes 4GiB", "full.budget"},
           {"--storage full --steps 10 --state-bytes 1152921504606846976", "--state-bytes"},
           {"--storage binomial:checkpoints=2 --steps 4e18 --state-bytes 8", "recomputed steps"},
           {"--storage full --steps 10 --state-bytes 8 --costs 1e308:1:0:0", "--costs"},
           {"--storage full --steps 100000000 --state-bytes 8 --actions", "--actions"}}) {
    SCOPED_TRACE(c.arguments);
    const auto run = runCli("schedule " + c.arguments);
    EXPECT_EQ(run.exitCode, 2) << run.output;
    EXPECT_NE(run.output.find(c.flag), std::string::npos) << run.output;
  }
  // --actions of cams follows --stages: records with rk4's 4 stages, none with one stage.
  const auto rk4 =
      runCli("schedule --storage cams:checkpoints=6 --steps 60 --state-bytes 16 --stages 4 --actions");
  const auto euler =
      runCli("schedule --storage cams:checkpoints=6 --steps 60 --state-bytes 16 --stages 1 --actions");
  ASSERT_EQ(rk4.exitCode, 0) << rk4.output;
  ASSERT_EQ(euler.exitCode, 0) << euler.output;
  EXPECT_NE(rk4.output.find("store ram record"), std::string::npos);
  EXPECT_EQ(euler.output.find("store ram record"), std::string::npos);
}

}  // namespace
}  // namespace hindsight
#endif
