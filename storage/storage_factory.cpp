#include <hindsight/storage/storage_factory.h>

#include <hindsight/engine/memory_storage_factory.h>
#include <hindsight/storage/disk_storage.h>
#include <hindsight/storage/hermite_storage.h>
#include <hindsight/storage/lossy_storage.h>
#include <hindsight/storage/multilevel_storage.h>

#include <functional>

namespace hindsight {
namespace {

// The engine's in-memory strategies (engine/memory_storage_factory.h) and then those of this
// component; each strategy has its row in one of the two tables only.
const std::vector<StorageStrategyEntry>& registry() {
  static const std::vector<StorageStrategyEntry> entries = [] {
    std::vector<StorageStrategyEntry> all = memoryStorageStrategies();
    all.insert(all.end(), {
                              {"hermite", &HermiteStorage::keys, &HermiteStorage::create},
                              {"disk", &DiskStorage::keys, &DiskStorage::create},
                              {"lossy", &LossyStorage::keys, &LossyStorage::create},
                              {"multilevel", &MultilevelStorage::keys, &MultilevelStorage::create},
                              {"packed", &LossyStorage::packedKeys, &LossyStorage::createPacked},
                          });
    return all;
  }();
  return entries;
}

}  // namespace

std::unique_ptr<TrajectoryStorage> createStorage(const std::string& text) {
  const StorageSpec spec = StorageSpec::parse(text);
  for (const StorageStrategyEntry& entry : registry()) {
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
  for (const StorageStrategyEntry& entry : registry()) {
    if (name == entry.name) return entry.keys();
  }
  std::string names;
  for (const auto& n : storageStrategyNames()) names += (names.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown storage strategy '" + name + "'; known: " + names);
}

std::vector<std::string> storageStrategyNames() {
  std::vector<std::string> names;
  for (const StorageStrategyEntry& entry : registry()) names.emplace_back(entry.name);
  return names;
}

}  // namespace hindsight
