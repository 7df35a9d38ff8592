// The documentation of every storage strategy and of each of its spec keys, for help texts, the Python
// module's hindsight.storage_specs() and the table of docs/guides/storage_strategies.md. It is the
// documentation part of the registry's rows (storage/storage_factory.h, storageStrategies()), so a
// strategy and its documentation are one row; tests/storage/storage_docs_test.cpp checks the examples
// and that the documentation's table is the one generated here.
#pragma once

#include <hindsight/engine/storage_registry.h>

#include <string>
#include <vector>

namespace hindsight {

/// One entry per documented strategy, in the factory's order.
const std::vector<StorageStrategyDoc>& storageStrategyDocs();

/// The entry of `name`, or nullptr when there is no such strategy.
const StorageStrategyDoc* findStorageStrategyDoc(const std::string& name);

/// The Markdown table of every strategy (name, exact, predicted, example, keys) for
/// docs/guides/storage_strategies.md, between its markers (the test regenerates it with
/// HINDSIGHT_REGENERATE=1).
std::string storageStrategiesMarkdown();

}  // namespace hindsight
