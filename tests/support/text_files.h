// Whole files as strings for the tests that compare checked-in files, write seeds or damage files: read
// and written in binary mode, so that every byte (a NUL, a CR, a cut in the middle of a character)
// arrives as it was.
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace hindsight::testing {

/// The bytes of `path`; empty when it cannot be read (the caller's comparison then fails).
inline std::string readText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

/// Replaces `path` with exactly `bytes`.
inline void writeText(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace hindsight::testing
