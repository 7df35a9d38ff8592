// Subcommands of the hindsight tool. Each registers its options on the app and, when selected,
// runs and returns the process exit code. Errors are reported on stderr with exit code 2 (bad input)
// or 3 (numerical or storage failure); nothing half-written is left behind.
#pragma once

#include <hindsight/engine/adjoint.h>
#include <hindsight/problems/app/config.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <deque>
#include <functional>
#include <string>
#include <vector>

namespace hindsight::cli {

struct Command {
  CLI::App* app;
  std::function<int()> run;
};

/// All commands, filled by registerCommands().
std::vector<Command>& commands();
void registerCommands(CLI::App& app);
int runSelected(CLI::App& app);

/// Command-line flags that stand for configuration fields (`--move-limit` is optimization.moveLimit).
/// CLI11 only collects their text; apply() hands the text of every flag that was given to
/// applyFlag(), so a flag accepts exactly what its field accepts (the one validation path of
/// problems/app/config.cpp) and an absent flag leaves the configuration alone -- no sentinel values.
class ConfigFlags {
 public:
  /// Registers on `app` the flag of config field `key` ("section.field"): its name, help text, type and
  /// default come from the field's row (problems/app/config_schema.h); `note` is appended to the help.
  void add(CLI::App* app, const std::string& key, const std::string& note = "");
  /// Applies the given flags in registration order; throws std::invalid_argument naming the flag.
  void apply(Config& config) const;
  bool given(const std::string& flag) const;

 private:
  struct Entry {
    std::string flag, key, text;
    CLI::Option* option = nullptr;
  };
  std::deque<Entry> entries_;  // stable addresses: CLI11 writes into Entry::text
};

/// Runs `body`, translating exceptions into messages and exit codes.
int guarded(const std::function<int()>& body);

void registerDemo(CLI::App& app);
void registerEvaluate(CLI::App& app);
void registerOptimize(CLI::App& app);
void registerPlot(CLI::App& app);
void registerVerify(CLI::App& app);
void registerExport(CLI::App& app);
void registerSchedule(CLI::App& app);
void registerConfig(CLI::App& app);

/// The footer of the --help of a command that reads a configuration: where the fields are listed.
inline constexpr const char* kConfigFieldsFooter =
    "Every configuration field (--set section.field=value), its default and its allowed values: "
    "hindsight config";

}  // namespace hindsight::cli
