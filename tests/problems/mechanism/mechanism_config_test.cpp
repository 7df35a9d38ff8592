// The `mechanism` section of the configuration: the examples read and write back, bad descriptions are
// named, the slider-crank example gives the default configuration's bits (one path), and the
// four-bar's design gradient matches central differences of psi1. Scenarios of a described mechanism set
// its drivers and gravity (problems/rod/scenarios.h): read and written back, bad ones named, and the
// described slider-crank's scenario gives the default slider-crank's scenario of the same crank.
#include <hindsight/problems/app/config.h>
#include <hindsight/problems/app/piston_rod.h>
#include <hindsight/problems/mechanism/mechanism_json.h>

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

namespace hindsight {
namespace {

std::string example(const std::string& name) {
  return std::string(HINDSIGHT_EXAMPLES_DIR) + "/mechanisms/" + name;
}

void coarsen(Config& c) {
  applySetting(c, "rod.elementsAlongLength=20", false);
  applySetting(c, "rod.elementsThroughHeight=4", false);
  applySetting(c, "rod.modeCount=4", false);
  c.validate();
}

TEST(MechanismConfig, ExamplesReadAndWriteBack) {
  for (const char* name : {"slider_crank.json", "slider_crank_mass.json", "four_bar.json",
                           "four_bar_scenarios.json", "flexible_pendulum.json"}) {
    const Config c = readConfigFile(example(name));
    ASSERT_TRUE(c.mechanism.has_value()) << name;
    const Config again = configFromJson(toJson(c));
    EXPECT_EQ(toJson(again).dump(), toJson(c).dump()) << name;
  }
}

void expectMessage(const std::function<void(nlohmann::json&)>& edit, const std::string& expected) {
  std::ifstream in(example("four_bar.json"));
  nlohmann::json j = nlohmann::json::parse(in);
  edit(j);
  try {
    configFromJson(j);
    ADD_FAILURE() << "accepted; expected: " << expected;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
  }
}

TEST(MechanismConfig, BadDescriptionsAreNamed) {
  expectMessage([](auto& j) { j["mechanism"]["joints"][1]["type"] = "hinge"; },
                "mechanism.joints[crankPin].type = 'hinge' must be one of: revolute, prismatic, fixed");
  expectMessage(
      [](auto& j) { j["mechanism"]["joints"][1]["body2"] = "coupla"; },
      "mechanism.joints[crankPin].body2 = 'coupla' is not a body; bodies: ground, crank, rocker, coupler");
  expectMessage(
      [](auto& j) { j["mechanism"]["joints"][0]["point1"] = "X"; },
      "mechanism.joints[crankBearing].point1 = 'X' is not a point of body 'ground'; its points: O2, O4");
  expectMessage([](auto& j) { j["mechanism"]["rigidBodies"][1]["mass"] = -1.0; },
                "mechanism.rigidBodies[rocker].mass = -1 is outside the allowed range [0, inf)");
  expectMessage([](auto& j) { j["mechanism"]["drivers"].clear(); },
                "so mechanism.free must list 1 coordinate(s), not 0");
  expectMessage([](auto& j) { j["mechanism"]["drivers"][0]["law"] = "sine"; },
                "mechanism.drivers[motor].law = 'sine' must be one of: cycloidal-ramp, constant-speed");
  expectMessage([](auto& j) { j["mechanism"]["drivers"][0]["rampTime"] = 0.0; },
                "mechanism.drivers[motor].rampTime = 0 is outside the allowed range (0, inf)");
  expectMessage([](auto& j) { j["mechanism"]["joints"][0]["colour"] = "red"; },
                "mechanism.joints[crankBearing].colour is not a field");
  expectMessage([](auto& j) { j["mechanism"]["rigidBodies"][0]["name"] = "rocker"; },
                "mechanism.rigidBodies[rocker].name = 'rocker' is used twice");
  expectMessage([](auto& j) { j["simulation"]["model"] = "full"; },
                "with a mechanism section it must be reduced");
  // Positions that cannot be assembled at t = 0 (the rocker far too short to reach the coupler).
  expectMessage(
      [](auto& j) {
        j["mechanism"]["rigidBodies"][1]["points"]["pin"] = {0.01, 0.0};
        j["mechanism"]["rigidBodies"][1]["points"]["O4"] = {-0.01, 0.0};
      },
      "mechanism: the initial positions do not assemble at t = 0");
}

TEST(MechanismConfig, TheSliderCrankExampleIsTheDefaultConfigurationBitForBit) {
  // One path: without a mechanism section the piston rod describes the paper's slider-crank with
  // mechanism::sliderCrank, and examples/mechanisms/slider_crank.json is that description written out, so
  // the two give the same bits. The independent route is the closed form (tests/support/slider_crank.h),
  // held to the description term by term and over a simulation and its adjoint in
  // tests/problems/mechanism/mechanism_problem_test.cpp.
  Config byDefault;
  coarsen(byDefault);
  Config described = readConfigFile(example("slider_crank.json"));
  coarsen(described);
  const PistonRod a(byDefault), b(described);
  const PistonRodEvaluation ea = a.evaluate(a.initialDesign()), eb = b.evaluate(b.initialDesign());
  EXPECT_EQ(eb.psi1, ea.psi1);
  EXPECT_EQ(eb.psi2, ea.psi2);
  EXPECT_TRUE(eb.dpsi1 == ea.dpsi1);
  EXPECT_TRUE(eb.dpsi2 == ea.dpsi2);
}

TEST(MechanismConfig, DescribedSliderCrankGradientHasTheSameBitsFromCheckpoints) {
  // The position solves are functions of (t, sigma) whatever the order of the calls: the forward states
  // recomputed from checkpoints give the bits of the stored ones (the default step and time span, where
  // the integrator's Newton iterations revisit the kept factorisation of the last position solve).
  Config full = readConfigFile(example("slider_crank.json"));
  coarsen(full);
  Config checkpointed = full;
  applySetting(checkpointed, "simulation.storage=binomial:checkpoints=20", false);
  checkpointed.validate();
  PistonRod::Request onlyPsi1;
  onlyPsi1.psi2 = false;
  onlyPsi1.psi2Gradient = false;
  const PistonRod a(full), b(checkpointed);
  const PistonRodEvaluation ea = a.evaluate(a.initialDesign(), onlyPsi1);
  const PistonRodEvaluation eb = b.evaluate(b.initialDesign(), onlyPsi1);
  EXPECT_EQ(ea.psi1, eb.psi1);
  EXPECT_TRUE(ea.dpsi1 == eb.dpsi1) << "largest difference " << (ea.dpsi1 - eb.dpsi1).cwiseAbs().maxCoeff();
}

/// dpsi1/dx of a described mechanism's configuration against central differences of psi1 at a few design
/// variables of the design x_i = 0.4 + 0.3 sin(frequency i).
void expectDesignGradientMatchesCentralDifferences(const Config& c, double frequency,
                                                   std::initializer_list<int> variables) {
  const PistonRod rod(c);
  PistonRod::Request onlyPsi1;
  onlyPsi1.psi2 = false;
  onlyPsi1.psi2Gradient = false;
  Vector x = rod.initialDesign();
  for (int i = 0; i < x.size(); ++i) x(i) = 0.4 + 0.3 * std::sin(frequency * i);
  const PistonRodEvaluation e = rod.evaluate(x, onlyPsi1);
  ASSERT_GT(e.psi1, 0.0);
  PistonRod::Request value = onlyPsi1;
  value.psi1Gradient = false;
  const double scale = e.dpsi1.cwiseAbs().maxCoeff();
  for (int d : variables) {
    const double h = 1e-5;
    Vector plus = x, minus = x;
    plus(d) += h;
    minus(d) -= h;
    const double fd = (rod.evaluate(plus, value).psi1 - rod.evaluate(minus, value).psi1) / (2 * h);
    EXPECT_NEAR(e.dpsi1(d), fd, 1e-5 * scale + 1e-5 * std::abs(fd)) << "design variable " << d;
  }
}

TEST(MechanismConfig, FourBarDesignGradientMatchesCentralDifferences) {
  Config c = readConfigFile(example("four_bar.json"));
  coarsen(c);
  applySetting(c, "rod.rampTime=0.5", false);
  applySetting(c, "rod.endTime=0.8", false);
  applySetting(c, "rod.modeCount=3", false);
  c.validate();
  expectDesignGradientMatchesCentralDifferences(c, 1.7, {0, 9, 30, 47, 71});
}

TEST(MechanismConfig, OpenChainDesignGradientMatchesCentralDifferences) {
  Config c = readConfigFile(example("flexible_pendulum.json"));
  coarsen(c);
  applySetting(c, "rod.modeCount=3", false);
  applySetting(c, "rod.endTime=1.5", false);
  c.validate();
  expectDesignGradientMatchesCentralDifferences(c, 2.3, {2, 17, 40, 63});
}

nlohmann::json withScenarios(const std::string& name, const nlohmann::json& scenarios) {
  std::ifstream in(example(name));
  nlohmann::json j = nlohmann::json::parse(in);
  j["scenarios"] = scenarios;
  return j;
}

TEST(MechanismConfig, ScenariosSetDriversAndGravityAndWriteBack) {
  const Config c = configFromJson(withScenarios("four_bar.json", nlohmann::json::parse(R"([
      {"name": "nominal"},
      {"name": "fast", "drivers": {"motor": {"speed": 20.0, "rampTime": 1.5}}, "endTime": 2.5, "weight": 2},
      {"name": "upright", "gravity": [0.0, -9.81], "drivers": {"motor": {"offset": 0.25}}}])")));
  EXPECT_EQ(toJson(configFromJson(toJson(c))).dump(), toJson(c).dump());
  const std::vector<Config> cases = scenarioConfigs(c);
  ASSERT_EQ(cases.size(), 3u);
  const mechanism::Driver& base = c.mechanism->drivers[0];
  EXPECT_EQ(cases[0].mechanism->drivers[0].law.speed, base.law.speed);
  EXPECT_EQ(cases[0].mechanism->gravity, c.mechanism->gravity);
  EXPECT_EQ(cases[1].mechanism->drivers[0].law.speed, 20.0);
  EXPECT_EQ(cases[1].mechanism->drivers[0].law.rampTime, 1.5);
  EXPECT_EQ(cases[1].mechanism->drivers[0].offset, base.offset);
  EXPECT_EQ(cases[1].rod.endTime, 2.5);
  EXPECT_EQ(cases[2].mechanism->gravity, mechanism::Vec2(0.0, -9.81));
  EXPECT_EQ(cases[2].mechanism->drivers[0].offset, 0.25);
  EXPECT_EQ(cases[2].mechanism->drivers[0].law.speed, base.law.speed);
  for (const Config& one : cases) EXPECT_TRUE(one.scenarios.empty());
}

TEST(MechanismConfig, BadScenariosAreNamed) {
  auto errorOf = [](const nlohmann::json& j) -> std::string {
    try {
      configFromJson(j);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "accepted";
  };
  auto expectError = [&](const std::string& file, const std::string& scenarios, const std::string& expected) {
    const std::string message = errorOf(withScenarios(file, nlohmann::json::parse(scenarios)));
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  };
  expectError("four_bar.json", R"([{"name": "a", "drivers": {"motr": {"speed": 3}}}])",
              "scenarios[0].drivers.motr is not a driver of the mechanism; drivers: motor");
  expectError("four_bar.json", R"([{"name": "a"}, {"name": "b", "crankSpeed": 30}])",
              "scenarios[1].crankSpeed sets the default slider-crank's crank; with a mechanism section");
  expectError(
      "four_bar.json", R"([{"name": "a", "drivers": {"motor": {"torque": 3}}}])",
      "scenarios[0].drivers.motor.torque is unknown; fields of a driver in a scenario: speed, rampTime, "
      "offset");
  expectError("four_bar.json", R"([{"name": "a", "drivers": {"motor": {"rampTime": 0}}}])",
              "scenarios[0].drivers.motor.rampTime = 0 is outside the allowed range (0, inf)");
  expectError("four_bar.json", R"([{"name": "a", "drivers": {}}])",
              "scenarios[0].drivers = {} must be a non-empty object of drivers by name");
  expectError("four_bar.json", R"([{"name": "a", "gravity": [0, -9.81, 0]}])",
              "scenarios[0].gravity = [0,-9.81,0] must be an array [gx, gy] of two numbers");
  expectError("four_bar.json", R"([{"name": "a", "drivers": {"motor": {"speed": "fast"}}}])",
              "scenarios[0].drivers.motor.speed = \"fast\" must be a finite number");
  // rampTime belongs to cycloidal-ramp drivers only.
  nlohmann::json constant = withScenarios(
      "four_bar.json", nlohmann::json::parse(R"([{"name": "a", "drivers": {"motor": {"rampTime": 1}}}])"));
  constant["mechanism"]["drivers"][0]["law"] = "constant-speed";
  constant["mechanism"]["drivers"][0].erase("rampTime");
  EXPECT_NE(
      errorOf(constant).find("scenarios[0].drivers.motor.rampTime: driver 'motor' has law constant-speed; "
                             "rampTime is a field of cycloidal-ramp only"),
      std::string::npos)
      << errorOf(constant);
  // Without a mechanism section, drivers and gravity have nothing to set.
  Config byDefault;
  nlohmann::json plain = toJson(byDefault);
  plain["scenarios"] = nlohmann::json::parse(R"([{"name": "a", "gravity": [0, -9.81]}])");
  EXPECT_NE(
      errorOf(plain).find("scenarios[0].gravity sets a described mechanism and needs a mechanism section"),
      std::string::npos)
      << errorOf(plain);
}

TEST(MechanismConfig, DescribedSliderCrankScenarioGivesTheDefaultScenario) {
  // The same operating case written both ways: the default slider-crank's crankSpeed and rampTime, and
  // the described slider-crank's driver. Both become the same description, so the bits agree.
  Config byDefault;
  coarsen(byDefault);
  nlohmann::json a = toJson(byDefault);
  a["scenarios"] = nlohmann::json::parse(
      R"([{"name": "fast", "crankSpeed": 47.12388980384690, "rampTime": 1.0, "endTime": 1.5}])");
  nlohmann::json b = withScenarios("slider_crank.json", nlohmann::json::parse(R"([{"name": "fast",
      "drivers": {"motor": {"speed": 47.12388980384690, "rampTime": 1.0}}, "endTime": 1.5}])"));
  b["rod"] = a["rod"];
  b["rod"]["rampTime"] = 1.0;  // validated for every configuration (endTime >= rod.rampTime)
  const Config defaultCase = scenarioConfigs(configFromJson(a))[0];
  const Config describedCase = scenarioConfigs(configFromJson(b))[0];
  const PistonRod ra(defaultCase), rb(describedCase);
  const PistonRodEvaluation ea = ra.evaluate(ra.initialDesign()), eb = rb.evaluate(rb.initialDesign());
  const PistonRodEvaluation nominal = PistonRod(byDefault).evaluate(ra.initialDesign());
  EXPECT_GT(ea.psi1, 1.5 * nominal.psi1);  // the scenario really is another operating case
  EXPECT_EQ(eb.psi1, ea.psi1);
  EXPECT_EQ(eb.psi2, ea.psi2);
  EXPECT_TRUE(eb.dpsi1 == ea.dpsi1);
  EXPECT_TRUE(eb.dpsi2 == ea.dpsi2);
}

}  // namespace
}  // namespace hindsight
