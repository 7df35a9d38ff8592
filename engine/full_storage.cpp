#include <hindsight/engine/full_storage.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace hindsight {

FullStorage::FullStorage(std::int64_t budgetBytes, bool stages)
    : TrajectoryStorage(budgetBytes), stages_(stages) {}

std::unique_ptr<TrajectoryStorage> FullStorage::create(const StorageSpec& spec) {
  return std::make_unique<FullStorage>(spec.bytes("budget", kDefaultBudget),
                                       spec.integer("stages", 0, 0, 1) == 1);
}

std::string FullStorage::spec() const {
  std::string text = "full";
  if (budgetBytes() != kDefaultBudget) text += ":budget=" + std::to_string(budgetBytes());
  if (stages_) text += std::string(text == "full" ? ":" : ",") + "stages=1";
  return text;
}

void FullStorage::doBegin() { blocks_.clear(); }

void FullStorage::FreeBlock::operator()(double* p) const { std::free(p); }

double* FullStorage::row(std::int64_t step) {
  Block& block = blocks_.back();
  assert(step >= block.firstStep && step < block.firstStep + block.capacity);
  return block.data.get() + (step - block.firstStep) * rowSize();
}

void FullStorage::doRecord(std::int64_t step, double, ConstVectorRef z, ConstVectorRef) {
  const std::int64_t n = info().stateSize;
  const std::int64_t rowBytes = rowSize() * 8;
  if (blocks_.empty() || step >= blocks_.back().firstStep + blocks_.back().capacity) {
    std::int64_t capacity = kStatesPerBlock;
    // Large rows: as many as fill whole huge pages.
    if (capacity * rowBytes >= kHugePageBytes)
      capacity = (capacity * rowBytes + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes / rowBytes;
    if (info().stepCount > 0) capacity = std::min(capacity, info().stepCount - step);
    capacity =
        std::max<std::int64_t>(1, std::min(capacity, (budgetBytes() - counters().bytesInMemory) / rowBytes));
    holdBytes(capacity * rowBytes);
    const std::int64_t bytes = capacity * rowBytes;
    void* memory = nullptr;
    if (bytes >= kHugePageBytes) {
      const std::int64_t pages = (bytes + kHugePageBytes - 1) / kHugePageBytes;
      memory = std::aligned_alloc(static_cast<std::size_t>(kHugePageBytes),
                                  static_cast<std::size_t>(pages * kHugePageBytes));
#if defined(__linux__) && defined(MADV_HUGEPAGE)
      // Advice only: without transparent huge pages the block is ordinary memory.
      if (memory != nullptr) madvise(memory, static_cast<std::size_t>(pages * kHugePageBytes), MADV_HUGEPAGE);
#endif
    } else {
      memory = std::malloc(static_cast<std::size_t>(bytes));
    }
    if (memory == nullptr) {
      releaseBytes(bytes);
      throw std::bad_alloc();
    }
    blocks_.push_back(
        Block{step, capacity, std::unique_ptr<double[], FreeBlock>(static_cast<double*>(memory))});
  }
  std::memcpy(row(step), z.data(), static_cast<std::size_t>(n) * 8);
  ++mutableCounters().statesStored;
}

void FullStorage::doRecordStepData(std::int64_t step, ConstVectorRef data) {
  std::memcpy(row(step) + info().stateSize, data.data(), static_cast<std::size_t>(data.size()) * 8);
  ++mutableCounters().stepDataStored;
}

void FullStorage::doFinish(double, ConstVectorRef, ConstVectorRef) {}

void FullStorage::releaseBlockAfter(std::int64_t step) {
  // Free blocks as the backward sweep leaves them behind.
  if (step == blocks_.back().firstStep) {
    releaseBytes(blocks_.back().capacity * rowSize() * 8);
    blocks_.pop_back();
  }
}

void FullStorage::doRestore(std::int64_t step, VectorRef z) {
  std::memcpy(z.data(), row(step), static_cast<std::size_t>(info().stateSize) * 8);
  // With step data, restoreStepData(step) follows and still reads the row.
  if (info().stepDataSize == 0) releaseBlockAfter(step);
}

bool FullStorage::doRestoreStepData(std::int64_t step, VectorRef data) {
  std::memcpy(data.data(), row(step) + info().stateSize, static_cast<std::size_t>(data.size()) * 8);
  releaseBlockAfter(step);
  return true;
}

}  // namespace hindsight

namespace hindsight {

void FullStorage::predict(const TrajectoryStorage& storage, const StorageSpec&,
                          const PredictionRequest& request, SchedulePrediction& p) {
  const auto& full = dynamic_cast<const FullStorage&>(storage);
  const std::int64_t steps = request.steps;
  // stages=1: every row the state and its step record (an explicit Runge-Kutta method's
  // Integrator::stepDataSize(): S - 1 stage states and S rhs data; none for S = 1), every adjoint step
  // served.
  const bool stageRows = full.stages_ && prediction::hasStageValues(request.stages);
  const std::int64_t rowDoubles = prediction::stageRowDoubles(request, stageRows, "full");
  if (stageRows) p.stepDataStored = p.stepDataRestored = steps;
  const std::int64_t budget = full.budgetBytes();
  if (steps > budget / (8 * rowDoubles)) {
    throw std::invalid_argument(
        "full: " + std::to_string(steps) + " states of " + formatBytes(request.stateBytes) +
        (stageRows ? " with their stage values (" + formatBytes(8 * rowDoubles) + " a step)"
                   : std::string()) +
        " exceed full.budget = " + formatBytes(budget));
  }
  p.plan = stageRows ? "every state and its step's stage values in RAM" : "every state in RAM";
  p.statesStored = steps;
  p.ramWrites = steps;
  p.ramReads = steps;
  p.peakRamBytes = steps * 8 * rowDoubles;  // <= full.budget (checked above)
}

void FullStorage::writeActions(const TrajectoryStorage&, const StorageSpec&, const PredictionRequest& request,
                               std::ostream& out) {
  prediction::writeEveryStateActions(request.steps, StorageLevel::kRam, out);
}

}  // namespace hindsight
