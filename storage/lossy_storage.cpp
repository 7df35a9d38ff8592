#include <hindsight/storage/lossy_storage.h>

#include <hindsight/engine/deterministic_math.h>
#include <hindsight/engine/storage_spec.h>

#include <zfp.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace hindsight {
namespace {

constexpr int kZstdLevel = 3;

// RAII for the ZFP objects of one (de)compression.
struct ZfpRun {
  zfp_field* field = nullptr;
  zfp_stream* stream = nullptr;
  bitstream* bits = nullptr;
  ZfpRun(double* values, std::size_t count, double tolerance, void* buffer, std::size_t capacity) {
    field = zfp_field_1d(values, zfp_type_double, count);
    stream = zfp_stream_open(nullptr);
    zfp_stream_set_accuracy(stream, tolerance);
    if (buffer != nullptr) {
      bits = stream_open(buffer, capacity);
      zfp_stream_set_bit_stream(stream, bits);
      zfp_stream_rewind(stream);
    }
  }
  ~ZfpRun() {
    if (bits != nullptr) stream_close(bits);
    zfp_stream_close(stream);
    zfp_field_free(field);
  }
  ZfpRun(const ZfpRun&) = delete;
  ZfpRun& operator=(const ZfpRun&) = delete;
};

}  // namespace

bool LossyStorage::Options::IsValid(std::string* error) const {
  std::string message;
  if (lossless && codec != Codec::kTime) {
    message = "packed: lossless coding is the time codec's";
  } else if (!(tolerance > 0.0) || !std::isfinite(tolerance)) {
    message = "lossy.tolerance = " + shortestText(tolerance) + " must be a positive number";
  } else if ((codec == Codec::kRound || codec == Codec::kTime) && tolerance > 0.5) {
    message = "lossy.tolerance = " + shortestText(tolerance) +
              " must be in (0, 0.5] for codec=" + (codec == Codec::kRound ? "round" : "time") + " (relative)";
  } else if (target != 0.0 && !(target >= kMinTarget && target <= kMaxTarget)) {
    message = "lossy.target = " + shortestText(target) + " must be in [1e-14, 0.1]";
  } else if (sensitivity != 0.0 && !(sensitivity >= kMinSensitivity && sensitivity <= kMaxSensitivity)) {
    message = "lossy.sensitivity = " + shortestText(sensitivity) + " must be in [0.001, 1000]";
  } else if (sensitivity != 0.0 && target == 0.0) {
    message = "lossy.sensitivity goes with target=T (it sets the tolerance T / sensitivity)";
  } else if (budgetBytes <= 0) {
    message = "lossy.budget = " + std::to_string(budgetBytes) + " must be positive";
  } else if (blockStates < 0) {
    message = "lossy.block = " + std::to_string(blockStates) + " must be positive (or 0 for automatic)";
  }
  if (error != nullptr) *error = message;
  return message.empty();
}

LossyStorage::LossyStorage(Options options)
    : TrajectoryStorage(std::max<std::int64_t>(1, options.budgetBytes)), options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument(error);
}

std::unique_ptr<TrajectoryStorage> LossyStorage::create(const StorageSpec& spec) {
  Options options;
  options.budgetBytes = spec.bytes("budget", kDefaultBudget);
  options.blockStates = spec.integer("block", 0, 1, std::int64_t{1} << 30);
  if (spec.has("target")) {
    if (spec.has("codec") || spec.has("tolerance"))
      throw std::invalid_argument(
          "lossy.target sets codec and tolerance itself: give target or codec+tolerance");
    options.target = spec.real("target", 0.0, kMinTarget, kMaxTarget);
    options.sensitivity = spec.real("sensitivity", 0.0, kMinSensitivity, kMaxSensitivity);
    options.codec = Codec::kTime;
    options.tolerance =
        options.target / (options.sensitivity > 0.0 ? options.sensitivity : kGradientSensitivity);
    return std::make_unique<LossyStorage>(options);
  }
  if (spec.has("sensitivity"))
    throw std::invalid_argument(
        "lossy.sensitivity goes with target=T (it sets the tolerance T / sensitivity)");
  const std::string codec = spec.text("codec", "", {"zfp", "round", "time"});
  if (codec.empty())
    throw std::invalid_argument(
        "lossy needs target=T (e.g. target=1e-6) or codec=zfp|round|time with tolerance");
  if (!spec.has("tolerance")) throw std::invalid_argument("lossy.tolerance is required, e.g. tolerance=1e-6");
  options.codec = codec == "zfp" ? Codec::kZfp : codec == "round" ? Codec::kRound : Codec::kTime;
  options.tolerance = spec.real("tolerance", 0.0, std::numeric_limits<double>::min(),
                                codec == "zfp" ? std::numeric_limits<double>::max() : 0.5);
  return std::make_unique<LossyStorage>(options);
}

