// The fields of a run's configuration: one table from which everything that names them is driven.
//
// Each row of configFields() is one field of the JSON configuration (problems/app/config.h), addressed
// as "section.field": its type, its allowed range or names, its unit, a one-line description and, where
// the command line has one, the flag that stands for it. From this table alone
//   - configFromJson(), `--set section.field=value` and the flags read, range-check and name the field
//     in their errors ("config field 'rod.modeCount' = 0 is outside the allowed range [1, 40]"), and
//     toJson() writes the configuration;
//   - `hindsight config` lists the fields with their defaults (configFieldsText()), and the flags of
//     `hindsight evaluate` and `hindsight optimize` take their help text from their rows;
//   - the table of docs/reference/cli.md is generated (configFieldsMarkdown()); the test
//     ConfigSchema.DocumentationTableIsGeneratedFromTheTable (tests/problems/app/config_schema_test.cpp)
//     fails when the page differs, and HINDSIGHT_REGENERATE=1 app_tests --gtest_filter=ConfigSchema.*
//     rewrites it.
// A default is not a column: it is the value of a default-constructed Config (the member initializers
// of problems/app/config.h and problems/rod/rod_config.h), read through the row, so the listing, the
// page and the parser's starting point cannot disagree.
//
// The range of a row is what one field may hold on its own; checks across fields (endTime >= rampTime,
// an even elementsThroughHeight, the density law's continuity, ...) are Config::validate()'s and
// rod::RodConfig::validate()'s, and the descriptions say where such a check applies. The `scenarios`
// and `mechanism` sections are lists and objects of their own (problems/rod/scenarios.h,
// problems/mechanism/mechanism_json.h), not rows.
#pragma once

#include <hindsight/problems/app/config.h>

#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

namespace hindsight {

enum class ConfigFieldType {
  integer,  ///< a JSON integer in [lower, upper]
  real,     ///< a JSON number in [lower, upper] ((lower, upper] with lowerOpen), finite
  boolean,  ///< true | false
  choice,   ///< one of `choices`
  text      ///< any string (checked where it is used, e.g. a storage spec by the storage factory)
};

struct ConfigField {
  std::string key;  ///< "section.field", as --set and the error messages name it
  ConfigFieldType type;
  double lower = 0.0;  ///< integer and real fields
  double upper = 0.0;
  bool lowerOpen = false;            ///< real fields: lower itself is excluded
  std::vector<std::string> choices;  ///< choice fields: the valid names
  std::string unit;                  ///< SI unit, "1" for a ratio, a count or a name
  std::string description;           ///< one line, as the listing and the documentation show it
  std::string flag;                  ///< the command-line flag that stands for the field, or empty
  /// The field's value in a configuration, as JSON writes it.
  std::function<nlohmann::json(const Config&)> get;
  /// Stores a value that check() accepted.
  std::function<void(Config&, const nlohmann::json&)> set;

  std::string section() const;  ///< "rod" of "rod.modeCount"
  std::string name() const;     ///< "modeCount" of "rod.modeCount"
  /// The allowed values as the messages, the listing and the page show them: "[1, 40]", "(0, inf]",
  /// "true | false", "rk4 | dopri5 | ...", "a storage spec".
  std::string allowed() const;
};

/// Every field, section by section in the order of toJson(): rod, simulation, optimization.
const std::vector<ConfigField>& configFields();

/// The row of `key` ("section.field"); throws std::invalid_argument naming an unknown section (with
/// the sections) or an unknown field (with the fields of its section).
const ConfigField& findConfigField(const std::string& key);

/// The table as plain text for `hindsight config`: one block per section, a line per field with its
/// type, default, allowed values, unit and description (and the flag that stands for it).
std::string configFieldsText();

/// The table as Markdown (one table per section: field, type, default, allowed, unit, description), as
/// docs/reference/cli.md has it between its config-fields markers.
std::string configFieldsMarkdown();

}  // namespace hindsight
