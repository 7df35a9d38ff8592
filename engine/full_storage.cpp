#include <hindsight/engine/full_storage.h>

#include <algorithm>
#include <cstring>

namespace hindsight {

FullStorage::FullStorage(std::int64_t budgetBytes) : TrajectoryStorage(budgetBytes) {}

std::string FullStorage::spec() const {
  return budgetBytes() == kDefaultBudget ? "full" : "full:budget=" + std::to_string(budgetBytes());
}

void FullStorage::doBegin() { blocks_.clear(); }

void FullStorage::doRecord(std::int64_t step, double, ConstVectorRef z, ConstVectorRef) {
  const std::int64_t n = info().stateSize;
  if (blocks_.empty() || step >= blocks_.back().firstStep + blocks_.back().capacity) {
    std::int64_t capacity = kStatesPerBlock;
    if (info().stepCount > 0) capacity = std::min(capacity, info().stepCount - step);
    capacity = std::max<std::int64_t>(
        1, std::min(capacity, (budgetBytes() - counters().bytesInMemory) / stateBytes()));
    holdBytes(capacity * stateBytes());
    blocks_.push_back(
        Block{step, capacity, std::unique_ptr<double[]>(new double[static_cast<std::size_t>(capacity * n)])});
  }
  Block& block = blocks_.back();
  std::memcpy(block.data.get() + (step - block.firstStep) * n, z.data(), static_cast<std::size_t>(n) * 8);
  ++mutableCounters().statesStored;
}

void FullStorage::doFinish(double, ConstVectorRef, ConstVectorRef) {}

void FullStorage::doRestore(std::int64_t step, VectorRef z) {
  const std::int64_t n = info().stateSize;
  Block& block = blocks_.back();
  assert(step >= block.firstStep && step < block.firstStep + block.capacity);
  std::memcpy(z.data(), block.data.get() + (step - block.firstStep) * n, static_cast<std::size_t>(n) * 8);
  if (step == block.firstStep) {
    // Free blocks as the backward sweep leaves them behind.
    releaseBytes(block.capacity * stateBytes());
    blocks_.pop_back();
  }
}

}  // namespace hindsight
