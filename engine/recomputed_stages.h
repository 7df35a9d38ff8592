// The stage values a recomputation leaves behind (`stages=1` on the checkpointing
// strategies `binomial` and `online`).
//
// A restore of state e + 1 that recomputes ends with the step e -> e + 1, whose stage values are those
// the adjoint step of e needs; that adjoint step comes after the adjoint step of e + 1 and after the
// restore of e, which may recompute again. So two step records suffice: `pending` receives the stages
// of the last step a restore recomputed, and becomes `served` when the restore of that step begins.
// The forward sweep's last step (its state is restored without recomputation) goes to `served`
// directly. Restores that load a checkpoint placed exactly at e + 1 leave nothing: that adjoint step
// evaluates its stages itself, as without stages=1. The recomputation schedule is not changed.
#pragma once

#include <hindsight/engine/types.h>

#include <cstdint>
#include <cstring>
#include <memory>
#include <utility>

namespace hindsight::internal {

class RecomputedStages {
 public:
  /// size doubles per step record; 0 releases both records.
  void reset(std::int64_t size) {
    size_ = size;
    pending_.reset(size > 0 ? new double[static_cast<std::size_t>(size)] : nullptr);
    served_.reset(size > 0 ? new double[static_cast<std::size_t>(size)] : nullptr);
    pendingStep_ = servedStep_ = -1;
  }
  bool active() const { return size_ > 0; }
  /// Bytes of the two records.
  std::int64_t bytes() const { return 2 * size_ * 8; }

  /// The buffer the stages of `step`, just recomputed, go into.
  Eigen::Map<Vector> pending(std::int64_t step) {
    pendingStep_ = step;
    return Eigen::Map<Vector>(pending_.get(), size_);
  }
  /// The forward sweep's stages of its last step.
  void recordLast(std::int64_t step, ConstVectorRef data) {
    std::memcpy(served_.get(), data.data(), static_cast<std::size_t>(size_) * 8);
    servedStep_ = step;
  }
  /// Called when the restore of `step` begins, before it recomputes.
  void beginRestore(std::int64_t step) {
    if (pendingStep_ != step) return;
    std::swap(pending_, served_);
    servedStep_ = step;
    pendingStep_ = -1;
  }
  /// True (and data filled) when the stages of `step` are held.
  bool restore(std::int64_t step, VectorRef data) const {
    if (!active() || servedStep_ != step) return false;
    std::memcpy(data.data(), served_.get(), static_cast<std::size_t>(size_) * 8);
    return true;
  }

 private:
  std::int64_t size_ = 0;
  std::unique_ptr<double[]> pending_, served_;
  std::int64_t pendingStep_ = -1, servedStep_ = -1;
};

}  // namespace hindsight::internal
