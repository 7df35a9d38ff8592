#include <hindsight/storage/storage_factory.h>

#include <hindsight/engine/full_storage.h>
#include <hindsight/storage/binomial_checkpointing.h>
#include <hindsight/storage/cams_checkpointing.h>
#include <hindsight/storage/disk_storage.h>
#include <hindsight/storage/hermite_storage.h>
#include <hindsight/storage/lossy_storage.h>
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/online_checkpointing.h>
#include <hindsight/storage/storage_spec.h>

#include <functional>

namespace hindsight {
namespace {

// FullStorage lives in the engine, which knows nothing of spec strings; its spec is read here.
std::unique_ptr<TrajectoryStorage> createFull(const StorageSpec& spec) {
  return std::make_unique<FullStorage>(spec.bytes("budget", FullStorage::kDefaultBudget),
                                       spec.integer("stages", 0, 0, 1) == 1);
}
std::vector<std::string> fullKeys() { return {"budget", "stages"}; }

struct Entry {
  const char* name;
  std::vector<std::string> (*keys)();
  std::unique_ptr<TrajectoryStorage> (*create)(const StorageSpec&);
};

const std::vector<Entry>& registry() {
  static const std::vector<Entry> entries = {
      {"full", &fullKeys, &createFull},
      {"hermite", &HermiteStorage::keys, &HermiteStorage::create},
      {"disk", &DiskStorage::keys, &DiskStorage::create},
      {"lossy", &LossyStorage::keys, &LossyStorage::create},
      {"multilevel", &MultilevelStorage::keys, &MultilevelStorage::create},
      {"binomial", &BinomialCheckpointing::keys, &BinomialCheckpointing::create},
      {"online", &OnlineCheckpointing::keys, &OnlineCheckpointing::create},
      {"cams", &CamsCheckpointing::keys, &CamsCheckpointing::create},
      {"packed", &LossyStorage::packedKeys, &LossyStorage::createPacked},
  };
  return entries;
}

}  // namespace

std::unique_ptr<TrajectoryStorage> createStorage(const std::string& text) {
  const StorageSpec spec = StorageSpec::parse(text);
  for (const Entry& entry : registry()) {
    if (spec.name() == entry.name) {
      spec.requireKeysIn(entry.keys());
      return entry.create(spec);
    }
  }
  std::string names;
  for (const auto& n : storageStrategyNames()) names += (names.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown storage strategy '" + spec.name() + "'; known: " + names);
}

std::vector<std::string> storageStrategyKeys(const std::string& name) {
  for (const Entry& entry : registry()) {
    if (name == entry.name) return entry.keys();
  }
  std::string names;
  for (const auto& n : storageStrategyNames()) names += (names.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown storage strategy '" + name + "'; known: " + names);
}

std::vector<std::string> storageStrategyNames() {
  std::vector<std::string> names;
  for (const Entry& entry : registry()) names.emplace_back(entry.name);
  return names;
}

}  // namespace hindsight
