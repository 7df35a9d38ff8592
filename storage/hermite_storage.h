// Strategy "hermite": keeps (z, z') at every M-th grid point and at the final point; states in
// between are cubic Hermite interpolants (docs/design.md §6; the scheme of CVODES' CV_HERMITE
// check-point interpolation, Hindmarsh et al., CVODES user documentation).
//
// Spec: hermite:every=M[,budget=BYTES][,tolerance=T], M in [1, 1e9] (default 10), budget default
// 4 GiB, T in [1e-14, 1] (default 0.01).
// With kept points t_a < t_b (b = a + M, or N for the last segment), H = t_b - t_a, s = (t - t_a)/H:
//   z(t) = h00(s) z_a + h10(s) H z'_a + h01(s) z_b + h11(s) H z'_b,
//   h00 = 2s^3 - 3s^2 + 1, h10 = s^3 - 2s^2 + s, h01 = -2s^3 + 3s^2, h11 = s^3 - s^2.
// The error is O(H^4) for a smooth trajectory: halving M divides it by about 16. restore(n) is exact
// at kept points and interpolated elsewhere, so isExact() is false and a discrete adjoint over it
// differentiates a slightly different trajectory; the gradient error shrinks like H^4.
// Error estimate and validity: the forward sweep sees every state, so it measures the interpolation
// error where it is largest for a smooth trajectory, at the middle step of each kept interval: that
// state is held (one state, allocated at begin()) until the interval's end is kept, then compared
// with the interpolant there. With N unknown (adaptive steps) the middle is not known in advance:
// two states are held, at offsets s and 2s from the interval's start (s doubling as the interval
// grows), so that at its end, of length L, one lies in [L/4, L/2] and both are compared. The largest relative
// error over the run (max-norm of the difference over the max-norm of the interval's states) is the run's
// state error e. The summary reports gradient_error_estimate = LossyStorage::kGradientSensitivity x e, the
// calibrated ratio of gradient to state error that the lossy strategy uses (storage/lossy_storage.h; the same
// problems, the same caveat: an estimate, not a bound); tests/storage/hermite_storage_test.cpp checks it
// against the measured gradient error. A run whose state error exceeds the tolerance T is refused at the end
// of the forward sweep with std::invalid_argument naming hermite.every, e and T (an interval too long for a
// cubic, e.g. every = N on a run of N steps, instead of a gradient off by orders of magnitude). Intervals of
// one step have no interior state and contribute nothing. Memory: (2n + 1) * 8 bytes per kept point plus 8
// bytes per grid time (restore needs t_n); preallocated when N is known, grown geometrically otherwise; every
// byte is charged to the budget, and exceeding it throws StorageError. needsDerivative() is true: the engine
// passes z' = F(t_n, z_n) to record() and finish(). interpolate(t) gives z(t) anywhere in [t0, t_N] once
// finish() has been called, for the continuous adjoint; data stay until the next begin(). Throws:
// std::invalid_argument for every < 1 (factory: naming "hermite.every" and its range) or t outside [t0, t_N]
// in interpolate(); StorageError when the budget would be exceeded; std::logic_error for interpolate() before
// finish().
#pragma once

#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>

#include <memory>
#include <vector>

namespace hindsight {

class HermiteStorage final : public TrajectoryStorage {
 public:
  static constexpr std::int64_t kDefaultBudget = std::int64_t{4} << 30;
  static constexpr std::int64_t kDefaultEvery = 10;
  static constexpr double kDefaultTolerance = 1e-2;
  /// Throws std::invalid_argument when every < 1, the budget is not positive or the tolerance is
  /// outside [1e-14, 1].
  explicit HermiteStorage(std::int64_t every = kDefaultEvery, std::int64_t budgetBytes = kDefaultBudget,
                          double tolerance = kDefaultTolerance);
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);

  std::string spec() const override;
  bool isExact() const override { return false; }
  bool needsDerivative() const override { return true; }
  bool canInterpolate() const override { return true; }
  /// Throws std::logic_error before finish(), std::invalid_argument for t outside [t0, t_N].
  void interpolate(double t, VectorRef z) override;

  std::int64_t every() const { return every_; }
  double tolerance() const { return tolerance_; }
  /// The largest relative interpolation error measured in the last forward sweep (see above).
  double stateErrorEstimate() const { return worstRelativeError_; }

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;

  /// Appends to `buffer`, growing its capacity (charged to the budget) when needed.
  void append(std::vector<double>& buffer, const double* values, std::size_t count);
  void keep(double t, ConstVectorRef z, ConstVectorRef zdot);
  /// Cubic Hermite between kept points `segment` and `segment + 1` at time t.
  void evaluate(std::size_t segment, double t, VectorRef z) const;
  /// N known: the step inside the interval starting at kept step `start` whose state is compared
  /// with the interpolant (-1 when the interval has no interior step).
  std::int64_t sampleStepAfter(std::int64_t start) const;
  void holdSample(int slot, std::int64_t offset, double t, const double* z);
  /// Compares the held samples with the interpolant of the last complete interval, drops them.
  void checkSamples();

  std::int64_t every_;
  double tolerance_;
  std::vector<double> samples_;  // up to two sampled states of the open interval (n values each)
  double sampleTimes_[2] = {0.0, 0.0};
  std::int64_t sampleOffsets_[2] = {-1, -1};  // from the interval's start; -1: none held
  double worstRelativeError_ = 0.0;
  bool finished_ = false;
  std::vector<double> times_;      // t_0 .. t_N
  std::vector<double> keptTimes_;  // t_0, t_M, t_2M, ..., t_N
  std::vector<double> kept_;       // per kept point: z (n values) then z' (n values)
};

}  // namespace hindsight