std::unique_ptr<TrajectoryStorage> LossyStorage::createPacked(const StorageSpec& spec) {
  Options options;
  options.codec = Codec::kTime;
  options.lossless = true;
  options.budgetBytes = spec.bytes("budget", kDefaultBudget);
  options.blockStates = spec.integer("block", 0, 1, std::int64_t{1} << 30);
  return std::make_unique<LossyStorage>(options);
}

std::string LossyStorage::spec() const {
  if (options_.lossless) {
    std::string text = "packed";
    char separator = ':';
    if (options_.budgetBytes != kDefaultBudget) {
      text += separator + std::string("budget=") + std::to_string(options_.budgetBytes);
      separator = ',';
    }
    if (options_.blockStates > 0)
      text += separator + std::string("block=") + std::to_string(options_.blockStates);
    return text;
  }
  std::string text = options_.target > 0.0 ? "lossy:target=" + shortestText(options_.target)
                                           : std::string("lossy:codec=") +
                                                 (options_.codec == Codec::kZfp     ? "zfp"
                                                  : options_.codec == Codec::kRound ? "round"
                                                                                    : "time") +
                                                 ",tolerance=" + shortestText(options_.tolerance);
  // A calibrated factor is part of what the run did: the spec says it (and gives it back when parsed).
  if (options_.target > 0.0 && sensitivity() != kGradientSensitivity)
    text += ",sensitivity=" + shortestText(sensitivity());
  if (options_.budgetBytes != kDefaultBudget) text += ",budget=" + std::to_string(options_.budgetBytes);
  if (options_.blockStates > 0) text += ",block=" + std::to_string(options_.blockStates);
  return text;
}

double LossyStorage::sensitivity() const {
  if (options_.sensitivity > 0.0) return options_.sensitivity;
  return calibrated_ > 0.0 ? calibrated_ : kGradientSensitivity;
}

void LossyStorage::calibrate(double sensitivity) {
  if (!(sensitivity >= kMinSensitivity && sensitivity <= kMaxSensitivity))
    throw std::invalid_argument("lossy: a calibrated sensitivity of " + shortestText(sensitivity) +
                                " is outside [0.001, 1000]");
  if (options_.target <= 0.0) return;  // the expert codecs keep their own tolerance and estimate
  calibrated_ = sensitivity;
  options_.tolerance = options_.target / this->sensitivity();
}

int LossyStorage::keptMantissaBits(double relativeTolerance) {
  // Round to nearest with m kept bits errs by at most half a unit in the last kept place:
  // |x~ - x| <= 2^(e - m - 1) <= 2^-(m+1) |x| for |x| in [2^e, 2^(e+1)).
  const double bits = std::ceil(-dmath::log2(relativeTolerance)) - 1.0;
  return static_cast<int>(std::clamp(bits, 0.0, 52.0));
}

void LossyStorage::roundMantissas(double* values, std::size_t count, int bits) {
  if (bits >= 52) return;
  const int shift = 52 - bits;
  const std::uint64_t half = (std::uint64_t{1} << (shift - 1)) - 1;
  const std::uint64_t mask = ~((std::uint64_t{1} << shift) - 1);
  for (std::size_t i = 0; i < count; ++i) {
    if (!std::isfinite(values[i])) continue;
    std::uint64_t word;
    std::memcpy(&word, values + i, 8);
    // Klöwer et al. 2021: add half an ulp minus one plus the last kept bit (ties to even), truncate.
    word = (word + half + ((word >> shift) & 1u)) & mask;
    double rounded;
    std::memcpy(&rounded, &word, 8);
    if (std::isfinite(rounded)) values[i] = rounded;  // rounding up past the largest double: keep x
  }
}

