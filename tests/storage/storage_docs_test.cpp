// storage/storage_docs.h describes exactly the factory's strategies and keys, and every documented
// example spec is accepted by the factory.
#include <hindsight/storage/storage_docs.h>
#include <hindsight/storage/storage_factory.h>

#include <gtest/gtest.h>

#include <algorithm>

namespace hindsight {
namespace {

TEST(StorageDocs, DocumentsEveryStrategyAndKeyOfTheFactory) {
  std::vector<std::string> documented;
  for (const StorageStrategyDoc& doc : storageStrategyDocs()) documented.push_back(doc.name);
  EXPECT_EQ(documented, storageStrategyNames()) << "add the new strategy to storage/storage_docs.cpp";
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

}  // namespace
}  // namespace hindsight
