// The hindsight command-line tool. Subcommands live in their own files and register here.
#include "commands.h"

#include <hindsight/engine/types.h>
#include <hindsight/problems/topopt/communicator.h>

#include <CLI/CLI.hpp>

#include <csignal>
#include <iostream>

int main(int argc, char** argv) {
  // A file-size limit (ulimit -f) would end the process by SIGXFSZ without a word; ignored, the write
  // fails with EFBIG like a full disk, and the failure is reported with the file's name (exit 3).
  std::signal(SIGXFSZ, SIG_IGN);
  // MPI for the process's lifetime when started by mpirun; nothing otherwise.
  const hindsight::MpiSession mpi(argc, argv);
  CLI::App app{
      "hindsight: exact adjoint gradients of flexible multibody systems, with interchangeable "
      "trajectory storage"};
  app.set_version_flag("--version", std::string("hindsight ") + hindsight::version());
  app.require_subcommand(1);
  hindsight::cli::registerCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the message (or the help); its own codes (104, 109, ...) would hide that this is
    // bad input, which exits with 2 like every other input error (--help and --version: 0).
    return app.exit(e) == 0 ? 0 : 2;
  }
  return hindsight::cli::runSelected(app);
}
