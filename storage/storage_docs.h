// The documentation of every storage strategy and of each of its spec keys, for help texts and the
// Python module's hindsight.storage_specs(). The strategies and their keys themselves come from the
// factory (storage/storage_factory.h); this table only describes them, and
// tests/storage/storage_docs_test.cpp checks that it describes exactly the factory's strategies and
// keys, so a new strategy is documented here when it is added to the factory.
#pragma once

#include <string>
#include <vector>

namespace hindsight {

struct StorageKeyDoc {
  std::string key;
  std::string doc;  ///< meaning, allowed values and default
};

struct StorageStrategyDoc {
  std::string name;
  std::string summary;  ///< one or two sentences: what is kept, what is recomputed
  bool exact = true;    ///< restore() returns the recorded bits (gradient bitwise equal to "full")
  std::string example;  ///< a valid spec string
  std::vector<StorageKeyDoc> keys;
};

/// One entry per documented strategy, in the factory's order.
const std::vector<StorageStrategyDoc>& storageStrategyDocs();

/// The entry of `name`, or nullptr when the strategy is not documented.
const StorageStrategyDoc* findStorageStrategyDoc(const std::string& name);

}  // namespace hindsight
