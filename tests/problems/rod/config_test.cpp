#include <hindsight/problems/rod/config.h>

#include <gtest/gtest.h>

#include <fstream>

namespace hindsight {
namespace {

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "<no std::invalid_argument>";
}

TEST(Config, DefaultsRoundTripThroughJsonAndHoldEverySpecNumber) {
  const Config defaults;
  const nlohmann::json json = toJson(defaults);
  EXPECT_EQ(json["rod"]["elementsAlongLength"], 200);
  EXPECT_EQ(json["rod"]["elementsThroughHeight"], 12);
  EXPECT_EQ(json["rod"]["youngsModulus"], 0.5e11);
  EXPECT_EQ(json["rod"]["density"], 8750.0);
  EXPECT_EQ(json["rod"]["massLawFactor"], 1e5);
  EXPECT_EQ(json["rod"]["modeCount"], 10);
  EXPECT_EQ(json["optimization"]["iterations"], 50);
  EXPECT_EQ(json["optimization"]["volumeFraction"], 0.5);
  EXPECT_EQ(toJson(configFromJson(json)), json);
}

TEST(Config, UnknownFieldsWrongTypesAndRangesAreNamed) {
  auto json = toJson(Config{});
  json["rod"]["modeCounts"] = 3;
  const auto unknown = errorOf([&] { configFromJson(json); });
  EXPECT_NE(unknown.find("'rod.modeCounts' is unknown"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("modeCount"), std::string::npos) << unknown;

  json = toJson(Config{});
  json["rod"]["modeCount"] = "ten";
  EXPECT_NE(errorOf([&] { configFromJson(json); }).find("'rod.modeCount' = \"ten\" must be an integer"),
            std::string::npos);
  json["rod"]["modeCount"] = 0;
  const auto range = errorOf([&] { configFromJson(json); });
  EXPECT_NE(range.find("'rod.modeCount' = 0 is outside the allowed range [1, 40]"), std::string::npos)
      << range;

  json = toJson(Config{});
  json["optimization"]["volumeFraction"] = 1.0;
  EXPECT_NE(errorOf([&] { configFromJson(json); }).find("optimization.volumeFraction"), std::string::npos);
  json = toJson(Config{});
  json["simulation"]["adjoint"] = "backwards";
  EXPECT_NE(errorOf([&] { configFromJson(json); }).find("discrete, continuous, cvodes"), std::string::npos);
  json = toJson(Config{});
  json["simulation"]["storage"] = "full:every=2";
  EXPECT_NE(errorOf([&] { configFromJson(json); }).find("unknown key 'every'"), std::string::npos);
  EXPECT_NE(errorOf([&] {
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
  EXPECT_NE(errorOf([&] { applySetting(config, "modeCount=3"); }).find("section.field=value"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { applySetting(config, "simulation.integrator=euler"); }).find("rk4"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { applySetting(config, "rod.poissonRatio=0.7"); }).find("rod.poissonRatio"),
            std::string::npos);
}

TEST(Config, UnreadableOrMalformedFilesAreNamed) {
  EXPECT_NE(errorOf([] { readConfigFile("/nonexistent/config.json"); }).find("/nonexistent/config.json"),
            std::string::npos);
  const std::string path = ::testing::TempDir() + "/broken.json";
  std::ofstream(path) << "{ \"rod\": ";
  EXPECT_NE(errorOf([&] { readConfigFile(path); }).find("not valid JSON"), std::string::npos);
}

}  // namespace
}  // namespace hindsight
