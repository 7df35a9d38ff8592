// Strategy "full": every step's state in memory. Exact, no recomputation; memory N * n * 8 bytes.
// Spec (engine/memory_storage_factory.h): full[:budget=BYTES][,stages=0|1] (default budget 4 GiB). With
// stages=1 every step keeps its stage values too (Integrator::stepDataSize(), 3 n doubles for
// rk4), so no adjoint step evaluates the right-hand side; memory N (n + stepDataSize) * 8 bytes. It lives in
// the engine because it needs nothing but memory: a program that links only hindsight::engine has a strategy.
// Works for unknown N (adaptive steps): states are kept in blocks, so growth never copies what is already
// stored.
#pragma once

#include <hindsight/engine/storage_registry.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>

#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {

class FullStorage final : public TrajectoryStorage {
 public:
  static constexpr std::int64_t kDefaultBudget = std::int64_t{4} << 30;
  explicit FullStorage(std::int64_t budgetBytes = kDefaultBudget, bool stages = false);
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  /// The registry's prediction (engine/storage_registry.h): the counts of N fixed steps.
  static void predict(const TrajectoryStorage& storage, const StorageSpec& spec,
                      const PredictionRequest& request, SchedulePrediction& p);
  /// The registry's action stream: every state recorded into its own RAM slot and loaded back.
  static void writeActions(const TrajectoryStorage& storage, const StorageSpec& spec,
                           const PredictionRequest& request, std::ostream& out);

  std::string spec() const override;
  bool isExact() const override { return true; }
  bool keepsStepData() const override { return stages_; }

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;
  void doRecordStepData(std::int64_t step, ConstVectorRef data) override;
  bool doRestoreStepData(std::int64_t step, VectorRef data) override;
  /// Doubles per step: the state, and with step data its stage values.
  std::int64_t rowSize() const { return info().stateSize + info().stepDataSize; }
  double* row(std::int64_t step);
  void releaseBlockAfter(std::int64_t step);

  // States live in blocks of up to kStatesPerBlock rows (more when rows are large: see kHugePageBytes); a
  // block is charged in full when it is allocated and sized so that it never exceeds the budget or the
  // known step count.
  struct FreeBlock {
    void operator()(double* p) const;
  };
  struct Block {
    std::int64_t firstStep;
    std::int64_t capacity;
    std::unique_ptr<double[], FreeBlock> data;
  };
  static constexpr std::int64_t kStatesPerBlock = 1024;
  // A block of at least this many bytes is sized to whole pages of this size, aligned to one and offered
  // to the kernel's transparent huge pages: the forward sweep then takes one page fault per 2 MiB it
  // fills instead of one per 4 KiB (bench/RESULTS.md, rows with stage values).
  static constexpr std::int64_t kHugePageBytes = std::int64_t{2} << 20;
  std::vector<Block> blocks_;
  bool stages_ = false;
};

}  // namespace hindsight
