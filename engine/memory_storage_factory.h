// The factory of the in-memory trajectory storage strategies: full, binomial, online and cams. They need
// nothing but memory, so they live in the engine and a program that links only hindsight::engine (Eigen
// and SLEEF) can checkpoint by spec string. The strategies that keep states in files or compress them
// (disk, lossy, packed, hermite, multilevel) are in the storage component, whose createStorage()
// (storage/storage_factory.h) accepts every spec, these four included, from this one table.
#pragma once

#include <hindsight/engine/storage_registry.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>

#include <memory>
#include <string>
#include <vector>

namespace hindsight {

/// The rows of the in-memory strategies (engine/storage_registry.h), in the order help texts list them:
/// full, binomial, online, cams.
const std::vector<StorageStrategyRow>& memoryStorageStrategies();

/// A strategy from "NAME[:key=value,...]" for NAME in full, binomial, online, cams. Throws
/// std::invalid_argument for an unknown key or out-of-range value (naming it and the range), and for
/// any other name: the in-memory names, and for a strategy of the storage component (disk, lossy,
/// packed, hermite, multilevel) that it needs hindsight::createStorage from that component.
std::unique_ptr<TrajectoryStorage> createMemoryStorage(const std::string& spec);

}  // namespace hindsight
