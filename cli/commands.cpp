#include "commands.h"

#include <hindsight/engine/dense_blocking.h>
#include <hindsight/engine/types.h>
#include <hindsight/problems/app/config_schema.h>
#include <hindsight/problems/rod/compensated_kernels.h>

#include <cstdlib>
#include <iostream>
#include <stdexcept>

namespace hindsight::cli {

std::vector<Command>& commands() {
  static std::vector<Command> all;
  return all;
}

void registerCommands(CLI::App& app) {
  registerDemo(app);
  registerEvaluate(app);
  registerOptimize(app);
  registerPlot(app);
  registerVerify(app);
  registerExport(app);
  registerSchedule(app);
  registerConfig(app);
}

void ConfigFlags::add(CLI::App* app, const std::string& key, const std::string& note) {
  const ConfigField& field = findConfigField(key);
  if (field.flag.empty()) throw std::logic_error("ConfigFlags::add: config field " + key + " has no flag");
  const std::string defaultValue = [&] {
    const nlohmann::json value = field.get(Config{});
    return value.is_string() ? value.get<std::string>() : value.dump();
  }();
  std::string help = field.description;
  if (field.type == ConfigFieldType::choice) help += "; one of " + field.allowed();
  if (field.type == ConfigFieldType::integer || field.type == ConfigFieldType::real)
    help += "; in " + field.allowed();
  help += "; default " + defaultValue + note + " (config field " + key + ")";
  const char* typeName = field.type == ConfigFieldType::integer ? "INT"
                         : field.type == ConfigFieldType::real  ? "FLOAT"
                         : key == "simulation.storage"          ? "STORAGE"
                                                                : "TEXT";
  Entry& entry = entries_.emplace_back(Entry{field.flag, key, "", nullptr});
  entry.option = app->add_option(field.flag, entry.text, help)->type_name(typeName);
}

void ConfigFlags::apply(Config& config) const {
  for (const Entry& entry : entries_) {
    if (entry.option->count() > 0) applyFlag(config, entry.flag, entry.key, entry.text, /*validate=*/false);
  }
}

bool ConfigFlags::given(const std::string& flag) const {
  for (const Entry& entry : entries_) {
    if (entry.flag == flag) return entry.option->count() > 0;
  }
  throw std::logic_error("ConfigFlags::given: no flag " + flag);
}

int runSelected(CLI::App& app) {
  // HINDSIGHT_KERNELS is read once per process: a wrong value stops the command before it starts (exit
  // 2, naming the variable), not in the middle of a run that has begun writing its results.
  // HINDSIGHT_EMULATE_CPU_CACHES likewise (engine/dense_blocking.h): the loader has already applied a
  // well-formed value; a malformed one is refused here rather than silently ignored.
  if (const int status = guarded([] {
        rod::defaultKernelIsa();
        emulatedCacheSizesFromSetting(std::getenv("HINDSIGHT_EMULATE_CPU_CACHES"));
        return 0;
      }))
    return status;
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
