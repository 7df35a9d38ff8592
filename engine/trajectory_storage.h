// The one interface between the adjoint sweep and the forward trajectory (docs/design.md §6).
//
// Protocol, enforced by the public non-virtual methods (Drake style: they check preconditions, then
// call the protected Do... hooks):
//   begin(info, recomputer)                 once, before the forward sweep;
//   record(n, t_n, z_n, zdot_n)             for n = 0, 1, ..., N-1, the state at the start of step n;
//   finish(N, t_N, z_N, zdot_N)             once, with the final state; N is known from here on;
//   restore(n, z)                           for n = N-1, N-2, ..., 0 during the backward sweep
//                                           (with TrajectoryInfo.workingStateHoldsLast, z already holds
//                                           x_{N-1} at the first restore: the caller's working state).
// A strategy may recompute states from a checkpoint by calling recompute(n, z), which advances z
// from grid point n to n+1 with exactly the step the forward sweep took, so the bits are the same.
//
// Step data. Besides the state, a strategy may keep per step what the adjoint step needs
// (the integrator's stage values; Integrator::stepDataSize()), so that the adjoint step evaluates no
// right-hand side. When info().stepDataSize > 0 (the engine sets it only for a strategy whose
// keepsStepData() is true and an integrator that offers step data), the protocol has two more calls:
//   recordStepData(n, data)     right after every record(n, ...), the stage values of step n;
//   restoreStepData(n, data)    right after every restore(n, z); true when `data` now holds the stage
//                               values of step n (the adjoint step then uses them), false when the
//                               strategy did not keep them for this step.
// A strategy that recomputes step n may take its stage values with recomputedStepData() right after
// recompute(n, z). Restored step data is hash-verified like states when verifyRestores is on.
// The storage knows nothing of integrators beyond that callback (docs/design.md P 1).
//
// Every strategy has a byte budget it never exceeds: it charges the bytes it holds in memory with
// holdBytes(), which throws StorageError before the budget would be exceeded. Restored states are
// checked against a hash of the recorded bits when verifyRestores is on (the default in debug
// builds); a mismatch in an exact strategy is an internal bug and throws std::logic_error.
#pragma once

