// Recomputes forward steps for checkpointing strategies with the same integrator code path and the
// grid the forward sweep took, so the bits are those of the forward sweep. Shared by the discrete
// and continuous adjoint sweeps.
#pragma once

#include <hindsight/engine/integrator.h>
#include <hindsight/engine/trajectory_storage.h>

#include <vector>

namespace hindsight {

class GridRecomputer final : public StepRecomputer {
 public:
  /// `times` is the forward grid t_0..t_N; it must outlive the recomputer (it may still grow during
  /// the forward sweep, before any recomputation).
  GridRecomputer(Integrator& integrator, const std::vector<double>& times)
      : integrator_(integrator), times_(times) {}
  void advance(std::int64_t step, VectorRef z) override {
    integrator_.step(times_[step], times_[step + 1] - times_[step], z);
  }
  void stepData(VectorRef data) override { integrator_.saveStepData(data); }

 private:
  Integrator& integrator_;
  const std::vector<double>& times_;
};

}  // namespace hindsight
