// Inputs the configuration readers let escape as JSON library exceptions instead of
// std::invalid_argument (found by the config fuzz test): numbers beyond double (json::out_of_range 406)
// and --set values with invalid UTF-8 (json::type_error 316 while writing the error message).
#include <hindsight/problems/app/config.h>

#include <gtest/gtest.h>

#include <fstream>

#include "support/storage_fixtures.h"

namespace hindsight {
namespace {

TEST(ConfigEdgeInput, NumbersBeyondDoubleAreInvalidArguments) {
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/hindsight_overflow.json";
  std::ofstream(path) << R"({"rod": {"length": 1e400}})";
  try {
    readConfigFile(path);
    ADD_FAILURE() << "1e400 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  Config config;
  EXPECT_THROW(applySetting(config, "rod.length=1e400"), std::invalid_argument);
  EXPECT_THROW(applySetting(config, "rod.length=-1e999"), std::invalid_argument);
}

TEST(ConfigEdgeInput, InvalidUtf8InASettingIsAnInvalidArgument) {
  Config config;
  try {
    applySetting(config, "simulation.model=fu\xecl");
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("simulation.model"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hindsight
