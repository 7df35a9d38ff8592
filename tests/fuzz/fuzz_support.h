// Deterministic fuzzing for gtest: seeds stored in tests/fuzz/seeds/, mutated by a std::mt19937_64
// with a fixed seed, so that every run (and every CI run) feeds the same inputs and a failure names
// an input that reproduces it. The number of cases bounds the time; HINDSIGHT_FUZZ_SCALE=k runs k
// times as many cases and HINDSIGHT_FUZZ_SEED=n other inputs, for longer hunts by hand:
//   HINDSIGHT_FUZZ_SCALE=50 HINDSIGHT_FUZZ_SEED=7 build-asan/tests/fuzz_tests
// These tests matter most under AddressSanitizer + UBSan (docs/guides/testing.md, "Sanitizers and fuzzing"),
// where an out-of-bounds read that happens not to crash is still reported.
#pragma once

#include "support/text_files.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#ifndef HINDSIGHT_FUZZ_SEEDS
#error "HINDSIGHT_FUZZ_SEEDS (the tests/fuzz/seeds directory) must be defined by the build"
#endif

namespace hindsight::fuzz {

/// Cases per test: `base` times HINDSIGHT_FUZZ_SCALE (default 1).
inline int cases(int base) {
  const char* scale = std::getenv("HINDSIGHT_FUZZ_SCALE");
  const int k = scale != nullptr ? std::max(1, std::atoi(scale)) : 1;
  return base * k;
}

/// The generator's seed: fixed unless HINDSIGHT_FUZZ_SEED is set; `salt` keeps tests independent.
inline std::uint64_t seed(std::uint64_t salt) {
  const char* text = std::getenv("HINDSIGHT_FUZZ_SEED");
  const std::uint64_t base = text != nullptr ? std::strtoull(text, nullptr, 10) : 20261123;
  return base * 0x9E3779B97F4A7C15ull + salt;
}

using testing::readText;
using testing::writeText;

/// The seed files seeds/PREFIX* in name order (the order must not depend on the file system).
inline std::vector<std::string> seedFiles(const std::string& prefix) {
  std::vector<std::filesystem::path> paths;
  for (const auto& entry : std::filesystem::directory_iterator(HINDSIGHT_FUZZ_SEEDS)) {
    if (entry.path().filename().string().rfind(prefix, 0) == 0) paths.push_back(entry.path());
  }
  std::sort(paths.begin(), paths.end());
  std::vector<std::string> texts;
  for (const auto& path : paths) texts.push_back(readText(path));
  return texts;
}

/// The non-empty lines of seeds/NAME that do not start with '#'.
inline std::vector<std::string> seedLines(const std::string& name) {
  std::istringstream in(readText(std::filesystem::path(HINDSIGHT_FUZZ_SEEDS) / name));
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line[0] != '#') lines.push_back(line);
  }
  return lines;
}

/// A printable form of an input for failure messages (binary bytes as \xNN).
inline std::string printable(const std::string& text, std::size_t limit = 400) {
  std::string out;
  static const char* hex = "0123456789abcdef";
  for (std::size_t i = 0; i < text.size() && i < limit; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c >= 32 && c < 127) {
      out += static_cast<char>(c);
    } else {
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  }
  if (text.size() > limit) out += "...(" + std::to_string(text.size()) + " bytes)";
  return out;
}

/// Byte-level mutations in the style of libFuzzer's: bit flips, random and "interesting" bytes,
/// insertion of dictionary tokens (the parser's own vocabulary reaches deeper than random bytes),
/// erasure, duplication and truncation of ranges.
class Mutator {
 public:
  explicit Mutator(std::uint64_t seed) : rng_(seed) {}

  std::mt19937_64& rng() { return rng_; }
  /// Uniform in [0, n); 0 when n == 0.
  std::size_t below(std::size_t n) {
    return n == 0 ? 0 : std::uniform_int_distribution<std::size_t>(0, n - 1)(rng_);
  }
  bool chance(double p) { return std::uniform_real_distribution<double>(0.0, 1.0)(rng_) < p; }
  template <typename T>
  const T& pick(const std::vector<T>& items) {
    return items[below(items.size())];
  }

  /// 1 to `maxRounds` mutations of `text`.
  std::string mutate(std::string text, const std::vector<std::string>& dictionary, int maxRounds = 4) {
    const int rounds = 1 + static_cast<int>(below(static_cast<std::size_t>(maxRounds)));
    for (int r = 0; r < rounds; ++r) mutateOnce(text, dictionary);
    return text;
  }

 private:
  void mutateOnce(std::string& text, const std::vector<std::string>& dictionary) {
    static const unsigned char interesting[] = {0,   1,   0x7f, 0x80, 0xff, '"', '\\',
                                                ',', '=', ':',  '.',  '{',  '}'};
    const std::size_t n = text.size();
    switch (below(8)) {
      case 0:  // flip one bit
        if (n > 0) text[below(n)] ^= static_cast<char>(1u << below(8));
        break;
      case 1:  // a random byte
        if (n > 0) text[below(n)] = static_cast<char>(below(256));
        break;
      case 2:  // an interesting byte
        if (n > 0) text[below(n)] = static_cast<char>(interesting[below(sizeof interesting)]);
        break;
      case 3:  // insert a dictionary token
      case 4:
        if (!dictionary.empty()) text.insert(below(n + 1), pick(dictionary));
        break;
      case 5: {  // erase a range
        if (n == 0) break;
        const std::size_t at = below(n);
        text.erase(at, 1 + below(std::min<std::size_t>(n - at, 16)));
        break;
      }
      case 6: {  // duplicate a range
        if (n == 0) break;
        const std::size_t at = below(n);
        const std::string piece = text.substr(at, 1 + below(std::min<std::size_t>(n - at, 16)));
        text.insert(below(n + 1), piece);
        break;
      }
      default:  // truncate
        text.resize(below(n + 1));
        break;
    }
  }

  std::mt19937_64 rng_;
};

}  // namespace hindsight::fuzz
