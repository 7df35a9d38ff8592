#include <hindsight/engine/memory_storage_factory.h>

#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/cams_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/online_checkpointing.h>

#include <stdexcept>

namespace hindsight {

const std::vector<StorageStrategyEntry>& memoryStorageStrategies() {
  static const std::vector<StorageStrategyEntry> entries = {
      {"full", &FullStorage::keys, &FullStorage::create},
      {"binomial", &BinomialCheckpointing::keys, &BinomialCheckpointing::create},
      {"online", &OnlineCheckpointing::keys, &OnlineCheckpointing::create},
      {"cams", &CamsCheckpointing::keys, &CamsCheckpointing::create},
  };
  return entries;
}

std::unique_ptr<TrajectoryStorage> createMemoryStorage(const std::string& text) {
  const StorageSpec spec = StorageSpec::parse(text);
  std::string names;
  for (const StorageStrategyEntry& entry : memoryStorageStrategies()) {
    if (spec.name() == entry.name) {
      spec.requireKeysIn(entry.keys());
      return entry.create(spec);
    }
    names += (names.empty() ? "" : ", ") + std::string(entry.name);
  }
  for (const char* other : {"disk", "lossy", "packed", "hermite", "multilevel"}) {
    if (spec.name() == other) {
      throw std::invalid_argument(
          "storage strategy '" + spec.name() +
          "' is not in memory: it needs the storage component (hindsight::createStorage, "
          "<hindsight/storage/storage_factory.h>); in memory: " +
          names);
    }
  }
  throw std::invalid_argument("unknown storage strategy '" + spec.name() + "'; in memory: " + names);
}

}  // namespace hindsight
