// Subcommands of the hindsight tool. Each registers its options on the app and, when selected,
// runs and returns the process exit code. Errors are reported on stderr with exit code 2 (bad input)
// or 3 (numerical or storage failure); nothing half-written is left behind.
#pragma once

#include <hindsight/engine/adjoint.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <functional>
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

/// Runs `body`, translating exceptions into messages and exit codes.
int guarded(const std::function<int()>& body);

/// The run summary as a JSON object (same keys as RunSummary's fields, snake_case).
nlohmann::json summaryToJson(const RunSummary& summary);

void registerDemo(CLI::App& app);
void registerEvaluate(CLI::App& app);
void registerOptimize(CLI::App& app);
void registerPlot(CLI::App& app);
void registerVerify(CLI::App& app);

}  // namespace hindsight::cli
