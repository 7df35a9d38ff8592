#include "storage/storage_factory.h"

#include "storage/disk_storage.h"
#include "storage/full_storage.h"
#include "storage/hermite_storage.h"
#include "storage/lossy_storage.h"
#include "storage/multilevel_storage.h"
#include "storage/binomial_checkpointing.h"
#include "storage/full_storage.h"
#include "storage/online_checkpointing.h"
#include "storage/storage_spec.h"

#include <functional>

namespace hindsight {
namespace {

struct Entry {
  const char* name;
  std::vector<std::string> (*keys)();
  std::unique_ptr<TrajectoryStorage> (*create)(const StorageSpec&);
};

const std::vector<Entry>& registry() {
  static const std::vector<Entry> entries = {
      {"full", &FullStorage::keys, &FullStorage::create},
      {"hermite", &HermiteStorage::keys, &HermiteStorage::create},
      {"disk", &DiskStorage::keys, &DiskStorage::create},
      {"lossy", &LossyStorage::keys, &LossyStorage::create},
      {"multilevel", &MultilevelStorage::keys, &MultilevelStorage::create},
      {"binomial", &BinomialCheckpointing::keys, &BinomialCheckpointing::create},
      {"online", &OnlineCheckpointing::keys, &OnlineCheckpointing::create},
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

std::vector<std::string> storageStrategyNames() {
  std::vector<std::string> names;
  for (const Entry& entry : registry()) names.emplace_back(entry.name);
  return names;
}

}  // namespace hindsight
