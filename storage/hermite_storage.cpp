#include <hindsight/storage/hermite_storage.h>

#include <hindsight/engine/storage_spec.h>
#include <hindsight/storage/lossy_storage.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace hindsight {

HermiteStorage::HermiteStorage(std::int64_t every, std::int64_t budgetBytes, double tolerance)
    : TrajectoryStorage(budgetBytes), every_(every), tolerance_(tolerance) {
  if (every < 1) {
    throw std::invalid_argument("hermite.every = " + std::to_string(every) + " must be in [1, 1000000000]");
  }
  if (!(tolerance >= 1e-14 && tolerance <= 1.0)) {
    std::ostringstream msg;
    msg << "hermite.tolerance = " << tolerance << " must be in [1e-14, 1]";
    throw std::invalid_argument(msg.str());
  }
}

std::unique_ptr<TrajectoryStorage> HermiteStorage::create(const StorageSpec& spec) {
  return std::make_unique<HermiteStorage>(spec.integer("every", kDefaultEvery, 1, 1'000'000'000),
                                          spec.bytes("budget", kDefaultBudget),
                                          spec.real("tolerance", kDefaultTolerance, 1e-14, 1.0));
}

std::string HermiteStorage::spec() const {
  std::string text = "hermite:every=" + std::to_string(every_);
  if (budgetBytes() != kDefaultBudget) text += ",budget=" + std::to_string(budgetBytes());
  if (tolerance_ != kDefaultTolerance) text += ",tolerance=" + shortestText(tolerance_);
  return text;
}

std::int64_t HermiteStorage::sampleStepAfter(std::int64_t start) const {
  const std::int64_t steps = info().stepCount;
  // The interval's length: every_, or the rest of a known trajectory for the last one.
  const std::int64_t length = steps > 0 ? std::min(every_, steps - start) : every_;
  return length >= 2 ? start + length / 2 : -1;
}

void HermiteStorage::holdSample(int slot, std::int64_t offset, double t, const double* z) {
  const std::size_t n = static_cast<std::size_t>(info().stateSize);
  std::memcpy(samples_.data() + static_cast<std::size_t>(slot) * n, z, n * 8);
  sampleTimes_[slot] = t;
  sampleOffsets_[slot] = offset;
}

void HermiteStorage::checkSamples() {
  if (keptTimes_.size() < 2) return;
  const std::size_t segment = keptTimes_.size() - 2;
  const std::size_t n = static_cast<std::size_t>(info().stateSize);
  const double* a = kept_.data() + segment * 2 * n;
  const double* b = a + 2 * n;
  const double ta = keptTimes_[segment], tb = keptTimes_[segment + 1];
  const double span = tb - ta;
  for (int slot = 0; slot < 2; ++slot) {
    if (sampleOffsets_[slot] < 0) continue;
    const double* sample = samples_.data() + static_cast<std::size_t>(slot) * n;
    const double s = (sampleTimes_[slot] - ta) / span;
    const double s2 = s * s, s3 = s2 * s;
    const double h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
    const double h10 = (s3 - 2.0 * s2 + s) * span;
    const double h01 = -2.0 * s3 + 3.0 * s2;
    const double h11 = (s3 - s2) * span;
    double difference = 0.0, scale = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double interpolated = h00 * a[i] + h10 * a[n + i] + h01 * b[i] + h11 * b[n + i];
      difference = std::max(difference, std::abs(interpolated - sample[i]));
      scale = std::max({scale, std::abs(a[i]), std::abs(b[i]), std::abs(sample[i])});
    }
    // A non-finite interpolant (an overflowing derivative) counts as the largest error.
    const double relative = std::isfinite(difference) ? (scale > 0.0 ? difference / scale : difference)
                                                      : std::numeric_limits<double>::infinity();
    worstRelativeError_ = std::max(worstRelativeError_, relative);
    sampleOffsets_[slot] = -1;
  }
}

void HermiteStorage::doBegin() {
  // begin() has released every byte; drop the buffers so that the charge matches what is held.
  std::vector<double>().swap(times_);
  std::vector<double>().swap(keptTimes_);
  std::vector<double>().swap(kept_);
  finished_ = false;
  sampleOffsets_[0] = sampleOffsets_[1] = -1;
  worstRelativeError_ = 0.0;
  // The samples of the error estimate: one state with N known, two without (see the header).
  const std::size_t sampleValues =
      every_ >= 2 ? static_cast<std::size_t>(info().stateSize) * (info().stepCount > 0 ? 1 : 2) : 0;
  if (sampleValues > 0) holdBytes(static_cast<std::int64_t>(sampleValues) * 8);
  if (samples_.size() != sampleValues) std::vector<double>(sampleValues).swap(samples_);
  const std::int64_t steps = info().stepCount;
  if (steps > 0) {
    // N known: one allocation each, charged up front, so recording never reallocates.
    const std::int64_t keptCount = (steps + every_ - 1) / every_ + 1;
    const std::int64_t n = info().stateSize;
    holdBytes((steps + 1 + keptCount + keptCount * 2 * n) * 8);
    times_.reserve(static_cast<std::size_t>(steps + 1));
    keptTimes_.reserve(static_cast<std::size_t>(keptCount));
    kept_.reserve(static_cast<std::size_t>(keptCount * 2 * n));
  }
}

