// Parsing of storage spec strings "NAME[:key=value,...]" (for example "binomial:checkpoints=20",
// "disk:dir=/tmp/run,level=3"), shared by the factory, the CLI and the benchmarks.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace hindsight {

/// A parsed spec. Typed getters validate the value and throw std::invalid_argument naming
/// "NAME.key", the value and the allowed range.
class StorageSpec {
 public:
  /// Throws std::invalid_argument for a malformed spec (empty name, "key" without "=", duplicate key).
  static StorageSpec parse(const std::string& text);

  const std::string& name() const { return name_; }
  const std::map<std::string, std::string>& values() const { return values_; }
  bool has(const std::string& key) const { return values_.count(key) != 0; }

  std::int64_t bytes(const std::string& key, std::int64_t fallback) const;
  std::int64_t integer(const std::string& key, std::int64_t fallback, std::int64_t min,
                       std::int64_t max) const;
  double real(const std::string& key, double fallback, double min, double max) const;
  std::string text(const std::string& key, const std::string& fallback,
                   const std::vector<std::string>& allowed = {}) const;

  /// Throws std::invalid_argument when a key is not in `validKeys`, listing the valid ones.
  void requireKeysIn(const std::vector<std::string>& validKeys) const;

 private:
  std::string name_;
  std::map<std::string, std::string> values_;
};

/// The shortest text that reads back as `value` ("1e-06", "0.25"): a spec's number written back into a
/// spec or a message.
std::string shortestText(double value);

}  // namespace hindsight