void LossyStorage::doBegin() {
  blocks_.clear();
  statesInRaw_ = 0;
  decodedBlock_ = -1;
  const std::int64_t n = info().stateSize;
  std::int64_t block = options_.blockStates;
  if (block == 0) block = std::clamp<std::int64_t>((std::int64_t{256} << 10) / stateBytes(), 1, 4096);
  // The time codec predicts from the previous states of the block: large states get at least 16 per
  // block (e.g. the full-order rod, where 256 KiB would hold 3 states of 10^4 doubles).
  if (options_.blockStates == 0 && options_.codec == Codec::kTime) block = std::max<std::int64_t>(block, 16);
  if (info().stepCount > 0) block = std::min(block, info().stepCount);
  blockStates_ = block;
  componentMajor_ = n <= block && options_.codec != Codec::kTime;  // the time codec takes rows
  const std::size_t values = static_cast<std::size_t>(block * n);
  std::size_t scratchBytes = ZSTD_compressBound(values * 8);
  worstRelativeError_ = 0.0;
  if (options_.codec == Codec::kTime) {
    timeCodec_ = std::make_unique<internal::TimeCodec>(static_cast<int>(n), block);
    scratchBytes = timeCodec_->maxEncodedBytes();
    // The codec's own work buffers: residuals, byte planes, one series, exceptions (worst case).
    holdBytes(static_cast<std::int64_t>(values) * 16 + block * 8 + 2 * n * 8);
    bounds_.assign(static_cast<std::size_t>(n), 0.0);
    scale_.assign(static_cast<std::size_t>(n), 0.0);
    mutableCounters().gradientErrorEstimate = 0.0;
  } else if (options_.codec == Codec::kZfp) {
    ZfpRun run(nullptr, values, options_.tolerance, nullptr, 0);
    scratchBytes = zfp_stream_maximum_size(run.stream, run.field);
  }
  holdBytes(2 * static_cast<std::int64_t>(values) * 8 + static_cast<std::int64_t>(scratchBytes));
  raw_.assign(values, 0.0);
  work_.assign(values, 0.0);
  scratch_.assign(scratchBytes, 0);
}

void LossyStorage::doRecord(std::int64_t, double, ConstVectorRef z, ConstVectorRef) {
  const std::int64_t n = info().stateSize;
  std::memcpy(raw_.data() + statesInRaw_ * n, z.data(), static_cast<std::size_t>(n) * 8);
  ++statesInRaw_;
  ++mutableCounters().statesStored;
  if (statesInRaw_ == blockStates_) compressBlock();
}

void LossyStorage::doFinish(double, ConstVectorRef, ConstVectorRef) {
  if (statesInRaw_ > 0) compressBlock();
}

