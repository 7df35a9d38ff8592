#include <hindsight/storage/time_codec.h>

#include <hindsight/engine/hash.h>

#include <hdf5.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>

namespace hindsight::internal {
namespace {

constexpr unsigned char kMagic[4] = {'H', 'T', 'C', '1'};

// Binomial extrapolation weights: the polynomial of degree k through x[i-1..i-1-k] evaluated at i is
// sum_m w[k][m] x[i-1-m], w[k][m] = (-1)^m C(k+1, m+1).
struct Weights {
  double w[TimeCodec::kMaxOrder + 1][TimeCodec::kMaxOrder + 1] = {};
  Weights() {
    for (int k = 0; k <= TimeCodec::kMaxOrder; ++k) {
      double binomial = 1.0;  // C(k+1, m+1), built up from C(k+1, 1) = k + 1
      for (int m = 0; m <= k; ++m) {
        binomial = m == 0 ? k + 1.0 : binomial * (k + 1.0 - m) / (m + 1.0);
        w[k][m] = (m % 2 == 0 ? 1.0 : -1.0) * binomial;
      }
    }
  }
};
const Weights kWeights;

// The prediction of series[i] from series[i-1], series[i-2], ...: the order ramps up to `order` over
// the block's first values; 0 for the first one. The same expression in encoder and decoder, so the
// prediction has the same bits on both sides.
inline double predict(const double* series, std::int64_t i, int order) {
  if (i == 0) return 0.0;
  const int k = static_cast<int>(std::min<std::int64_t>(order, i - 1));
  const double* w = kWeights.w[k];
  double sum = 0.0;
  for (int m = 0; m <= k; ++m) sum += w[m] * series[i - 1 - m];
  return sum;
}

inline std::uint64_t bitsOf(double x) {
  std::uint64_t u;
  std::memcpy(&u, &x, 8);
  return u;
}
inline double fromBits(std::uint64_t u) {
  double x;
  std::memcpy(&x, &u, 8);
  return x;
}
inline std::uint64_t zigzag(std::uint64_t d) {
  return (d << 1) ^ static_cast<std::uint64_t>(static_cast<std::int64_t>(d) >> 63);
}
inline std::uint64_t unzigzag(std::uint64_t z) { return (z >> 1) ^ (~(z & 1) + 1); }

template <class T>
void put(unsigned char*& p, T value) {
  std::memcpy(p, &value, sizeof(T));
  p += sizeof(T);
}
template <class T>
T get(const unsigned char*& p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  p += sizeof(T);
  return value;
}

[[noreturn]] void corrupt(const char* what, const std::string& why) {
  throw StorageError(std::string(what) + " is corrupted: " + why);
}

}  // namespace

TimeCodec::TimeCodec(int n, std::int64_t maxStates, int zstdLevel)
    : n_(n), maxStates_(maxStates), level_(zstdLevel) {
  const std::size_t values = static_cast<std::size_t>(maxStates) * static_cast<std::size_t>(n);
  residuals_.resize(values);
  shuffled_.resize(values * 8);
  reconstructed_.resize(static_cast<std::size_t>(maxStates));
  exceptions_.reserve(2 * values);
  // Header, bounds, every value an exception in the worst case, and zstd's bound on the residuals.
  maxEncoded_ = kHeaderBytes + static_cast<std::size_t>(n) * 8 + values * 16 + ZSTD_compressBound(values * 8);
}

std::size_t TimeCodec::encode(const double* rows, std::int64_t count, int order, unsigned char* out) {
  const std::int64_t n = n_;
  for (std::int64_t j = 0; j < n; ++j) {
    std::uint64_t* r = residuals_.data() + j * count;
    // The component's series is strided in rows; gather it into reconstructed_ (exact copy here).
    double* series = reconstructed_.data();
    for (std::int64_t i = 0; i < count; ++i) series[i] = rows[i * n + j];
    for (std::int64_t i = 0; i < count; ++i) {
      r[i] = zigzag(bitsOf(series[i]) - bitsOf(predict(series, i, order)));
    }
  }
  exceptions_.clear();
  return finish(0, order, count, nullptr, out);
}

std::size_t TimeCodec::encodeBounded(const double* rows, std::int64_t count, int order, const double* bounds,
                                     unsigned char* out, const double* scale, double* maxRelativeError) {
  const std::int64_t n = n_;
  exceptions_.clear();
  double worst = 0.0;
  for (std::int64_t j = 0; j < n; ++j) {
    std::uint64_t* r = residuals_.data() + j * count;
    double* y = reconstructed_.data();
    const double bound = bounds[j];
    const double step = 2.0 * bound;
    double componentWorst = 0.0;
    for (std::int64_t i = 0; i < count; ++i) {
      const double x = rows[i * n + j];
      const double prediction = predict(y, i, order);
      double q = 0.0;
      if (step > 0.0) q = std::nearbyint((x - prediction) / step);
      const double restored = prediction + q * step;
      if (std::isfinite(x) && std::isfinite(restored) && std::abs(q) < 9.0e15 &&
          std::abs(restored - x) <= bound) {
        r[i] = zigzag(static_cast<std::uint64_t>(static_cast<std::int64_t>(q)));
        y[i] = restored;
        componentWorst = std::max(componentWorst, std::abs(restored - x));
      } else {  // kept exactly
        r[i] = 0;
        y[i] = x;
        exceptions_.push_back(static_cast<std::uint64_t>(j * count + i));
        exceptions_.push_back(bitsOf(x));
      }
    }
    if (scale != nullptr && scale[j] > 0.0) worst = std::max(worst, componentWorst / scale[j]);
  }
  if (maxRelativeError != nullptr) *maxRelativeError = worst;
  return finish(1, order, count, bounds, out);
}

std::size_t TimeCodec::finish(int mode, int order, std::int64_t count, const double* bounds,
                              unsigned char* out) {
  const std::size_t values = static_cast<std::size_t>(count) * static_cast<std::size_t>(n_);
  // Byte shuffle: byte b of residual v goes to plane b.
  unsigned char* planes = shuffled_.data();
  for (std::size_t v = 0; v < values; ++v) {
    const std::uint64_t r = residuals_[v];
    for (std::size_t b = 0; b < 8; ++b) planes[b * values + v] = static_cast<unsigned char>(r >> (8 * b));
  }
  unsigned char* payload = out + kHeaderBytes;
  unsigned char* p = payload;
  if (mode == 1) {
    std::memcpy(p, bounds, static_cast<std::size_t>(n_) * 8);
    p += static_cast<std::size_t>(n_) * 8;
  }
  if (!exceptions_.empty()) {
    std::memcpy(p, exceptions_.data(), exceptions_.size() * 8);
    p += exceptions_.size() * 8;
  }
  const std::size_t capacity = maxEncoded_ - static_cast<std::size_t>(p - out);
  const std::size_t size = ZSTD_compress(p, capacity, planes, values * 8, level_);
  if (ZSTD_isError(size))
    throw StorageError(std::string("time codec: zstd failed: ") + ZSTD_getErrorName(size));
  p += size;
  const std::int64_t payloadBytes = p - payload;
  unsigned char* h = out;
  std::memcpy(h, kMagic, 4);
  h += 4;
  put<std::uint8_t>(h, static_cast<std::uint8_t>(mode));
  put<std::uint8_t>(h, static_cast<std::uint8_t>(order));
  put<std::uint16_t>(h, 0);
  put<std::int64_t>(h, count);
  put<std::int32_t>(h, n_);
  put<std::int32_t>(h, static_cast<std::int32_t>(exceptions_.size() / 2));
  put<std::int64_t>(h, payloadBytes);
  // The checksum covers the header's first 32 bytes and the payload.
  put<std::uint64_t>(h, fnv1a(payload, static_cast<std::size_t>(payloadBytes), fnv1a(out, kHeaderBytes - 8)));
  return kHeaderBytes + static_cast<std::size_t>(payloadBytes);
}

std::int64_t TimeCodec::blockStates(const unsigned char* in, std::size_t size) {
  if (size < kHeaderBytes || std::memcmp(in, kMagic, 4) != 0) return 0;
  std::int64_t count;
  std::memcpy(&count, in + 8, 8);
  return count;
}

void TimeCodec::decode(const unsigned char* in, std::size_t size, std::int64_t count, double* rows,
                       const char* what) {
  if (size < kHeaderBytes) corrupt(what, "shorter than its header");
  const unsigned char* h = in;
  if (std::memcmp(h, kMagic, 4) != 0) corrupt(what, "bad magic");
  h += 4;
  const int mode = get<std::uint8_t>(h);
  const int order = get<std::uint8_t>(h);
  get<std::uint16_t>(h);
  const std::int64_t storedCount = get<std::int64_t>(h);
  const std::int32_t storedN = get<std::int32_t>(h);
  const std::int32_t exceptionCount = get<std::int32_t>(h);
  const std::int64_t payloadBytes = get<std::int64_t>(h);
  const std::uint64_t checksum = get<std::uint64_t>(h);
  if (mode > 1 || order > kMaxOrder) corrupt(what, "unknown mode or order");
  if (storedCount != count || storedN != n_ || count > maxStates_) {
    corrupt(what, "holds " + std::to_string(storedCount) + " x " + std::to_string(storedN) +
                      " values, expected " + std::to_string(count) + " x " + std::to_string(n_));
  }
  if (payloadBytes < 0 || static_cast<std::uint64_t>(payloadBytes) != size - kHeaderBytes)
    corrupt(what, "payload size does not match");
  const unsigned char* payload = in + kHeaderBytes;
  if (fnv1a(payload, static_cast<std::size_t>(payloadBytes), fnv1a(in, kHeaderBytes - 8)) != checksum)
    corrupt(what, "checksum mismatch");
  const std::size_t values = static_cast<std::size_t>(count) * static_cast<std::size_t>(n_);
  const unsigned char* p = payload;
  const double* bounds = nullptr;
  std::size_t fixed =
      static_cast<std::size_t>(exceptionCount) * 16 + (mode == 1 ? static_cast<std::size_t>(n_) * 8 : 0);
  if (exceptionCount < 0 || static_cast<std::size_t>(exceptionCount) > values ||
      fixed > static_cast<std::size_t>(payloadBytes))
    corrupt(what, "bad exception count");
  if (mode == 1) {
    bounds = reinterpret_cast<const double*>(p);  // read through memcpy below
    p += static_cast<std::size_t>(n_) * 8;
  }
  const unsigned char* exceptions = p;
  p += static_cast<std::size_t>(exceptionCount) * 16;
  const std::size_t zsize = static_cast<std::size_t>(payload + payloadBytes - p);
  const std::size_t got = ZSTD_decompress(shuffled_.data(), values * 8, p, zsize);
  if (ZSTD_isError(got) || got != values * 8) corrupt(what, "zstd frame does not decode to the block's size");
  const unsigned char* planes = shuffled_.data();
  for (std::size_t v = 0; v < values; ++v) {
    std::uint64_t r = 0;
    for (std::size_t b = 0; b < 8; ++b) r |= static_cast<std::uint64_t>(planes[b * values + v]) << (8 * b);
    residuals_[v] = r;
  }
  const std::int64_t n = n_;
  std::size_t nextException = 0;
  std::uint64_t exceptionIndex = values;  // none
  std::uint64_t exceptionBits = 0;
  auto loadException = [&] {
    if (nextException < static_cast<std::size_t>(exceptionCount)) {
      std::memcpy(&exceptionIndex, exceptions + nextException * 16, 8);
      std::memcpy(&exceptionBits, exceptions + nextException * 16 + 8, 8);
      ++nextException;
    } else {
      exceptionIndex = values;
    }
  };
  loadException();
  for (std::int64_t j = 0; j < n; ++j) {
    const std::uint64_t* r = residuals_.data() + j * count;
    double* y = reconstructed_.data();
    if (mode == 0) {
      for (std::int64_t i = 0; i < count; ++i) y[i] = fromBits(bitsOf(predict(y, i, order)) + unzigzag(r[i]));
    } else {
      double bound;
      std::memcpy(&bound, reinterpret_cast<const unsigned char*>(bounds) + j * 8, 8);
      const double step = 2.0 * bound;
      for (std::int64_t i = 0; i < count; ++i) {
        const std::uint64_t index = static_cast<std::uint64_t>(j * count + i);
        if (index == exceptionIndex) {
          y[i] = fromBits(exceptionBits);
          loadException();
        } else {
          const double q = static_cast<double>(static_cast<std::int64_t>(unzigzag(r[i])));
          y[i] = predict(y, i, order) + q * step;
        }
      }
    }
    for (std::int64_t i = 0; i < count; ++i) rows[i * n + j] = y[i];
  }
}

// ---- HDF5 filter ----
namespace {

// cd_values: n (values per row), order, zstd level. The chunk holds whole rows (HDF5 hands over
// edge chunks at full size).
size_t timeCodecFilter(unsigned flags, size_t cdCount, const unsigned cdValues[], size_t nbytes,
                       size_t* bufferSize, void** buffer) {
  if (cdCount < 3 || cdValues[0] == 0) return 0;
  const int n = static_cast<int>(cdValues[0]);
  const int order = static_cast<int>(cdValues[1]);
  const int level = static_cast<int>(cdValues[2]);
  try {
    if (flags & H5Z_FLAG_REVERSE) {
      const auto* in = static_cast<const unsigned char*>(*buffer);
      const std::int64_t count = TimeCodec::blockStates(in, nbytes);
      if (count <= 0) return 0;
      // One codec per thread, grown to the largest chunk seen: the filter has no other state.
      thread_local std::unique_ptr<TimeCodec> codec;
      thread_local std::pair<int, std::int64_t> shape{0, 0};
      if (!codec || shape.first != n || shape.second < count) {
        codec = std::make_unique<TimeCodec>(n, count, level);
        shape = {n, count};
      }
      const size_t outBytes = static_cast<size_t>(count) * static_cast<size_t>(n) * 8;
      void* out = H5allocate_memory(outBytes, false);
      if (out == nullptr) return 0;
      try {
        codec->decode(in, nbytes, count, static_cast<double*>(out));
      } catch (...) {
        H5free_memory(out);
        return 0;
      }
      H5free_memory(*buffer);
      *buffer = out;
      *bufferSize = outBytes;
      return outBytes;
    }
    if (nbytes % (static_cast<size_t>(n) * 8) != 0) return 0;
    const std::int64_t count = static_cast<std::int64_t>(nbytes / (static_cast<size_t>(n) * 8));
    thread_local std::unique_ptr<TimeCodec> codec;
    thread_local std::pair<int, std::int64_t> shape{0, 0};
    if (!codec || shape.first != n || shape.second < count) {
      codec = std::make_unique<TimeCodec>(n, count, level);
      shape = {n, count};
    }
    const size_t bound = codec->maxEncodedBytes();
    void* out = H5allocate_memory(bound, false);
    if (out == nullptr) return 0;
    size_t size = 0;
    try {
      size =
          codec->encode(static_cast<const double*>(*buffer), count, order, static_cast<unsigned char*>(out));
    } catch (...) {
      H5free_memory(out);
      return 0;
    }
    H5free_memory(*buffer);
    *buffer = out;
    *bufferSize = bound;
    return size;
  } catch (...) {
    return 0;
  }
}

const H5Z_class2_t kTimeCodecClass = {
    H5Z_CLASS_T_VERS, kTimeCodecFilterId, 1, 1, "hindsight time codec", nullptr, nullptr, &timeCodecFilter};

}  // namespace

bool ensureTimeCodecFilter() {
  static std::once_flag once;
  static bool available = false;
  std::call_once(once, [] {
    available = H5Zregister(&kTimeCodecClass) >= 0;
    H5Eclear2(H5E_DEFAULT);
  });
  return available;
}

}  // namespace hindsight::internal
