#include <hindsight/storage/storage_docs.h>

#include <hindsight/storage/storage_factory.h>

namespace hindsight {

const std::vector<StorageStrategyDoc>& storageStrategyDocs() {
  static const std::vector<StorageStrategyDoc> docs = [] {
    std::vector<StorageStrategyDoc> all;
    for (const StorageStrategyRow& row : storageStrategies()) all.push_back(row.doc);
    return all;
  }();
  return docs;
}

const StorageStrategyDoc* findStorageStrategyDoc(const std::string& name) {
  for (const StorageStrategyDoc& doc : storageStrategyDocs()) {
    if (doc.name == name) return &doc;
  }
  return nullptr;
}

namespace {

// A table cell: '|' would end the cell, a line break the row.
std::string cell(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '|')
      out += "\\|";
    else if (c == '\n')
      out += ' ';
    else
      out += c;
  }
  return out;
}

}  // namespace

std::string storageStrategiesMarkdown() {
  std::string out =
      "| strategy | what it keeps | exact | `hindsight schedule` | example | keys |\n"
      "|---|---|---|---|---|---|\n";
  for (const StorageStrategyRow& row : storageStrategies()) {
    std::string keys;
    for (const StorageKeyDoc& key : row.doc.keys) {
      keys += (keys.empty() ? "" : "<br>") + std::string("`") + key.key + "`: " + cell(key.doc);
    }
    out += "| `" + row.name() + "` | " + cell(row.doc.summary) + " | " + (row.doc.exact ? "yes" : "no") +
           " | " + (row.predict != nullptr ? "predicted" : "not predicted: " + cell(row.notPredicted)) +
           " | `" + row.doc.example + "` | " + keys + " |\n";
  }
  return out;
}

}  // namespace hindsight
