// Strategy "full": every step's state in memory. Exact, no recomputation; memory N * n * 8 bytes.
// Spec: full[:budget=BYTES] (default budget 4 GiB). Works for unknown N (adaptive steps): states are
// kept in blocks, so growth never copies what is already stored.
#pragma once

#include "storage/storage_spec.h"
#include "storage/trajectory_storage.h"

#include <memory>
#include <vector>

namespace hindsight {

class FullStorage final : public TrajectoryStorage {
 public:
  static constexpr std::int64_t kDefaultBudget = std::int64_t{4} << 30;
  explicit FullStorage(std::int64_t budgetBytes = kDefaultBudget);
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  static std::vector<std::string> keys() { return {"budget"}; }

  std::string spec() const override;
  bool isExact() const override { return true; }

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;

  // States live in blocks of up to kStatesPerBlock; a block is charged in full when it is
  // allocated and sized so that it never exceeds the budget or the known step count.
  struct Block {
    std::int64_t firstStep;
    std::int64_t capacity;
    std::unique_ptr<double[]> data;
  };
  static constexpr std::int64_t kStatesPerBlock = 1024;
  std::vector<Block> blocks_;
};

}  // namespace hindsight
