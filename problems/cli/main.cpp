#include "engine/types.h"

#include <CLI/CLI.hpp>

#include <iostream>

int main(int argc, char** argv) {
  CLI::App app{"hindsight: exact adjoint gradients of flexible multibody systems"};
  app.set_version_flag("--version", std::string("hindsight ") + hindsight::version());
  CLI11_PARSE(app, argc, argv);
  return 0;
}
