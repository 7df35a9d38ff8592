#include <hindsight/problems/app/config.h>

#include <gtest/gtest.h>

#include <fstream>

#include "support/engine_fixtures.h"
#include "support/storage_fixtures.h"

namespace hindsight {
namespace {

using testing::invalidArgumentMessage;

TEST(Config, DefaultsRoundTripThroughJsonAndHoldEverySpecNumber) {
  const Config defaults;
  const nlohmann::json json = toJson(defaults);
  EXPECT_EQ(json["rod"]["elementsAlongLength"], 200);
  EXPECT_EQ(json["rod"]["elementsThroughHeight"], 12);
  EXPECT_EQ(json["rod"]["youngsModulus"], 0.5e11);
  EXPECT_EQ(json["rod"]["density"], 8750.0);
  EXPECT_EQ(json["rod"]["massLawFactor"], 1e5);
  EXPECT_EQ(json["rod"]["modeCount"], 10);
  // The paper's 50 iterations became a cap of 150: the stopping rule ends the run (docs/guides/optimizer.md).
  EXPECT_EQ(json["optimization"]["iterations"], 150);
  EXPECT_EQ(json["optimization"]["method"], "mma-adaptive");
  // The trust region's cap is 0.2, not the 0.5 of Svanberg's note: every ulp-perturbed start then ends
  // within 1 % of the others (docs/guides/optimizer.md); the paper's MMA is asked for with 0.5.
  EXPECT_EQ(json["optimization"]["moveLimit"], 0.2);
  EXPECT_EQ(json["optimization"]["volumeFraction"], 0.5);
  EXPECT_EQ(toJson(configFromJson(json)), json);
}

TEST(Config, UnknownFieldsWrongTypesAndRangesAreNamed) {
  auto json = toJson(Config{});
  json["rod"]["modeCounts"] = 3;
  const auto unknown = invalidArgumentMessage([&] { configFromJson(json); });
  EXPECT_NE(unknown.find("'rod.modeCounts' is unknown"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("modeCount"), std::string::npos) << unknown;

  json = toJson(Config{});
  json["rod"]["modeCount"] = "ten";
  EXPECT_NE(invalidArgumentMessage([&] {
              configFromJson(json);
            }).find("'rod.modeCount' = \"ten\" must be an integer"),
            std::string::npos);
  json["rod"]["modeCount"] = 0;
  const auto range = invalidArgumentMessage([&] { configFromJson(json); });
  EXPECT_NE(range.find("'rod.modeCount' = 0 is outside the allowed range [1, 40]"), std::string::npos)
      << range;

  json = toJson(Config{});
  json["optimization"]["volumeFraction"] = 1.0;
  EXPECT_NE(invalidArgumentMessage([&] { configFromJson(json); }).find("optimization.volumeFraction"),
            std::string::npos);
  json = toJson(Config{});
  json["simulation"]["adjoint"] = "backwards";
  EXPECT_NE(invalidArgumentMessage([&] { configFromJson(json); }).find("discrete, continuous, cvodes"),
            std::string::npos);
  json = toJson(Config{});
  json["simulation"]["storage"] = "full:every=2";
  EXPECT_NE(invalidArgumentMessage([&] { configFromJson(json); }).find("unknown key 'every'"),
            std::string::npos);
  EXPECT_NE(invalidArgumentMessage([&] {
              configFromJson(nlohmann::json{{"model", {}}});
            }).find("section 'model' is unknown"),
            std::string::npos);
}

TEST(Config, SetAssignmentsAreCheckedLikeTheFile) {
  Config config;
  applySetting(config, "rod.modeCount=12");
  applySetting(config, "simulation.integrator=trbdf2");
  applySetting(config, "optimization.volumeFraction=0.4");
  EXPECT_EQ(config.rod.modeCount, 12);
  EXPECT_EQ(config.simulation.integrator, "trbdf2");
  EXPECT_EQ(config.optimization.volumeFraction, 0.4);
  EXPECT_NE(invalidArgumentMessage([&] { applySetting(config, "modeCount=3"); }).find("section.field=value"),
            std::string::npos);
  EXPECT_NE(invalidArgumentMessage([&] { applySetting(config, "simulation.integrator=euler"); }).find("rk4"),
            std::string::npos);
  EXPECT_NE(
      invalidArgumentMessage([&] { applySetting(config, "rod.poissonRatio=0.7"); }).find("rod.poissonRatio"),
      std::string::npos);
  applySetting(config, "simulation.integrator=generalized-alpha");
  EXPECT_NE(invalidArgumentMessage([&] {
              applySetting(config, "simulation.rhoInfinity=1.5");
            }).find("'simulation.rhoInfinity' = 1.5 is outside the allowed range [0, 1]"),
            std::string::npos);
}

// {"extra": {}} used to be accepted (an empty unknown section was never looked up), {"rod": 5} was
// reported as the unknown field 'rod.', and 1e-400 was reported as the 0.0 it parses to.
TEST(Config, SectionsAreCheckedByNameAndShapeAndValuesAreReportedAsWritten) {
  const auto extra =
      invalidArgumentMessage([] { configFromJson(nlohmann::json::parse(R"({"extra": {}})")); });
  EXPECT_NE(extra.find("section 'extra' is unknown; sections: rod, simulation, optimization"),
            std::string::npos)
      << extra;
  const auto scalar = invalidArgumentMessage([] { configFromJson(nlohmann::json::parse(R"({"rod": 5})")); });
  EXPECT_NE(scalar.find("section 'rod' = 5 must be a JSON object"), std::string::npos) << scalar;
  Config config;
  const auto tiny = invalidArgumentMessage([&] { applySetting(config, "simulation.step=1e-400"); });
  EXPECT_NE(tiny.find("'simulation.step' = 1e-400 is outside the range of a double (it underflows to 0)"),
            std::string::npos)
      << tiny;
  EXPECT_NE(tiny.find("(0, 1]"), std::string::npos) << tiny;
  const auto huge = invalidArgumentMessage([&] { applySetting(config, "rod.length=1e400"); });
  EXPECT_NE(huge.find("'rod.length' = 1e400 is outside the range of a double (it overflows)"),
            std::string::npos)
      << huge;
  EXPECT_EQ(config.simulation.step, Config{}.simulation.step);
}

// A command-line flag is its config field: the same checks, the message names the flag and range.
TEST(Config, FlagsAreCheckedAsTheirFieldsAndNamed) {
  Config config;
  applyFlag(config, "--move-limit", "optimization.moveLimit", "0.1");
  applyFlag(config, "--storage", "simulation.storage", "binomial:checkpoints=20");
  EXPECT_EQ(config.optimization.moveLimit, 0.1);
  EXPECT_EQ(config.simulation.storage, "binomial:checkpoints=20");
  const struct {
    const char* flag;
    const char* key;
    const char* text;
    const char* message;
  } cases[] = {
      {"--iterations", "optimization.iterations", "-1",
       "--iterations = -1 is outside the allowed range [0, 100000]"},
      {"--iterations", "optimization.iterations", "2.5",
       "--iterations = 2.5 must be an integer in [0, 100000]"},
      {"--move-limit", "optimization.moveLimit", "0", "--move-limit = 0 is outside the allowed range (0, 1]"},
      {"--move-limit", "optimization.moveLimit", "nan", "--move-limit = nan must be a number in (0, 1]"},
      {"--filter-radius", "optimization.filterRadius", "-1",
       "--filter-radius = -1 is outside the allowed range [0, 1000]"},
      {"--picture-every", "optimization.pictureEvery", "-2",
       "--picture-every = -2 is outside the allowed range [0, 100000]"},
      {"--objective", "optimization.objective", "psi3", "--objective = psi3 must be one of: psi1, psi2"},
      {"--storage", "simulation.storage", "5", "unknown storage strategy"},
  };
  for (const auto& c : cases) {
    const auto message = invalidArgumentMessage([&] { applyFlag(config, c.flag, c.key, c.text); });
    EXPECT_NE(message.find(c.message), std::string::npos) << c.flag << " " << c.text << ": " << message;
  }
  EXPECT_EQ(config.optimization.moveLimit, 0.1);
  EXPECT_EQ(config.optimization.iterations, 150);
}

// The choices are enums in C++ and the same strings in JSON (--print-config is unchanged).
TEST(Config, ChoicesAreEnumsWithTheirJsonNames) {
  const nlohmann::json defaults = toJson(Config{});
  EXPECT_EQ(defaults["simulation"]["adjoint"], "discrete");
  EXPECT_EQ(defaults["simulation"]["eigenvectorRoute"], "adjoint-nelson");
  EXPECT_EQ(defaults["simulation"]["model"], "reduced");
  EXPECT_EQ(defaults["optimization"]["objective"], "psi1");
  Config config;
  applySetting(config, "simulation.adjoint=cvodes");
  applySetting(config, "simulation.eigenvectorRoute=nelson");
  applySetting(config, "simulation.model=full");
  applySetting(config, "optimization.objective=psi2");
  EXPECT_EQ(config.simulation.adjoint, AdjointMethod::Cvodes);
  EXPECT_EQ(config.simulation.eigenvectorRoute, rod::EigenvectorSensitivityMethod::NelsonPerVariable);
  EXPECT_EQ(config.simulation.model, RodModel::Full);
  EXPECT_EQ(config.optimization.objective, Objective::Psi2);
  const nlohmann::json json = toJson(config);
  EXPECT_EQ(json["simulation"]["adjoint"], "cvodes");
  EXPECT_EQ(json["simulation"]["eigenvectorRoute"], "nelson");
  EXPECT_EQ(json["simulation"]["model"], "full");
  EXPECT_EQ(json["optimization"]["objective"], "psi2");
  EXPECT_EQ(toJson(configFromJson(json)), json);
  for (const char* name : {"psi1", "psi2"}) EXPECT_EQ(toString(parseObjective(name)), name);
  for (const char* name : {"reduced", "full"}) EXPECT_EQ(toString(parseRodModel(name)), name);
  for (const char* name : {"adjoint-nelson", "nelson"})
    EXPECT_EQ(toString(parseEigenvectorRoute(name)), name);
  EXPECT_NE(invalidArgumentMessage([] { parseObjective("psi3"); }).find("optimization.objective"),
            std::string::npos);
  EXPECT_NE(invalidArgumentMessage([&] {
              applySetting(config, "optimization.objective=psi3");
            }).find("must be one of: psi1, psi2"),
            std::string::npos);
}

TEST(Config, UnreadableOrMalformedFilesAreNamed) {
  EXPECT_NE(invalidArgumentMessage([] {
              readConfigFile("/nonexistent/config.json");
            }).find("/nonexistent/config.json"),
            std::string::npos);
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/broken.json";
  std::ofstream(path) << "{ \"rod\": ";
  EXPECT_NE(invalidArgumentMessage([&] { readConfigFile(path); }).find("not valid JSON"), std::string::npos);
}

}  // namespace
}  // namespace hindsight
