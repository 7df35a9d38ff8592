// The configuration's one table (problems/app/config_schema.h) drives the reader, --set, the flags,
// `hindsight config` and the tables of docs/reference/cli.md; these tests fail when any of them drifts
// from it. With HINDSIGHT_REGENERATE=1 in the environment the documentation test rewrites the page's
// tables from the table instead (then review the diff and commit it).
#include <hindsight/problems/app/config.h>
#include <hindsight/problems/app/config_schema.h>

#include "support/engine_fixtures.h"
#include "support/generated_text.h"
#include "support/run_cli.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <set>
#include <sstream>
#include <string>

namespace hindsight {
namespace {

namespace fs = std::filesystem;
using testing::generatedSectionMatches;
using testing::invalidArgumentMessage;

const fs::path kSource = HINDSIGHT_SOURCE_DIR;
constexpr const char* kBegin = "<!-- config-fields: generated from problems/app/config_schema.h -->\n";
constexpr const char* kEnd = "<!-- config-fields: end -->\n";

std::string textOf(double x) {
  std::ostringstream out;
  out.precision(17);
  out << x;
  return out.str();
}

TEST(ConfigSchema, DocumentationTableIsGeneratedFromTheTable) {
  EXPECT_TRUE(generatedSectionMatches(kSource / "docs/reference/cli.md", kBegin, kEnd, configFieldsMarkdown(),
                                      "the configuration's table (problems/app/config_schema.h)"));
}

// The table names exactly the fields the configuration writes: a member added to Config without a row
// (or a row without a member) is caught here.
TEST(ConfigSchema, RowsAreExactlyTheFieldsOfTheConfiguration) {
  Config config;
  config.optimization.aggregate = Aggregate::Max;  // written only when it matters
  const nlohmann::json json = toJson(config);
  std::set<std::string> written;
  for (const auto& [section, fields] : json.items()) {
    for (const auto& [name, value] : fields.items()) written.insert(section + "." + name);
  }
  std::set<std::string> rows;
  for (const ConfigField& f : configFields()) {
    EXPECT_TRUE(rows.insert(f.key).second) << "two rows for " << f.key;
    EXPECT_FALSE(f.description.empty()) << f.key;
    EXPECT_EQ(&findConfigField(f.key), &f);
  }
  EXPECT_EQ(rows, written);
}

// Every default is a value its own row accepts, and setting it through --set changes nothing.
TEST(ConfigSchema, EveryDefaultLiesInItsRowsRangeAndRoundTrips) {
  const Config defaults;
  const nlohmann::json before = toJson(defaults);
  for (const ConfigField& f : configFields()) {
    Config config;
    const nlohmann::json value = f.get(defaults);
    const std::string text = value.is_string() ? value.get<std::string>() : value.dump();
    EXPECT_NO_THROW(applySetting(config, f.key + "=" + text)) << f.key << " = " << text;
    EXPECT_EQ(toJson(config), before) << f.key;
  }
}

// Each row's range is the one the reader enforces, and the message names the field and the row's
// allowed values: a value just outside each finite bound is refused, the bounds themselves follow the
// row's open/closed ends, and a name outside a choice row's list is refused with the list.
TEST(ConfigSchema, ReaderEnforcesEveryRowsRangeAndNamesIt) {
  int checked = 0;
  for (const ConfigField& f : configFields()) {
    const std::string who = "config field '" + f.key + "'";
    std::vector<std::string> refused;
    if (f.type == ConfigFieldType::real) {
      refused.push_back(textOf(f.lower - 1.0));
      if (f.lowerOpen) refused.push_back(textOf(f.lower));
      if (std::isfinite(f.upper)) refused.push_back(textOf(f.upper + 1.0));
      refused.push_back("\"text\"");
    } else if (f.type == ConfigFieldType::integer) {
      refused.push_back(std::to_string(static_cast<long>(f.lower) - 1));
      refused.push_back(std::to_string(static_cast<long>(f.upper) + 1));
      refused.push_back("1.5");
    } else if (f.type == ConfigFieldType::choice) {
      refused.push_back("no-such-name");
    } else if (f.type == ConfigFieldType::boolean) {
      refused.push_back("2");
    }
    for (const std::string& text : refused) {
      Config config;
      const std::string message = invalidArgumentMessage([&] {
        // validate = false: only the row's own check may refuse it
        applySetting(config, f.key + "=" + text, /*validate=*/false);
      });
      EXPECT_EQ(message.rfind(who + " = " + text, 0), 0u) << f.key << "=" << text << ": " << message;
      if (f.type != ConfigFieldType::boolean)
        EXPECT_NE(message.find(f.allowed()), std::string::npos) << f.key << "=" << text << ": " << message;
      ++checked;
    }
    if (f.type == ConfigFieldType::real || f.type == ConfigFieldType::integer) {
      // The closed bounds are accepted by the row (the checks across fields may still refuse them).
      Config config;
      if (!f.lowerOpen) {
        EXPECT_NO_THROW(applySetting(config, f.key + "=" + textOf(f.lower), false)) << f.key;
      }
      if (std::isfinite(f.upper)) {
        EXPECT_NO_THROW(applySetting(config, f.key + "=" + textOf(f.upper), false)) << f.key;
      }
    }
  }
  EXPECT_GT(checked, 100);
}

TEST(ConfigSchema, AllowedValuesAreShownAsTheMessagesSayThem) {
  EXPECT_EQ(findConfigField("rod.modeCount").allowed(), "[1, 40]");
  EXPECT_EQ(findConfigField("optimization.moveLimit").allowed(), "(0, 1]");
  EXPECT_EQ(findConfigField("rod.length").allowed(), "(0, inf]");
  EXPECT_EQ(findConfigField("simulation.adjoint").allowed(), "discrete, continuous, cvodes");
  EXPECT_EQ(invalidArgumentMessage([] {
              findConfigField("rod.modes");
            }).rfind("config field 'rod.modes' is unknown; fields of 'rod': ", 0),
            0u);
  EXPECT_EQ(invalidArgumentMessage([] { findConfigField("solver.step"); }),
            "config section 'solver' is unknown; sections: rod, simulation, optimization");
}

#ifdef HINDSIGHT_CLI_PATH
// `hindsight config` prints the table, and every flag that stands for a field is in the --help of the
// command that reads it, with the field's key and allowed values from its row.
TEST(ConfigSchema, ConfigCommandAndFlagsComeFromTheTable) {
  const testing::CliResult listing = testing::runCli("config");
  EXPECT_EQ(listing.exitCode, 0);
  EXPECT_EQ(listing.output, configFieldsText());
  const testing::CliResult markdown = testing::runCli("config --markdown");
  EXPECT_EQ(markdown.exitCode, 0);
  EXPECT_EQ(markdown.output, configFieldsMarkdown());
  const std::string help =
      testing::runCli("evaluate --help").output + testing::runCli("optimize --help").output;
  int flags = 0;
  for (const ConfigField& f : configFields()) {
    if (f.flag.empty()) continue;
    ++flags;
    const std::size_t at = help.find("  " + f.flag + " ");
    ASSERT_NE(at, std::string::npos) << f.flag;
    const std::string line = help.substr(at, help.find('\n', at) - at);
    EXPECT_NE(line.find("(config field " + f.key + ")"), std::string::npos) << line;
    if (f.type != ConfigFieldType::text) EXPECT_NE(line.find(f.allowed()), std::string::npos) << line;
  }
  EXPECT_EQ(flags, 9);
  // A flag's error names the flag and its row's range, exit code 2.
  const testing::CliResult bad = testing::runCli("optimize --move-limit 0 --out /nonexistent/x");
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_NE(bad.output.find("--move-limit = 0 is outside the allowed range (0, 1]"), std::string::npos)
      << bad.output;
}
#endif

}  // namespace
}  // namespace hindsight