void HermiteStorage::append(std::vector<double>& buffer, const double* values, std::size_t count) {
  if (buffer.size() + count > buffer.capacity()) {
    const std::size_t needed = buffer.size() + count;
    std::size_t capacity = std::max<std::size_t>(needed, std::max<std::size_t>(2 * buffer.capacity(), 256));
    // Grow less than geometrically when the budget would not allow it.
    const std::int64_t room = budgetBytes() - counters().bytesInMemory;
    const std::size_t affordable =
        buffer.capacity() + static_cast<std::size_t>(std::max<std::int64_t>(room, 0) / 8);
    capacity = std::max(needed, std::min(capacity, affordable));
    holdBytes(static_cast<std::int64_t>(capacity - buffer.capacity()) * 8);
    buffer.reserve(capacity);
  }
  buffer.insert(buffer.end(), values, values + count);
}

void HermiteStorage::keep(double t, ConstVectorRef z, ConstVectorRef zdot) {
  append(keptTimes_, &t, 1);
  append(kept_, z.data(), static_cast<std::size_t>(z.size()));
  append(kept_, zdot.data(), static_cast<std::size_t>(zdot.size()));
  ++mutableCounters().statesStored;
}

void HermiteStorage::doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) {
  append(times_, &t, 1);
  const std::int64_t offset = step % every_;
  if (offset == 0) {
    keep(t, z, zdot);
    checkSamples();  // the interval that ends here
    return;
  }
  if (info().stepCount > 0) {
    if (step == sampleStepAfter(step - offset)) holdSample(0, offset, t, z.data());
  } else if (offset == 1) {
    holdSample(0, offset, t, z.data());
  } else if (sampleOffsets_[1] < 0 && offset == 2 * sampleOffsets_[0]) {
    holdSample(1, offset, t, z.data());
  } else if (sampleOffsets_[1] > 0 && offset == 2 * sampleOffsets_[1]) {
    // The interval doubled: the later sample becomes the earlier one, this state the later one.
    holdSample(0, sampleOffsets_[1], sampleTimes_[1], samples_.data() + info().stateSize);
    holdSample(1, offset, t, z.data());
  }
}

void HermiteStorage::doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) {
  append(times_, &t, 1);
  keep(t, z, zdot);
  checkSamples();
  mutableCounters().gradientErrorEstimate = LossyStorage::kGradientSensitivity * worstRelativeError_;
  finished_ = true;
  if (worstRelativeError_ > tolerance_) {
    std::ostringstream msg;
    msg << "hermite.every = " << every_
        << " is too long for this trajectory: the interpolated states are off by " << worstRelativeError_
        << " (relative, measured mid-interval in the forward sweep) > hermite.tolerance = " << tolerance_
        << "; lower every (the error falls like every^4) or raise tolerance";
    throw std::invalid_argument(msg.str());
  }
}

void HermiteStorage::evaluate(std::size_t segment, double t, VectorRef z) const {
  const std::size_t n = static_cast<std::size_t>(info().stateSize);
  const double ta = keptTimes_[segment], tb = keptTimes_[segment + 1];
  const double span = tb - ta;
  const double s = (t - ta) / span;
  const double s2 = s * s, s3 = s2 * s;
  const double h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
  const double h10 = (s3 - 2.0 * s2 + s) * span;
  const double h01 = -2.0 * s3 + 3.0 * s2;
  const double h11 = (s3 - s2) * span;
  const double* a = kept_.data() + segment * 2 * n;
  const double* b = a + 2 * n;
  for (std::size_t i = 0; i < n; ++i) {
    z(static_cast<Eigen::Index>(i)) = h00 * a[i] + h10 * a[n + i] + h01 * b[i] + h11 * b[n + i];
  }
}

void HermiteStorage::doRestore(std::int64_t step, VectorRef z) {
  const std::size_t n = static_cast<std::size_t>(info().stateSize);
  const std::size_t segment = static_cast<std::size_t>(step / every_);
  if (step % every_ == 0) {
    std::memcpy(z.data(), kept_.data() + segment * 2 * n, n * 8);  // a kept point: the recorded bits
    return;
  }
  evaluate(segment, times_[static_cast<std::size_t>(step)], z);
}

void HermiteStorage::interpolate(double t, VectorRef z) {
  if (!finished_) throw std::logic_error("hermite storage: interpolate() before finish()");
  const double first = keptTimes_.front(), last = keptTimes_.back();
  if (!(t >= first && t <= last)) {
    std::ostringstream msg;
    msg << "hermite storage: interpolate(t = " << t << ") outside the trajectory [" << first << ", " << last
        << "]";
    throw std::invalid_argument(msg.str());
  }
  assert(z.size() == info().stateSize);
  if (keptTimes_.size() < 2) {  // a single kept point: only t = t0 = t_N
    std::memcpy(z.data(), kept_.data(), static_cast<std::size_t>(info().stateSize) * 8);
    return;
  }
  // The segment [t_a, t_b] containing t; t = t_N uses the last segment.
  auto it = std::upper_bound(keptTimes_.begin(), keptTimes_.end(), t);
  std::size_t segment = static_cast<std::size_t>(it - keptTimes_.begin());
  segment = segment == 0 ? 0 : segment - 1;
  if (segment + 1 >= keptTimes_.size()) segment = keptTimes_.size() - 2;
  evaluate(segment, t, z);
}

}  // namespace hindsight
