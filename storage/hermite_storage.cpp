#include <hindsight/storage/hermite_storage.h>

#include <algorithm>
#include <cstring>
#include <sstream>

namespace hindsight {

HermiteStorage::HermiteStorage(std::int64_t every, std::int64_t budgetBytes)
    : TrajectoryStorage(budgetBytes), every_(every) {
  if (every < 1) {
    throw std::invalid_argument("hermite.every = " + std::to_string(every) + " must be in [1, 1000000000]");
  }
}

std::unique_ptr<TrajectoryStorage> HermiteStorage::create(const StorageSpec& spec) {
  return std::make_unique<HermiteStorage>(spec.integer("every", kDefaultEvery, 1, 1'000'000'000),
                                          spec.bytes("budget", kDefaultBudget));
}

std::string HermiteStorage::spec() const {
  std::string text = "hermite:every=" + std::to_string(every_);
  if (budgetBytes() != kDefaultBudget) text += ",budget=" + std::to_string(budgetBytes());
  return text;
}

void HermiteStorage::doBegin() {
  // begin() has released every byte; drop the buffers so that the charge matches what is held.
  std::vector<double>().swap(times_);
  std::vector<double>().swap(keptTimes_);
  std::vector<double>().swap(kept_);
  finished_ = false;
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
  if (step % every_ == 0) keep(t, z, zdot);
}

void HermiteStorage::doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) {
  append(times_, &t, 1);
  keep(t, z, zdot);
  finished_ = true;
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
