// Fuzzing the configuration readers (problems/app/config.h): configFromJson, readConfigFile and
// applySetting take a user's input, so whatever they are given they must either return a
// configuration that validate()s, holds only finite numbers and survives a JSON round trip, or throw
// std::invalid_argument. Any other exception (a JSON library error, std::out_of_range, bad_alloc)
// would escape the CLI's error handling as an internal error instead of exit code 2 with the field.
#include "fuzz/fuzz_support.h"
#include "support/storage_fixtures.h"

#include <hindsight/problems/app/config.h>

#include <cmath>
#include <limits>

namespace hindsight {
namespace {

using nlohmann::json;

std::string tokenString(const json& value) { return value.dump(); }

// The parser's vocabulary: field names, numbers at and beyond the edges of double and int64, and
// JSON's structural characters.
std::vector<std::string> dictionary() {
  std::vector<std::string> words = {"1e400",
                                    "-1e400",
                                    "1e-400",
                                    "-0",
                                    "0",
                                    "-1",
                                    "1",
                                    "2147483648",
                                    "9223372036854775807",
                                    "9223372036854775808",
                                    "18446744073709551615",
                                    "18446744073709551616",
                                    "NaN",
                                    "Infinity",
                                    "null",
                                    "true",
                                    "false",
                                    "\"\"",
                                    "[]",
                                    "{}",
                                    "{",
                                    "}",
                                    "[",
                                    "]",
                                    ",",
                                    ":",
                                    "\"",
                                    "\\u0000",
                                    "\\ud800",
                                    "0.5",
                                    "1e-308",
                                    "4.9e-324",
                                    "1.7976931348623157e308"};
  const json defaults = toJson(Config{});  // named: items() of a temporary would dangle
  for (const auto& [section, fields] : defaults.items()) {
    words.push_back("\"" + section + "\"");
    for (const auto& [name, value] : fields.items()) words.push_back("\"" + name + "\"");
  }
  return words;
}

// Values for the structured mutations: every JSON type, the numbers at the edges of each field's
// range type, and non-finite doubles (which JSON text cannot carry but a json object can).
std::vector<json> interestingValues() {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<json> values = {json(nullptr),
                              json(true),
                              json(false),
                              json(0),
                              json(-1),
                              json(1),
                              json(2),
                              json(3),
                              json(40),
                              json(41),
                              json(0.5),
                              json(1.0),
                              json(-0.0),
                              json(1e-300),
                              json(1e300),
                              json(std::numeric_limits<double>::denorm_min()),
                              json(std::numeric_limits<double>::max()),
                              json(std::numeric_limits<double>::quiet_NaN()),
                              json(inf),
                              json(-inf),
                              json(std::numeric_limits<int>::max()),
                              json(std::int64_t{1} << 31),
                              json(std::numeric_limits<std::int64_t>::max()),
                              json(std::numeric_limits<std::int64_t>::min()),
                              json(std::numeric_limits<std::uint64_t>::max()),
                              json(std::uint64_t{1} << 63),
                              json(""),
                              json("rk4"),
                              json("trbdf2"),
                              json("full"),
                              json("psi2"),
                              json("binomial:checkpoints=0"),
                              json("disk:dir="),
                              json("lossy:codec=zfp"),
                              json::array(),
                              json::array({1, 2}),
                              json::object(),
                              json::object({{"x", 1}})};
  return values;
}

// The properties of an accepted configuration.
void expectSound(const Config& config, const std::string& input) {
  EXPECT_NO_THROW(config.validate()) << input;
  const json out = toJson(config);
  for (const auto& [section, fields] : out.items()) {
    for (const auto& [name, value] : fields.items()) {
      if (value.is_number_float()) {
        EXPECT_TRUE(std::isfinite(value.get<double>()))
            << section << "." << name << " accepted from " << input;
      }
    }
  }
  try {
    EXPECT_EQ(toJson(configFromJson(out)), out) << input;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "an accepted configuration does not read back: " << e.what() << "\n" << input;
  }
}

// Runs `read`; passes when it returns a sound configuration or throws std::invalid_argument.
template <typename Read>
void expectConfigOrInvalidArgument(Read&& read, const std::string& input) {
  try {
    expectSound(read(), input);
  } catch (const std::invalid_argument& e) {
    EXPECT_GT(std::string(e.what()).size(), 0u) << input;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw " << typeid(e).name() << " (" << e.what()
                  << ") instead of std::invalid_argument for\n"
                  << fuzz::printable(input);
  }
}

TEST(ConfigFuzz, SeedsAreValidConfigurations) {
  const auto seeds = fuzz::seedFiles("config_");
  ASSERT_GE(seeds.size(), 3u);
  for (const std::string& text : seeds)
    EXPECT_NO_THROW(expectSound(configFromJson(json::parse(text)), text)) << text;
  for (const std::string& line : fuzz::seedLines("settings.txt")) {
    Config config;
    EXPECT_NO_THROW(applySetting(config, line)) << line;
  }
}

// Mutated JSON text through readConfigFile: the file reader's own parse-error handling included.
TEST(ConfigFuzz, MutatedJsonFiles) {
  const auto seeds = fuzz::seedFiles("config_");
  const auto words = dictionary();
  fuzz::Mutator mutator(fuzz::seed(1));
  const testing::ScratchDirectory scratch;  // removed with what the test wrote
  const std::string path = scratch.path() + "/hindsight_fuzz_config.json";
  for (int k = 0; k < fuzz::cases(1500); ++k) {
    const std::string text = mutator.mutate(mutator.pick(seeds), words, 6);
    fuzz::writeText(path, text);
    expectConfigOrInvalidArgument([&] { return readConfigFile(path); }, text);
    if (HasFailure()) return;  // the first failing input is the useful one
  }
}

// Structured mutations: valid JSON with fields set to values of every type and edge, unknown fields
// and sections, sections that are not objects.
TEST(ConfigFuzz, RandomFieldValues) {
  const auto seeds = fuzz::seedFiles("config_");
  const json defaults = toJson(Config{});
  const auto values = interestingValues();
  fuzz::Mutator mutator(fuzz::seed(2));
  std::vector<std::pair<std::string, std::string>> fields;
  for (const auto& [section, members] : defaults.items()) {
    for (const auto& [name, value] : members.items()) fields.emplace_back(section, name);
  }
  for (int k = 0; k < fuzz::cases(3000); ++k) {
    json input = json::parse(mutator.pick(seeds));
    const int edits = 1 + static_cast<int>(mutator.below(4));
    for (int e = 0; e < edits; ++e) {
      const auto& [section, name] = mutator.pick(fields);
      if (input.contains(section) && !input[section].is_object()) continue;  // replaced by an earlier edit
      switch (mutator.below(10)) {
        case 0:
          input[section][name + "x"] = 1;  // unknown field
          break;
        case 1:
          input[mutator.chance(0.5) ? "rods" : section] =
              mutator.pick(values);  // unknown or non-object section
          break;
        case 2: {  // a numeric field just outside or inside its range
          const json& old = defaults[section][name];
          if (old.is_number()) input[section][name] = old.get<double>() * (mutator.chance(0.5) ? -1.0 : 1e6);
          break;
        }
        default:
          input[section][name] = mutator.pick(values);
      }
    }
    const std::string text = input.dump();  // NaN and infinity print as null; the input itself holds them
    expectConfigOrInvalidArgument([&] { return configFromJson(input); }, text);
    if (HasFailure()) return;
  }
}

// --set assignments: mutated seed lines and random field/value pairs, each applied to the defaults.
TEST(ConfigFuzz, MutatedSettings) {
  const auto lines = fuzz::seedLines("settings.txt");
  auto words = dictionary();
  for (const auto& line : lines) words.push_back(line.substr(line.find('=')));
  const auto values = interestingValues();
  fuzz::Mutator mutator(fuzz::seed(3));
  for (int k = 0; k < fuzz::cases(3000); ++k) {
    std::string assignment;
    if (mutator.chance(0.5)) {
      assignment = mutator.mutate(mutator.pick(lines), words, 3);
    } else {
      const std::string& line = mutator.pick(lines);
      assignment = line.substr(0, line.find('=') + 1) + tokenString(mutator.pick(values));
    }
    Config config;
    expectConfigOrInvalidArgument(
        [&] {
          applySetting(config, assignment);
          return config;
        },
        assignment);
    if (HasFailure()) return;
  }
}

// Scenario lists (problems/rod/scenarios.h) of any length, with every field set to values of every
// type and edge, duplicate and empty names, unknown fields, and lists that are not lists.
TEST(ConfigFuzz, RandomScenarios) {
  const auto values = interestingValues();
  const std::vector<std::string> fields = {"name",        "crankSpeed", "rampTime", "endTime",
                                           "crankRadius", "weight",     "x"};
  const std::vector<json> names = {json("a"), json("b"), json(""),     json("a"),
                                   json(" "), json(1),   json(nullptr)};
  const std::string seed = fuzz::seedFiles("config_06").at(0);
  fuzz::Mutator mutator(fuzz::seed(4));
  for (int k = 0; k < fuzz::cases(2000); ++k) {
    json input = json::parse(seed);
    if (mutator.chance(0.1)) {
      input["scenarios"] = mutator.pick(values);  // not a list
    } else {
      json list = json::array();
      const std::size_t count = mutator.below(5);
      for (std::size_t i = 0; i < count; ++i) {
        json scenario = json::object();
        if (mutator.chance(0.9)) scenario["name"] = mutator.pick(names);
        const std::size_t set = mutator.below(4);
        for (std::size_t f = 0; f < set; ++f) scenario[mutator.pick(fields)] = mutator.pick(values);
        list.push_back(mutator.chance(0.05) ? mutator.pick(values) : scenario);
      }
      input["scenarios"] = list;
    }
    if (mutator.chance(0.3))
      input["optimization"]["aggregate"] = mutator.chance(0.5) ? json("sum") : mutator.pick(values);
    const std::string text = input.dump();
    expectConfigOrInvalidArgument([&] { return configFromJson(input); }, text);
    if (HasFailure()) return;
  }
}

// Several --set assignments applied together and checked once (the CLI's order-independent path):
// a sound configuration or std::invalid_argument, and the same outcome for the assignments reversed.
TEST(ConfigFuzz, SettingsAppliedTogetherDoNotDependOnTheirOrder) {
  const auto lines = fuzz::seedLines("settings.txt");
  const auto values = interestingValues();
  fuzz::Mutator mutator(fuzz::seed(5));
  for (int k = 0; k < fuzz::cases(1500); ++k) {
    std::vector<std::string> assignments;
    const std::size_t count = 1 + mutator.below(4);
    for (std::size_t i = 0; i < count; ++i) {
      const std::string& line = mutator.pick(lines);
      assignments.push_back(mutator.chance(0.5)
                                ? line
                                : line.substr(0, line.find('=') + 1) + tokenString(mutator.pick(values)));
    }
    const auto apply = [](std::vector<std::string> list) {
      Config config;
      for (const std::string& assignment : list) applySetting(config, assignment, /*validate=*/false);
      config.validate();
      return config;
    };
    std::string input;
    for (const std::string& assignment : assignments) input += assignment + "\n";
    expectConfigOrInvalidArgument([&] { return apply(assignments); }, input);
    // With every field set once the order cannot matter (a field set twice keeps its last value).
    bool distinct = true;
    for (std::size_t i = 0; i < assignments.size(); ++i) {
      for (std::size_t j = i + 1; j < assignments.size(); ++j) {
        distinct = distinct && assignments[i].substr(0, assignments[i].find('=')) !=
                                   assignments[j].substr(0, assignments[j].find('='));
      }
    }
    if (distinct) {
      std::vector<std::string> reversed(assignments.rbegin(), assignments.rend());
      bool forwardOk = true, reverseOk = true;
      json forward, backward;
      try {
        forward = toJson(apply(assignments));
      } catch (const std::invalid_argument&) {
        forwardOk = false;
      }
      try {
        backward = toJson(apply(reversed));
      } catch (const std::invalid_argument&) {
        reverseOk = false;
      }
      EXPECT_EQ(forwardOk, reverseOk) << input;
      if (forwardOk && reverseOk) EXPECT_EQ(forward, backward) << input;
    }
    if (HasFailure()) return;
  }
}

}  // namespace
}  // namespace hindsight
