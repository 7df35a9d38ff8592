// Runs the real `hindsight` executable as a user would (tests of the command-line tool): the exit
// code and stdout + stderr. Only where the build defines HINDSIGHT_CLI_PATH (tests/CMakeLists.txt).
#pragma once

#ifdef HINDSIGHT_CLI_PATH

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace hindsight::testing {

struct CliResult {
  int exitCode;
  std::string output;
};

inline CliResult runCli(const std::string& arguments) {
  const std::string command = std::string(HINDSIGHT_CLI_PATH) + " " + arguments + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  std::string output;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) output += buffer;
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

}  // namespace hindsight::testing

#endif
