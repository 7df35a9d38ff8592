// storage/storage_docs.h describes exactly the registry's strategies and keys, every documented example
// spec is accepted by the factory, and the table of docs/guides/storage_strategies.md is the one generated
// from the rows. With HINDSIGHT_REGENERATE=1 in the environment the test rewrites that table instead
// (then review the diff and commit it).
#include <hindsight/storage/storage_docs.h>
#include <hindsight/storage/storage_factory.h>

#include "support/generated_text.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

namespace hindsight {
namespace {

TEST(StorageDocs, DocumentsEveryStrategyAndKeyOfTheFactory) {
  std::vector<std::string> documented;
  for (const StorageStrategyDoc& doc : storageStrategyDocs()) documented.push_back(doc.name);
  EXPECT_EQ(documented, storageStrategyNames());
  for (const std::string& name : storageStrategyNames()) {
    const StorageStrategyDoc* doc = findStorageStrategyDoc(name);
    ASSERT_NE(doc, nullptr) << name;
    std::vector<std::string> keys;
    for (const StorageKeyDoc& key : doc->keys) {
      keys.push_back(key.key);
      EXPECT_FALSE(key.doc.empty()) << name << "." << key.key;
    }
    std::vector<std::string> factoryKeys = storageStrategyKeys(name);
    std::sort(keys.begin(), keys.end());
    std::sort(factoryKeys.begin(), factoryKeys.end());
    EXPECT_EQ(keys, factoryKeys) << name;
    EXPECT_FALSE(doc->summary.empty()) << name;
  }
  EXPECT_EQ(findStorageStrategyDoc("no-such-strategy"), nullptr);
}

TEST(StorageDocs, ExamplesAreValidSpecsWithTheDocumentedExactness) {
  for (const StorageStrategyDoc& doc : storageStrategyDocs()) {
    const auto storage = createStorage(doc.example);
    ASSERT_NE(storage, nullptr) << doc.example;
    EXPECT_EQ(storage->isExact(), doc.exact) << doc.example;
  }
}

TEST(StorageDocs, KeysOfAnUnknownStrategyNameTheKnownOnes) {
  try {
    storageStrategyKeys("nope");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown storage strategy 'nope'; known: full"), std::string::npos);
  }
}

TEST(StorageDocs, DocumentationTableIsGeneratedFromTheRows) {
  EXPECT_TRUE(testing::generatedSectionMatches(
      std::filesystem::path(HINDSIGHT_SOURCE_DIR) / "docs/guides/storage_strategies.md",
      "<!-- storage-strategies: generated from the registry's rows (storage/storage_docs.h) -->\n",
      "<!-- storage-strategies: end -->\n", storageStrategiesMarkdown(),
      "the registry's rows (storage/storage_docs.h)"));
}

}  // namespace
}  // namespace hindsight
