// The hindsight command-line tool. Subcommands live in their own files and register here.
#include "commands.h"

#include <hindsight/engine/types.h>
#include <hindsight/problems/topopt/communicator.h>

#include <CLI/CLI.hpp>

#include <iostream>

int main(int argc, char** argv) {
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
    return app.exit(e);
  }
  return hindsight::cli::runSelected(app);
}