void LossyStorage::compressBlock() {
  const std::int64_t n = info().stateSize;
  const std::int64_t count = statesInRaw_;
  const std::size_t values = static_cast<std::size_t>(count * n);
  if (componentMajor_) {  // each component contiguous in time
    for (std::int64_t i = 0; i < count; ++i) {
      for (std::int64_t j = 0; j < n; ++j) {
        work_[static_cast<std::size_t>(j * count + i)] = raw_[static_cast<std::size_t>(i * n + j)];
      }
    }
  } else {  // each state contiguous in space
    std::memcpy(work_.data(), raw_.data(), values * 8);
  }
  std::size_t size = 0;
  if (options_.lossless) {
    size = timeCodec_->encode(raw_.data(), count, internal::TimeCodec::kLosslessOrder, scratch_.data());
  } else if (options_.codec == Codec::kTime) {
    for (std::int64_t j = 0; j < n; ++j) {
      double largest = 0.0;
      for (std::int64_t i = 0; i < count; ++i)
        largest = std::max(largest, std::abs(raw_[static_cast<std::size_t>(i * n + j)]));
      scale_[static_cast<std::size_t>(j)] = std::isfinite(largest) ? largest : 0.0;
      bounds_[static_cast<std::size_t>(j)] = options_.tolerance * scale_[static_cast<std::size_t>(j)];
    }
    double worst = 0.0;
    size = timeCodec_->encodeBounded(raw_.data(), count, internal::TimeCodec::kBoundedOrder, bounds_.data(),
                                     scratch_.data(), scale_.data(), &worst);
    worstRelativeError_ = std::max(worstRelativeError_, worst);
    mutableCounters().gradientErrorEstimate = sensitivity() * worstRelativeError_;
  } else if (options_.codec == Codec::kZfp) {
    // ZFP's absolute bound T against each component's largest magnitude in the block: the relative
    // state error the estimate is made of (infinite for a component that is zero over a block: the
    // bound cannot say that such a component is reproduced exactly, so neither does the estimate).
    for (std::int64_t j = 0; j < n; ++j) {
      double largest = 0.0;
      for (std::int64_t i = 0; i < count; ++i)
        largest = std::max(largest, std::abs(raw_[static_cast<std::size_t>(i * n + j)]));
      const double relative = largest > 0.0 && std::isfinite(largest)
                                  ? options_.tolerance / largest
                                  : std::numeric_limits<double>::infinity();
      worstRelativeError_ = std::max(worstRelativeError_, relative);
    }
    mutableCounters().gradientErrorEstimate = kGradientSensitivity * worstRelativeError_;
    ZfpRun run(work_.data(), values, options_.tolerance, scratch_.data(), scratch_.size());
    size = zfp_compress(run.stream, run.field);
    if (size == 0) throw StorageError("lossy storage: ZFP compression failed");
  } else {
    // Every value within T of itself, relatively: so is every component against its largest magnitude.
    worstRelativeError_ = std::max(worstRelativeError_, options_.tolerance);
    mutableCounters().gradientErrorEstimate = kGradientSensitivity * worstRelativeError_;
    roundMantissas(work_.data(), values, keptMantissaBits(options_.tolerance));
    // Byte shuffle into raw_ (consumed above): byte b of every value together.
    auto* shuffled = reinterpret_cast<unsigned char*>(raw_.data());
    const auto* bytes = reinterpret_cast<const unsigned char*>(work_.data());
    for (std::size_t i = 0; i < values; ++i) {
      for (std::size_t b = 0; b < 8; ++b) shuffled[b * values + i] = bytes[i * 8 + b];
    }
    size = ZSTD_compress(scratch_.data(), scratch_.size(), shuffled, values * 8, kZstdLevel);
    if (ZSTD_isError(size))
      throw StorageError(std::string("lossy storage: zstd failed: ") + ZSTD_getErrorName(size));
  }
  holdBytes(static_cast<std::int64_t>(size));
  Block block{count, static_cast<std::int64_t>(size),
              std::unique_ptr<unsigned char[]>(new unsigned char[size])};
  std::memcpy(block.data.get(), scratch_.data(), size);
  blocks_.push_back(std::move(block));
  StorageCounters& c = mutableCounters();
  c.uncompressedBytes += static_cast<std::int64_t>(values) * 8;
  c.compressedBytes += static_cast<std::int64_t>(size);
  statesInRaw_ = 0;
}

void LossyStorage::decodeBlock(std::size_t index) {
  Block& block = blocks_[index];
  const std::size_t values = static_cast<std::size_t>(block.states * info().stateSize);
  if (options_.codec == Codec::kTime) {
    timeCodec_->decode(block.data.get(), static_cast<std::size_t>(block.bytes), block.states, work_.data(),
                       "lossy storage: a compressed block");
  } else if (options_.codec == Codec::kZfp) {
    ZfpRun run(work_.data(), values, options_.tolerance, block.data.get(),
               static_cast<std::size_t>(block.bytes));
    if (zfp_decompress(run.stream, run.field) == 0)
      throw StorageError("lossy storage: ZFP decompression failed");
  } else {
    auto* shuffled = reinterpret_cast<unsigned char*>(raw_.data());
    const std::size_t size =
        ZSTD_decompress(shuffled, values * 8, block.data.get(), static_cast<std::size_t>(block.bytes));
    if (ZSTD_isError(size) || size != values * 8)
      throw StorageError("lossy storage: zstd decompression failed");
    auto* bytes = reinterpret_cast<unsigned char*>(work_.data());
    for (std::size_t i = 0; i < values; ++i) {
      for (std::size_t b = 0; b < 8; ++b) bytes[i * 8 + b] = shuffled[b * values + i];
    }
  }
  decodedBlock_ = static_cast<std::int64_t>(index);
  decodedStates_ = block.states;
  releaseBytes(block.bytes);  // the backward sweep never comes back to this block
  block.data.reset();
  block.bytes = 0;
}

void LossyStorage::doRestore(std::int64_t step, VectorRef z) {
  const std::int64_t index = step / blockStates_;
  if (index != decodedBlock_) decodeBlock(static_cast<std::size_t>(index));
  const std::int64_t i = step - index * blockStates_;
  const std::int64_t n = info().stateSize;
  if (componentMajor_) {
    for (std::int64_t j = 0; j < n; ++j) z(j) = work_[static_cast<std::size_t>(j * decodedStates_ + i)];
  } else {
    std::memcpy(z.data(), work_.data() + i * n, static_cast<std::size_t>(n) * 8);
  }
}

}  // namespace hindsight
