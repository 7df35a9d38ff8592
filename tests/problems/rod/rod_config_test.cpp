#include <hindsight/problems/rod/rod_config.h>

#include <gtest/gtest.h>

#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace hindsight {
namespace rod {
namespace {

TEST(RodConfig, DefaultsAreTheSpecValuesAndValid) {
  const RodConfig config;
  EXPECT_NO_THROW(config.validate());
  EXPECT_EQ(config.elementsAlongLength, 200);
  EXPECT_EQ(config.elementsThroughHeight, 12);
  EXPECT_EQ(config.designCount(), 2376);  // docs/design.md §2: "the inner 2376 elements"
  EXPECT_DOUBLE_EQ(config.crankSpeed, 10.0 * 3.14159265358979323846);
  EXPECT_EQ(config.eslSamples, 100);
}

// Each case breaks one field; the message must name it.
TEST(RodConfig, InvalidFieldsThrowNamingTheField) {
  const std::vector<std::pair<std::string, std::function<void(RodConfig&)>>> cases = {
      {"elementsAlongLength", [](RodConfig& c) { c.elementsAlongLength = 2; }},
      {"elementsThroughHeight", [](RodConfig& c) { c.elementsThroughHeight = 11; }},
      {"length", [](RodConfig& c) { c.length = 0.0; }},
      {"height", [](RodConfig& c) { c.height = -0.06; }},
      {"thickness", [](RodConfig& c) { c.thickness = std::numeric_limits<double>::quiet_NaN(); }},
      {"youngsModulus", [](RodConfig& c) { c.youngsModulus = -1.0; }},
      {"density", [](RodConfig& c) { c.density = 0.0; }},
      {"poissonRatio", [](RodConfig& c) { c.poissonRatio = 0.5; }},
      {"stiffnessPenalty", [](RodConfig& c) { c.stiffnessPenalty = 0.5; }},
      {"massLawFactor", [](RodConfig& c) { c.massLawFactor = 2e5; }},
      {"massLawExponent", [](RodConfig& c) { c.massLawExponent = 0.0; }},
      {"massLawThreshold", [](RodConfig& c) { c.massLawThreshold = 1.5; }},
      {"designLowerBound", [](RodConfig& c) { c.designLowerBound = 0.0; }},
      {"initialDesign", [](RodConfig& c) { c.initialDesign = 0.001; }},
      {"modeCount", [](RodConfig& c) { c.modeCount = 0; }},
      {"crankRadius", [](RodConfig& c) { c.crankRadius = 1.0; }},
      {"crankSpeed", [](RodConfig& c) { c.crankSpeed = -3.0; }},
      {"rampTime", [](RodConfig& c) { c.rampTime = 0.0; }},
      {"endTime", [](RodConfig& c) { c.endTime = 1.0; }},
      {"eslSamples", [](RodConfig& c) { c.eslSamples = 0; }},
  };
  for (const auto& [field, breakIt] : cases) {
    RodConfig config;
    breakIt(config);
    try {
      config.validate();
      ADD_FAILURE() << "no exception for a bad " << field;
    } catch (const std::invalid_argument& error) {
      const std::string message = error.what();
      EXPECT_NE(message.find("RodConfig." + field + " = "), std::string::npos) << message;
      EXPECT_NE(message.find("allowed range"), std::string::npos) << message;
    }
  }
}

TEST(RodConfig, ContinuousMassLawWithOtherParametersIsAccepted) {
  RodConfig config;
  config.massLawThreshold = 0.2;
  config.massLawExponent = 4.0;
  config.massLawFactor = std::pow(0.2, -3.0);
  EXPECT_NO_THROW(config.validate());
}

}  // namespace
}  // namespace rod
}  // namespace hindsight
