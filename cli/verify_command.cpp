// `hindsight verify DIR`: checks DIR/results.h5 as a resume would (problems/topopt/results_file.h:
// Fletcher32 and content hash of every dataset, the run state's hash, the configuration fingerprint
// the MPI ranks agreed on, plausibility of the restored design and MMA state) and prints every object
// checked. Exit 0 when the file is sound, 3 when it is corrupted (the object named), 2 for bad input (no such
// directory, no results.h5 in it). It only reads, so it may run beside an optimize run writing the same
// directory: the atomic write means it sees the last complete file.
#include <hindsight/problems/topopt/results_file.h>
#include "commands.h"

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <stdexcept>

namespace hindsight::cli {
namespace {

int runVerify(const std::string& directory) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(directory))
    throw std::invalid_argument("verify: '" + directory + "' is not a directory");
  const std::string path = (fs::path(directory) / "results.h5").string();
  if (!fs::exists(path)) throw std::invalid_argument("verify: '" + path + "' does not exist");
  const ResultsVerification result = verifyResultsFile(path);  // StorageError (exit 3) when unreadable
  std::cout << path << ": format " << result.formatVersion << ", " << result.completedIterations
            << " completed iterations" << (result.finished ? ", finished" : "") << '\n';
  if (!result.configurationFingerprint.empty()) {
    std::cout << "  configuration fingerprint " << result.configurationFingerprint << ", agreed by "
              << result.ranks << " rank(s)\n";
  }
  for (const ResultsCheck& check : result.checks) {
    std::cout << "  " << std::left << std::setw(30) << (check.object == "/" ? "/ (attributes)" : check.object)
              << (!check.problem.empty() ? "CORRUPTED: " + check.problem
                  : result.checksummed   ? std::string("OK")
                                         : std::string("plausible (no checksum in format 1)"))
              << '\n';
  }
  if (const ResultsCheck* bad = result.firstProblem()) {
    std::cerr << "hindsight: storage failure: " << path
              << " is corrupted: " << (bad->object == "/" ? "the root attributes" : bad->object)
              << " failed its check; do not resume from it\n";
    return 3;
  }
  if (!result.checksummed) {
    std::cout << path
              << ": plausible, but written before checksums (format 1): its values could not be verified\n";
  } else {
    std::cout << path << ": sound (every checksum matches, the state is plausible)\n";
  }
  return 0;
}

}  // namespace

void registerVerify(CLI::App& app) {
  auto directory = std::make_shared<std::string>();
  CLI::App* command = app.add_subcommand(
      "verify", "Check DIR/results.h5 of an optimization run: checksums of every dataset, plausible state");
  command->add_option("directory", *directory, "result directory (of hindsight optimize --out)")->required();
  commands().push_back({command, [directory] { return guarded([&] { return runVerify(*directory); }); }});
}

}  // namespace hindsight::cli
