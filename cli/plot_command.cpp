// `hindsight plot DIR [DIR2] --out FILE.png`: psi1 over the iterations of one or two optimization runs
// (e.g. the psi1 and the psi2 route, like Fig. 4 of Held, Knüfer & Seifried) drawn by
// problems/topopt/plot_history.py with python3 + matplotlib + h5py. The script's path is compiled in
// (HINDSIGHT_PLOT_SCRIPT); the interpreter is $HINDSIGHT_PYTHON, else /usr/bin/python3 (where the
// Debian packages python3-matplotlib and python3-h5py install), else python3 on the PATH.
// Before plotting, every results file is read with every check of a resume (a corrupted file exits 3
// naming it; a plot of it would show numbers verify rejects); FILE must end in .png and is not
// overwritten without --force (a careless --out DIR/design_final.png would replace a run's picture).
#include <hindsight/problems/topopt/results_file.h>
#include "commands.h"

#include <spawn.h>
#include <sys/wait.h>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>

extern char** environ;

namespace hindsight::cli {
namespace {

struct PlotSettings {
  std::vector<std::string> directories;
  std::string output = "history.png";
  bool force = false;
};

int runPlot(const PlotSettings& s) {
  namespace fs = std::filesystem;
  if (s.directories.empty() || s.directories.size() > 2) {
    throw std::invalid_argument("plot: give one or two result directories");
  }
  for (const std::string& directory : s.directories) {
    if (!fs::exists(fs::path(directory) / "results.h5")) {
      throw std::invalid_argument("plot: '" + directory + "/results.h5' does not exist");
    }
  }
  const fs::path output(s.output);
  if (output.extension() != ".png") {
    throw std::invalid_argument("plot: --out '" + s.output + "' must name a .png file");
  }
  if (fs::exists(output) && !s.force) {
    throw std::invalid_argument("plot: --out '" + s.output + "' exists; use --force to overwrite it");
  }
  for (const std::string& directory : s.directories) {
    readResultsFile((fs::path(directory) / "results.h5").string());  // StorageError (exit 3) naming the file
  }
  const std::string script = HINDSIGHT_PLOT_SCRIPT;
  if (!fs::exists(script)) throw std::invalid_argument("plot: the script " + script + " is missing");
  std::string python = "python3";
  if (const char* chosen = std::getenv("HINDSIGHT_PYTHON"); chosen != nullptr && *chosen != '\0') {
    python = chosen;
  } else if (fs::exists("/usr/bin/python3")) {
    python = "/usr/bin/python3";
  }
  std::vector<std::string> arguments = {python, script};
  for (const std::string& directory : s.directories)
    arguments.push_back((fs::path(directory) / "results.h5").string());
  arguments.push_back("--out");
  arguments.push_back(s.output);
  std::vector<char*> argv;
  for (std::string& argument : arguments) argv.push_back(argument.data());
  argv.push_back(nullptr);
  pid_t child = 0;
  const int status = posix_spawnp(&child, python.c_str(), nullptr, nullptr, argv.data(), environ);
  if (status != 0) throw std::runtime_error("plot: cannot start " + python + ": " + std::strerror(status));
  int exit = 0;
  while (waitpid(child, &exit, 0) < 0) {
    if (errno != EINTR) throw std::runtime_error("plot: waiting for " + python + " failed");
  }
  if (!WIFEXITED(exit) || WEXITSTATUS(exit) != 0) {
    std::cerr << "hindsight: plot: " << python << ' ' << script << " failed\n";
    return 3;
  }
  std::cout << "wrote " << s.output << '\n';
  return 0;
}

}  // namespace

void registerPlot(CLI::App& app) {
  auto s = std::make_shared<PlotSettings>();
  CLI::App* command = app.add_subcommand(
      "plot", "psi1 over the iterations of one or two optimization runs (e.g. the psi1 and the psi2 route)");
  command->add_option("directories", s->directories, "result directories (DIR [DIR2])")
      ->required()
      ->expected(1, 2);
  command->add_option("--out", s->output, "PNG file (.png; not overwritten without --force)")
      ->capture_default_str();
  command->add_flag("--force", s->force, "overwrite the --out file");
  commands().push_back({command, [s] { return guarded([&] { return runPlot(*s); }); }});
}

}  // namespace hindsight::cli
