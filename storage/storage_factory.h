// The one factory of trajectory storage strategies (docs/design.md P 2): a spec string
// "NAME[:key=value,...]" becomes a strategy. Every strategy is one row of the registry
// (engine/storage_registry.h: name, documented keys, factory, prediction); adding a strategy touches its
// own files, its row in storage_factory.cpp (or, for an in-memory strategy, in
// engine/memory_storage_factory.cpp) and the typed conformance test list.
#pragma once

#include <hindsight/engine/storage_registry.h>
#include <hindsight/engine/trajectory_storage.h>

#include <memory>
#include <string>
#include <vector>

namespace hindsight {

/// Every row: the engine's in-memory strategies (full, binomial, online, cams), then hermite, disk, lossy,
/// multilevel, packed; help texts list them in this order.
const std::vector<StorageStrategyRow>& storageStrategies();

/// Throws std::invalid_argument for an unknown name (listing the known ones), an unknown key
/// (listing the valid ones) or an out-of-range value (naming it and the range).
std::unique_ptr<TrajectoryStorage> createStorage(const std::string& spec);

/// Names of all strategies, for help texts.
std::vector<std::string> storageStrategyNames();

/// The spec keys strategy `name` accepts (storage/storage_docs.h documents them); throws
/// std::invalid_argument for an unknown name, listing the known ones.
std::vector<std::string> storageStrategyKeys(const std::string& name);

}  // namespace hindsight
