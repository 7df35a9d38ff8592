#include <hindsight/problems/topopt/run_fingerprint.h>

#include <hindsight/engine/hash.h>
#include <hindsight/problems/topopt/communicator.h>

#include <cstdio>
#include <stdexcept>

namespace hindsight {
namespace {

std::string hashText(const std::string& text) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "fnv1a64:%016llx",
                static_cast<unsigned long long>(fnv1a(text.data(), text.size())));
  return buffer;
}

// A byte string through allGather's doubles (every byte value is exact in a double).
std::vector<double> asDoubles(const std::string& text) {
  std::vector<double> values(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) values[i] = static_cast<unsigned char>(text[i]);
  return values;
}

void collect(const std::string& prefix, const nlohmann::json& a, const nlohmann::json& b,
             std::vector<std::string>& out) {
  if (a.is_object() && b.is_object()) {
    nlohmann::json keys = nlohmann::json::object();
    for (const auto& item : a.items()) keys[item.key()] = true;
    for (const auto& item : b.items()) keys[item.key()] = true;
    for (const auto& item : keys.items()) {
      const std::string name = prefix.empty() ? item.key() : prefix + "." + item.key();
      const auto ia = a.find(item.key());
      const auto ib = b.find(item.key());
      if (ia == a.end() || ib == b.end()) {
        out.push_back(name);
      } else if (prefix.empty()) {
        collect(name, *ia, *ib, out);  // one level down: section.field
      } else if (*ia != *ib) {
        out.push_back(name);
      }
    }
    return;
  }
  if (a != b) out.push_back(prefix);
}

}  // namespace

std::string configurationFingerprint(const Config& config) { return hashText(toJson(config).dump()); }

std::string configurationFingerprint(const std::string& configurationJson) {
  try {
    return configurationFingerprint(configFromJson(nlohmann::json::parse(configurationJson)));
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(std::string("the configuration is not valid JSON: ") + e.what());
  }
}

std::vector<std::string> differingFields(const nlohmann::json& a, const nlohmann::json& b) {
  std::vector<std::string> fields;
  collect("", a, b, fields);
  return fields;
}

void agreeOnConfiguration(const Communicator& world, const Config& config, const nlohmann::json& runOptions) {
  if (!world.parallel()) return;
  nlohmann::json description = toJson(config);
  description["run"] = runOptions;
  const std::string text = description.dump();
  const std::uint64_t h = fnv1a(text.data(), text.size());
  // Two exact 32-bit halves per rank.
  const std::vector<double> hashes =
      world.allGather({static_cast<double>(h >> 32), static_cast<double>(h & 0xffffffffULL)});
  std::vector<int> differing;
  for (int r = 1; r < world.size(); ++r) {
    if (hashes[2 * r] != hashes[0] || hashes[2 * r + 1] != hashes[1]) differing.push_back(r);
  }
  if (differing.empty()) return;
  // Every rank learns every description (collective, so all ranks build the same message).
  const std::vector<double> lengths = world.allGather({static_cast<double>(text.size())});
  const std::vector<double> bytes = world.allGather(asDoubles(text));
  std::vector<std::string> texts;
  std::size_t offset = 0;
  for (double length : lengths) {
    std::string t(static_cast<std::size_t>(length), '\0');
    for (std::size_t i = 0; i < t.size(); ++i)
      t[i] = static_cast<char>(static_cast<unsigned char>(bytes[offset + i]));
    offset += t.size();
    texts.push_back(std::move(t));
  }
  const nlohmann::json root = nlohmann::json::parse(texts[0]);
  std::string message =
      "the MPI ranks were started with different configurations; every rank must get the same "
      "--config, --set, flags and hindsight version:";
  for (int r : differing) {
    const nlohmann::json other = nlohmann::json::parse(texts[static_cast<std::size_t>(r)]);
    std::string fields;
    for (const std::string& field : differingFields(root, other)) {
      const nlohmann::json::json_pointer pointer("/" + [&] {
        std::string p = field;
        for (char& c : p) {
          if (c == '.') c = '/';
        }
        return p;
      }());
      const auto valueIn = [&](const nlohmann::json& j) {
        return j.contains(pointer) ? j.at(pointer).dump() : std::string("absent");
      };
      std::string a = valueIn(root), b = valueIn(other);
      if (a.size() > 80) a = a.substr(0, 77) + "...";
      if (b.size() > 80) b = b.substr(0, 77) + "...";
      fields += (fields.empty() ? " " : ", ") + field + " (rank 0: " + a + ", rank " + std::to_string(r) +
                ": " + b + ")";
    }
    message += " rank " + std::to_string(r) + " differs from rank 0 in" + fields + ";";
  }
  message.back() = '.';
  throw std::invalid_argument(message);
}

}  // namespace hindsight
