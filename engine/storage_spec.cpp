#include <hindsight/engine/storage_spec.h>

#include <hindsight/engine/trajectory_storage.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace hindsight {
namespace {

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

}  // namespace

StorageSpec StorageSpec::parse(const std::string& text) {
  StorageSpec spec;
  // A control character (a NUL from a JSON "\u0000", a tab) would be echoed into the messages below,
  // and a NUL ends what.(): the message would stop before it names the key and the valid ones.
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7f) {
      static const char* hex = "0123456789abcdef";
      throw std::invalid_argument("storage spec '" + text.substr(0, i) +
                                  "...' has a control character (byte 0x" + hex[c >> 4] + hex[c & 15] +
                                  ") at position " + std::to_string(i) +
                                  "; a spec is printable text such as binomial:checkpoints=50");
    }
  }
  const auto colon = text.find(':');
  spec.name_ = text.substr(0, colon);
  if (spec.name_.empty()) throw std::invalid_argument("storage spec '" + text + "' has no strategy name");
  if (colon == std::string::npos) return spec;
  std::stringstream rest(text.substr(colon + 1));
  std::string item;
  while (std::getline(rest, item, ',')) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size()) {
      throw std::invalid_argument("storage spec '" + text + "': '" + item + "' is not of the form key=value");
    }
    const std::string key = item.substr(0, eq);
    if (!spec.values_.emplace(key, item.substr(eq + 1)).second) {
      throw std::invalid_argument("storage spec '" + text + "': key '" + key + "' given twice");
    }
  }
  return spec;
}

std::int64_t StorageSpec::bytes(const std::string& key, std::int64_t fallback) const {
  const auto it = values_.find(key);
  return it == values_.end() ? fallback : parseBytes(it->second, name_ + "." + key);
}

std::int64_t StorageSpec::integer(const std::string& key, std::int64_t fallback, std::int64_t min,
                                  std::int64_t max) const {
  const auto it = values_.find(key);
  if (it == values_.end()) return fallback;
  std::size_t pos = 0;
  long long value = 0;
  try {
    value = std::stoll(it->second, &pos);
  } catch (const std::exception&) {
    pos = 0;
  }
  if (pos == 0 || pos != it->second.size() || value < min || value > max) {
    throw std::invalid_argument(name_ + "." + key + " = '" + it->second + "' must be an integer in [" +
                                std::to_string(min) + ", " + std::to_string(max) + "]");
  }
  return value;
}

double StorageSpec::real(const std::string& key, double fallback, double min, double max) const {
  const auto it = values_.find(key);
  if (it == values_.end()) return fallback;
  std::size_t pos = 0;
  double value = 0.0;
  try {
    value = std::stod(it->second, &pos);
  } catch (const std::exception&) {
    pos = 0;
  }
  if (pos == 0 || pos != it->second.size() || !std::isfinite(value) || value < min || value > max) {
    std::ostringstream range;
    range << "[" << min << ", " << max << "]";
    throw std::invalid_argument(name_ + "." + key + " = '" + it->second + "' must be a number in " +
                                range.str());
  }
  return value;
}

std::string StorageSpec::text(const std::string& key, const std::string& fallback,
                              const std::vector<std::string>& allowed) const {
  const auto it = values_.find(key);
  if (it == values_.end()) return fallback;
  if (!allowed.empty()) {
    bool ok = false;
    for (const auto& a : allowed) ok = ok || a == it->second;
    if (!ok) {
      throw std::invalid_argument(name_ + "." + key + " = '" + it->second +
                                  "' must be one of: " + join(allowed));
    }
  }
  return it->second;
}

void StorageSpec::requireKeysIn(const std::vector<std::string>& validKeys) const {
  for (const auto& [key, value] : values_) {
    bool ok = false;
    for (const auto& valid : validKeys) ok = ok || valid == key;
    if (!ok) {
      throw std::invalid_argument("unknown key '" + key + "' for storage '" + name_ + "'; valid keys: " +
                                  (validKeys.empty() ? std::string("(none)") : join(validKeys)));
    }
  }
}

std::string shortestText(double value) {
  char text[32];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(text, sizeof text, "%.*g", precision, value);
    if (std::strtod(text, nullptr) == value) break;
  }
  return text;
}

}  // namespace hindsight
