#include <hindsight/engine/trajectory_storage.h>

#include <hindsight/engine/hash.h>

#include <cmath>
#include <cstring>
#include <sstream>

namespace hindsight {

TrajectoryStorage::TrajectoryStorage(std::int64_t budgetBytes) : budgetBytes_(budgetBytes) {
  if (budgetBytes <= 0) {
    throw std::invalid_argument("storage budget must be positive, got " + std::to_string(budgetBytes) +
                                " bytes");
  }
}

void TrajectoryStorage::begin(const TrajectoryInfo& info, StepRecomputer& recomputer) {
  if (info.stateSize <= 0) {
    throw std::invalid_argument("TrajectoryInfo.stateSize must be positive, got " +
                                std::to_string(info.stateSize));
  }
  if (!(info.t1 > info.t0)) {
    throw std::invalid_argument("TrajectoryInfo: t1 must exceed t0");
  }
  if (counters_.bytesInMemory != 0) releaseBytes(counters_.bytesInMemory);
  info_ = info;
  recomputer_ = &recomputer;
  counters_ = StorageCounters{};
  stepCount_ = -1;
  nextRecord_ = 0;
  nextRestore_ = -1;
  hashes_.clear();
  stepDataHashes_.clear();
  expectedStepDataCall_ = StepDataCall::kNone;
  if (info.stepDataSize < 0) {
    throw std::invalid_argument("TrajectoryInfo.stepDataSize must be >= 0, got " +
                                std::to_string(info.stepDataSize));
  }
  phase_ = Phase::kForward;
  doBegin();
}

void TrajectoryStorage::record(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) {
  if (phase_ != Phase::kForward)
    throw std::logic_error("TrajectoryStorage::record outside the forward sweep");
  if (step != nextRecord_) {
    throw std::logic_error("TrajectoryStorage::record: expected step " + std::to_string(nextRecord_) +
                           ", got " + std::to_string(step));
  }
  assert(z.size() == info_.stateSize);
  if (expectedStepDataCall_ != StepDataCall::kNone)
    throw std::logic_error("TrajectoryStorage::record: recordStepData missing for the previous step");
  if (verifyRestores_) hashes_.push_back(hashState(z));
  doRecord(step, t, z, zdot);
  ++nextRecord_;
  if (info_.stepDataSize > 0) expectedStepDataCall_ = StepDataCall::kRecord;
}

void TrajectoryStorage::recordStepData(std::int64_t step, ConstVectorRef data) {
  if (expectedStepDataCall_ != StepDataCall::kRecord || step != nextRecord_ - 1 ||
      data.size() != info_.stepDataSize) {
    throw std::logic_error("TrajectoryStorage::recordStepData(" + std::to_string(step) +
                           ") not right after record(" + std::to_string(step) +
                           ") with stepDataSize doubles");
  }
  expectedStepDataCall_ = StepDataCall::kNone;
  if (verifyRestores_) stepDataHashes_.push_back(hashState(data));
  doRecordStepData(step, data);
}

bool TrajectoryStorage::restoreStepData(std::int64_t step, VectorRef data) {
  if (expectedStepDataCall_ != StepDataCall::kRestore || step != nextRestore_ + 1 ||
      data.size() != info_.stepDataSize) {
    throw std::logic_error("TrajectoryStorage::restoreStepData(" + std::to_string(step) +
                           ") not right after restore(" + std::to_string(step) +
                           ") with stepDataSize doubles");
  }
  expectedStepDataCall_ = StepDataCall::kNone;
  const bool restored = doRestoreStepData(step, data);
  if (restored) {
    ++counters_.stepDataRestored;
    if (verifyRestores_ && isExact() && hashState(data) != stepDataHashes_[static_cast<std::size_t>(step)]) {
      throw std::logic_error("storage '" + spec() + "' restored different step data for step " +
                             std::to_string(step));
    }
  }
  return restored;
}

void TrajectoryStorage::finish(std::int64_t stepCount, double t, ConstVectorRef z, ConstVectorRef zdot) {
  if (phase_ != Phase::kForward || stepCount != nextRecord_ || expectedStepDataCall_ != StepDataCall::kNone) {
    throw std::logic_error("TrajectoryStorage::finish: " + std::to_string(nextRecord_) +
                           " steps recorded, finish(" + std::to_string(stepCount) + ")");
  }
  stepCount_ = stepCount;
  doFinish(t, z, zdot);
  phase_ = Phase::kBackward;
  nextRestore_ = stepCount - 1;
}

void TrajectoryStorage::restore(std::int64_t step, VectorRef z) {
  if (phase_ != Phase::kBackward || step != nextRestore_ || expectedStepDataCall_ != StepDataCall::kNone) {
    throw std::logic_error("TrajectoryStorage::restore: expected step " + std::to_string(nextRestore_) +
                           ", got " + std::to_string(step));
  }
  if (verifyRestores_ && info_.workingStateHoldsLast && step == stepCount_ - 1 &&
      hashState(z) != hashes_[static_cast<std::size_t>(step)]) {
    throw std::logic_error(
        "TrajectoryStorage::restore(" + std::to_string(step) +
        "): TrajectoryInfo.workingStateHoldsLast is set, but z is not the state recorded last");
  }
  doRestore(step, z);
  if (verifyRestores_ && isExact() && hashState(z) != hashes_[static_cast<std::size_t>(step)]) {
    throw std::logic_error("storage '" + spec() + "' restored different bits for step " +
                           std::to_string(step));
  }
  --nextRestore_;
  if (info_.stepDataSize > 0) expectedStepDataCall_ = StepDataCall::kRestore;
  if (nextRestore_ < 0) phase_ = Phase::kIdle;
}

void TrajectoryStorage::holdBytes(std::int64_t bytes) {
  if (!fits(bytes)) {
    throw StorageError("storage '" + spec() + "' would exceed its budget of " + formatBytes(budgetBytes_) +
                       " (holds " + formatBytes(counters_.bytesInMemory) + ", needs " + formatBytes(bytes) +
                       " more); raise the budget or choose a checkpointing strategy");
  }
  counters_.bytesInMemory += bytes;
  if (counters_.bytesInMemory > counters_.peakBytesInMemory)
    counters_.peakBytesInMemory = counters_.bytesInMemory;
}

void TrajectoryStorage::releaseBytes(std::int64_t bytes) {
  assert(bytes <= counters_.bytesInMemory);
  counters_.bytesInMemory -= bytes;
}

void TrajectoryStorage::recompute(std::int64_t step, VectorRef z) {
  recomputer_->advance(step, z);
  ++counters_.recomputedSteps;
}

std::uint64_t hashState(ConstVectorRef z) {
  std::uint64_t h = kFnv1aOffsetBasis;
  for (Eigen::Index i = 0; i < z.size(); ++i) {
    // The little-endian bytes, so that the hash does not depend on the host's byte order.
    std::uint64_t bits;
    std::memcpy(&bits, z.data() + i, sizeof bits);
    unsigned char bytes[8];
    for (int b = 0; b < 8; ++b) bytes[b] = static_cast<unsigned char>(bits >> (8 * b));
    h = fnv1a(bytes, sizeof bytes, h);
  }
  return h;
}

std::int64_t parseBytes(const std::string& text, const std::string& field) {
  std::size_t pos = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &pos);
  } catch (const std::exception&) {
    pos = 0;
  }
  const std::string unit = text.substr(pos);
  double scale = 0.0;
  if (unit.empty() || unit == "B")
    scale = 1.0;
  else if (unit == "KiB")
    scale = 1024.0;
  else if (unit == "MiB")
    scale = 1024.0 * 1024.0;
  else if (unit == "GiB")
    scale = 1024.0 * 1024.0 * 1024.0;
  else if (unit == "TiB")
    scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
  else if (unit == "kB" || unit == "KB")
    scale = 1e3;
  else if (unit == "MB")
    scale = 1e6;
  else if (unit == "GB")
    scale = 1e9;
  // Less than one byte ("0.5", ".024") would truncate to a budget of 0, which no strategy can use.
  if (pos == 0 || scale == 0.0 || !(value * scale >= 1.0) || !std::isfinite(value) ||
      value * scale > 9.0e18) {
    throw std::invalid_argument(field + " = '" + text +
                                "' is not a positive byte count (examples: 4096, 64KiB, 32MiB, 4GiB, 10MB)");
  }
  return static_cast<std::int64_t>(value * scale);
}

std::string formatBytes(std::int64_t bytes) {
  if (bytes == TrajectoryStorage::kUnlimitedBytes) return "unlimited";
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double value = static_cast<double>(bytes);
  int u = 0;
  while (value >= 1024.0 && u < 4) {
    value /= 1024.0;
    ++u;
  }
  std::ostringstream out;
  out.precision(u == 0 ? 0 : 1);
  out << std::fixed << value << ' ' << units[u];
  return out.str();
}

void throwBackwardSweepFailure(const NumericalError& failure, const TrajectoryStorage& storage,
                               const std::string& sweep) {
  std::string what = failure.what();
  const std::size_t suffix = what.rfind(" (at t = ");
  if (suffix != std::string::npos) what.erase(suffix);  // NumericalError appends the time again
  std::string message =
      "backward sweep (" + sweep + ") with storage '" + storage.spec() + "' failed: " + what;
  if (!storage.isExact()) {
    message +=
        "; the storage is approximate (the states it restores are not the recorded ones), which a stiff "
        "problem's backward sweep may not tolerate: try a tighter setting or an exact storage";
  }
  throw NumericalError(message, failure.time());
}

}  // namespace hindsight
