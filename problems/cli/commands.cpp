#include "problems/cli/commands.h"

#include "engine/types.h"

#include <iostream>
#include <stdexcept>

namespace hindsight::cli {

std::vector<Command>& commands() {
  static std::vector<Command> all;
  return all;
}

void registerCommands(CLI::App& app) {
  registerDemo(app);
  registerOptimize(app);
  registerPlot(app);
}

int runSelected(CLI::App& app) {
  for (const Command& command : commands()) {
    if (command.app->parsed()) return command.run();
  }
  std::cerr << app.help();
  return 2;
}

int guarded(const std::function<int()>& body) {
  try {
    return body();
  } catch (const std::invalid_argument& e) {
    std::cerr << "hindsight: error: " << e.what() << '\n';
    return 2;
  } catch (const NumericalError& e) {
    std::cerr << "hindsight: numerical failure: " << e.what() << '\n';
    return 3;
  } catch (const StorageError& e) {
    std::cerr << "hindsight: storage failure: " << e.what() << '\n';
    return 3;
  } catch (const std::exception& e) {
    std::cerr << "hindsight: failure: " << e.what() << '\n';
    return 3;
  }
}

}  // namespace hindsight::cli