#include <hindsight/engine/types.h>

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {

/// What a strategy learns about the trajectory before it starts.
struct TrajectoryInfo {
  std::string problemName;
  int stateSize = 0;
  double t0 = 0.0;
  double t1 = 0.0;
  /// Number of steps N when it is known in advance (fixed step); -1 when it is not (adaptive).
  std::int64_t stepCount = -1;
  /// Doubles of step data (stage values) per step the engine passes to recordStepData(); 0: none (the
  /// strategy keeps no step data, or the integrator offers none, e.g. generalized-alpha).
  std::int64_t stepDataSize = 0;
  /// True when the z of the first restore(N-1, z) already holds x_{N-1}, the state of the last record():
  /// the caller's working state, revolve's "current state" (Griewank & Walther 2000) and
  /// checkpoint_schedules' WORK, which the storage need not keep. computeGradient sets it (its backward sweep
  /// restores into the buffer the forward sweep's last step started from); other callers leave it false. With
  /// verifyRestores on, restore(N-1) checks the promise and throws std::logic_error when z differs.
  bool workingStateHoldsLast = false;
};

/// The callback through which a strategy recomputes forward steps.
class StepRecomputer {
 public:
  virtual ~StepRecomputer() = default;
  /// z <- z_{step+1}, given z = z_step; bitwise identical to the forward sweep's step.
  virtual void advance(std::int64_t step, VectorRef z) = 0;
  /// The step data (stage values, TrajectoryInfo::stepDataSize doubles) of the step advance() just took.
  virtual void stepData(VectorRef data) {
    (void)data;
    throw std::logic_error("this recomputer provides no step data");
  }
};

/// Counters every strategy reports (docs/design.md §6); they end up in the run summary.
struct StorageCounters {
  std::int64_t recomputedSteps = 0;
  std::int64_t statesStored = 0;       ///< states or checkpoints written in the forward sweep
  std::int64_t bytesInMemory = 0;      ///< bytes held now
  std::int64_t peakBytesInMemory = 0;  ///< the most bytes held at any time
  std::int64_t bytesOnDisk = 0;        ///< file size (compressed), 0 for memory-only strategies
  std::int64_t uncompressedBytes = 0;  ///< raw size of what was compressed, for the ratio
  std::int64_t compressedBytes = 0;
  double ioSeconds = 0.0;
  /// A lossy strategy's estimate of the relative 2-norm error of the gradient its restored states
  /// cause (lossy:target=T, lossy:codec=time); -1 when the strategy makes none.
  double gradientErrorEstimate = -1.0;
  std::int64_t stepDataStored = 0;    ///< steps whose step data (stage values) was kept, any sweep
  std::int64_t stepDataRestored = 0;  ///< adjoint steps served from kept step data (no rhs evaluated)
  /// A strategy that plans by a cost model (multilevel): the predicted and the measured seconds of its
  /// own work, recomputation plus disk I/O; 0 for the others.
  double predictedSeconds = 0.0;
  double scheduleSeconds = 0.0;
  /// Seconds spent building a plan (cams), part of the sweep that built it (begin(): the forward sweep).
  double planningSeconds = 0.0;
  /// uncompressedBytes / compressedBytes, or 1 when nothing was compressed.
  double compressionRatio() const {
    return compressedBytes > 0 ? static_cast<double>(uncompressedBytes) / static_cast<double>(compressedBytes)
                               : 1.0;
  }
};

class TrajectoryStorage {
 public:
  static constexpr std::int64_t kUnlimitedBytes = std::numeric_limits<std::int64_t>::max();

  virtual ~TrajectoryStorage() = default;
  TrajectoryStorage(const TrajectoryStorage&) = delete;
  TrajectoryStorage& operator=(const TrajectoryStorage&) = delete;

  /// The spec string that recreates this strategy, e.g. "binomial:checkpoints=20".
  virtual std::string spec() const = 0;
  /// True when restore() returns the recorded bits (lossless strategies).
  virtual bool isExact() const = 0;
  /// True when record() needs zdot (F at the recorded point), e.g. for Hermite interpolation.
  virtual bool needsDerivative() const { return false; }

  void begin(const TrajectoryInfo& info, StepRecomputer& recomputer);
  void record(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot);
  void finish(std::int64_t stepCount, double t, ConstVectorRef z, ConstVectorRef zdot);
  void restore(std::int64_t step, VectorRef z);
  /// True when the strategy keeps step data (stage values) when the integrator offers it (stages=1, cams).
  virtual bool keepsStepData() const { return false; }
  /// True when its step records also hold the rhs data the integrator offers (Integrator::stepRhsDataSize(),
  /// Problem::rhsDataSize() per stage), so that the adjoint step re-forms nothing the rhs computed. Default:
  /// every strategy that keeps step data; cams does not (its plans count records in state units of the
  /// stage values alone).
  virtual bool keepsRhsData() const { return keepsStepData(); }
  void recordStepData(std::int64_t step, ConstVectorRef data);
  bool restoreStepData(std::int64_t step, VectorRef data);

  const StorageCounters& counters() const { return counters_; }
  std::int64_t budgetBytes() const { return budgetBytes_; }
  const TrajectoryInfo& info() const { return info_; }
  /// Number of steps N, known after finish().
  std::int64_t stepCount() const { return stepCount_; }

  void setVerifyRestores(bool on) { verifyRestores_ = on; }
  bool verifyRestores() const { return verifyRestores_; }

  /// True when interpolate() gives z(t) at any t in [t0, t_N] (for the continuous adjoint, which
  /// takes its own backward steps). Strategies that keep no dense output return false.
  virtual bool canInterpolate() const { return false; }
  /// z <- z(t) for t in [info().t0, t_N], in any order, between finish() and the next begin(); z has
  /// info().stateSize entries. Strategies that cannot interpolate throw std::logic_error.
  virtual void interpolate(double t, VectorRef z) {
    (void)t;
    (void)z;
    throw std::logic_error("strategy " + spec() + " cannot interpolate");
  }

 protected:
  explicit TrajectoryStorage(std::int64_t budgetBytes);

  virtual void doBegin() = 0;
  virtual void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) = 0;
  virtual void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) = 0;
  virtual void doRestore(std::int64_t step, VectorRef z) = 0;
  /// Step data hooks (see the header comment); called only when info().stepDataSize > 0.
  virtual void doRecordStepData(std::int64_t step, ConstVectorRef data) {
    (void)step;
    (void)data;
  }
  virtual bool doRestoreStepData(std::int64_t step, VectorRef data) {
    (void)step;
    (void)data;
    return false;
  }

  /// Charges bytes against the budget; throws StorageError naming the strategy when it would be exceeded.
  void holdBytes(std::int64_t bytes);
  void releaseBytes(std::int64_t bytes);
  /// True when another `bytes` fit into the budget.
  bool fits(std::int64_t bytes) const { return bytes <= budgetBytes_ - counters_.bytesInMemory; }
  /// Advances z from grid point `step` to `step + 1` by recomputation, counted.
  void recompute(std::int64_t step, VectorRef z);
  /// The step data of the step recompute() just took (info().stepDataSize doubles).
  void recomputedStepData(VectorRef data) { recomputer_->stepData(data); }
  std::int64_t stepDataBytes() const { return info_.stepDataSize * 8; }
  StorageCounters& mutableCounters() { return counters_; }
  std::int64_t stateBytes() const { return static_cast<std::int64_t>(info_.stateSize) * 8; }

 private:
  std::int64_t budgetBytes_;
  TrajectoryInfo info_;
  StepRecomputer* recomputer_ = nullptr;
  StorageCounters counters_;
  std::int64_t stepCount_ = -1;
  std::int64_t nextRecord_ = 0;
  std::int64_t nextRestore_ = -1;
  enum class Phase { kIdle, kForward, kBackward } phase_ = Phase::kIdle;
#ifdef NDEBUG
  bool verifyRestores_ = false;
#else
  bool verifyRestores_ = true;
#endif
  std::vector<std::uint64_t> hashes_;
  std::vector<std::uint64_t> stepDataHashes_;
  enum class StepDataCall { kNone, kRecord, kRestore } expectedStepDataCall_ = StepDataCall::kNone;
};

/// FNV-1a hash of the bytes of a state vector; used to verify recomputation bit for bit.
std::uint64_t hashState(ConstVectorRef z);

/// Parses a byte count such as "4096", "64KiB", "32MiB", "4GiB", "10MB"; throws std::invalid_argument
/// naming `field` on a malformed or negative value.
std::int64_t parseBytes(const std::string& text, const std::string& field);
/// "32.0 MiB" style rendering for messages and summaries.
std::string formatBytes(std::int64_t bytes);

/// Throws a NumericalError at the same time as `failure` that names the backward sweep (`sweep`, e.g.
/// "discrete adjoint"), the storage's spec and, for an approximate storage, that the states it
/// restored are not the recorded ones: a Newton failure on a stiff problem in the backward sweep
/// then points at the storage setting rather than at the model.
[[noreturn]] void throwBackwardSweepFailure(const NumericalError& failure, const TrajectoryStorage& storage,
                                            const std::string& sweep);

}  // namespace hindsight
