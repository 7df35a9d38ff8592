// Coding of blocks of consecutive states along time: the byte coding shared by "disk" and
// multilevel's disk level (through the HDF5 filter below, inside storage/chunked_state_file.h) and by
// "lossy:target=T" (in memory). Not a strategy itself.
//
// A block holds `count` consecutive states of `n` doubles. Each component is taken as a series in time
// and predicted from its previous values in the block by polynomial extrapolation of order k
// (k = 0: the previous value; k = 1: linear through the two previous; ...; the order ramps up over the
// first values of a block, which is decoded on its own: random access per block).
//   lossless:  the residual is the integer difference of the IEEE bit patterns of the value and its
//              prediction (mod 2^64, zigzag-mapped), so decoding restores every bit; near predictions
//              give residuals with many leading zero bits;
//   bounded:   per component j an absolute bound e_j; the residual against the prediction from the
//              already *reconstructed* values is quantized to a multiple of 2 e_j (Di & Cappello's SZ
//              scheme), so |restored - recorded| <= e_j; a value that does not fit (non-finite, or
//              rounding pushed it past the bound) is kept exactly as an exception.
// The residuals, component-major, are byte-shuffled (byte b of every residual together) and
// compressed with zstd. Why this and not ZFP or plain shuffle + zstd: measured on the rod's
// trajectories, see docs/theory/storage.md, "Compression along time".
//
// Block layout (little-endian): magic "HTC1", mode (0 lossless, 1 bounded), order, 2 spare bytes,
// count (int64), n (int32), exception count (int32), payload bytes (int64), FNV-1a of the payload
// (uint64) of the header's first 32 bytes and the payload; payload = [bounded: n bounds (double)]
// [exceptions: (index int64, bits uint64)...] then one zstd frame of the shuffled residuals. decode() checks
// magic, sizes and the checksum and throws StorageError on any mismatch: a corrupted block is an error, never
// wrong states.
//
// Thread-safety: a TimeCodec object holds work buffers; use one per thread. The work buffers are
// allocated once for the largest block (constructor), so coding allocates nothing.
#pragma once

#include <hindsight/engine/trajectory_storage.h>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace hindsight::internal {

class TimeCodec {
 public:
  static constexpr int kMaxOrder = 8;
  /// Default orders, chosen by measurement on the rod (docs/theory/storage.md, "Compression along time").
  static constexpr int kLosslessOrder = 6;
  static constexpr int kBoundedOrder = 1;
  static constexpr std::size_t kHeaderBytes = 40;

  /// Work buffers for blocks of up to maxStates states of n doubles.
  TimeCodec(int n, std::int64_t maxStates, int zstdLevel = 3);

  /// Worst-case size of a coded block of maxStates states (lossless or bounded).
  std::size_t maxEncodedBytes() const { return maxEncoded_; }

  /// Lossless: rows holds `count` states (state-major, count * n doubles). Writes at most
  /// maxEncodedBytes() into out; returns the bytes written.
  std::size_t encode(const double* rows, std::int64_t count, int order, unsigned char* out);
  /// Bounded: |restored_ij - rows_ij| <= bounds[j] (bounds[j] >= 0). Returns the bytes written;
  /// *maxRelativeError (optional) gets max_ij |restored - recorded| / scale[j] over components with
  /// scale[j] > 0 (scale may be null: then it is not computed).
  std::size_t encodeBounded(const double* rows, std::int64_t count, int order, const double* bounds,
                            unsigned char* out, const double* scale = nullptr,
                            double* maxRelativeError = nullptr);
  /// Restores the `count` states (state-major) of a block coded by encode/encodeBounded. Throws
  /// StorageError (mentioning `what`) when the block is corrupted or does not have count x n values.
  void decode(const unsigned char* in, std::size_t size, std::int64_t count, double* rows,
              const char* what = "trajectory block");

  /// States held by a coded block (from its header; 0 when the header is not valid).
  static std::int64_t blockStates(const unsigned char* in, std::size_t size);

 private:
  std::size_t finish(int mode, int order, std::int64_t count, const double* bounds, unsigned char* out);

  int n_;
  std::int64_t maxStates_;
  int level_;
  std::size_t maxEncoded_;
  std::vector<std::uint64_t> residuals_;   // component-major
  std::vector<unsigned char> shuffled_;    // byte planes
  std::vector<double> reconstructed_;      // bounded mode: one component's series
  std::vector<std::uint64_t> exceptions_;  // (index, bits) pairs
};

/// The HDF5 filter id under which the time codec runs in chunked_state_file (lossless mode). 256..511
/// are the ids HDF5 leaves for unregistered filters; files written with it need hindsight to read.
inline constexpr int kTimeCodecFilterId = 306;
/// Registers the time-codec HDF5 filter (cd_values: n, order, zstd level) once; false on failure.
bool ensureTimeCodecFilter();

}  // namespace hindsight::internal
