// Internal machinery shared by the "disk" and "multilevel" strategies: an HDF5 file holding rows of
// states, written and read in chunks by one background thread. Not a strategy itself.
//
// File format (self-describing, readable with the plain HDF5 API or h5py + hdf5plugin):
//   /states   float64 [rows x stateSize], chunked by `chunkStates` rows, filters in this order:
//             codec time (default): hindsight's time codec (filter id 306, cd_values = stateSize,
//               order, level; storage/time_codec.h: prediction along time, lossless), Fletcher32;
//             codec zstd: byte shuffle (HDF5), zstd (filter id 32015, cd_values[0] = level), Fletcher32;
//   /times    float64 [rows], the time of each row, chunked and filtered the same way;
//   root attributes: format ("hindsight trajectory 1"), problem, stateSize, t0, t1,
//             hindsightVersion, chunkStates, codec ("time" or "zstd"), and stepCount (written when
//             the forward sweep ends). Filter 306 is not registered with the HDF Group: a file coded
//             with it is read by hindsight (or any program that registers the filter of
//             storage/time_codec.h).
// zstd is registered with HDF5 under its registered id 32015 (HDF Group filter registry,
// https://github.com/HDFGroup/hdf5_plugins/blob/master/docs/RegisteredFilterPlugins.md) by our own
// small callback over libzstd when no plugin provides it, so the file is the same one the official
// plugin (and hdf5plugin.Zstd in Python) reads and writes. Fletcher32 makes a corrupted chunk an
// error at read time instead of silently wrong states.
//
// Threading: every HDF5 call happens on the background thread (serialized across files by a mutex
// when HDF5 was built without thread safety); the owner's thread only copies
// states into and out of a fixed pool of chunk buffers (allocated once in the constructor, sized
// bufferBytes() each) and waits when all buffers are busy. The owner uses one object from one
// thread. A failure on the background thread (unwritable file, full disk, corrupted chunk) is kept
// and thrown as StorageError naming the file by the owner's next call; the thread is joined by
// close() and by the destructor, which also removes the file unless keepFile is set.
//
// Protocol: append() rows 0, 1, 2, ...; finishWriting(); [the file is closed here and may be
// inspected]; startReading(firstRow); read() rows in non-increasing order (repeats allowed); close().
#pragma once

#include <hindsight/engine/trajectory_storage.h>

#include <cstdint>
#include <memory>
#include <string>

namespace hindsight::internal {

struct StateFileOptions {
  std::string directory;
  std::string filePrefix = "hindsight";
  int compressionLevel = 3;  ///< zstd level, 1..22
  /// Coding of the rows: kTime (default) predicts each row from the previous rows of its chunk and
  /// codes the residual (storage/time_codec.h, HDF5 filter 306); kZstd is byte shuffle + zstd alone.
  enum class Codec { kTime, kZstd };
  Codec codec = Codec::kTime;
  int timeOrder = 6;             ///< extrapolation order of kTime, 0..8
  std::int64_t chunkStates = 1;  ///< rows per HDF5 chunk and per buffer
  int bufferCount = 3;           ///< >= 1; 1 disables overlap of I/O and computation
  bool keepFile = false;
  /// Test hook: the write of chunk number K (0-based) and all later ones fail as a full disk would.
  std::int64_t failWriteAfterChunks = -1;
};

class ChunkedStateFile {
 public:
  /// Bytes of one chunk buffer: chunkStates rows of the state plus their times.
  static std::int64_t bufferBytes(int stateSize, std::int64_t chunkStates) {
    return chunkStates * (static_cast<std::int64_t>(stateSize) + 1) * 8;
  }

  /// Creates a new uniquely named file in options.directory (creating the directory if needed) and
  /// starts the background thread. Throws StorageError naming the directory or file on failure.
  ChunkedStateFile(const StateFileOptions& options, const TrajectoryInfo& info);
  ~ChunkedStateFile();
  ChunkedStateFile(const ChunkedStateFile&) = delete;
  ChunkedStateFile& operator=(const ChunkedStateFile&) = delete;

  const std::string& path() const;
  /// Appends one row; blocks only when every buffer is waiting to be written.
  void append(double t, const double* z);
  /// Writes what is buffered and the stepCount attribute, then closes the file; waits for it.
  void finishWriting(std::int64_t stepCount);
  /// Reopens the file read-only, checks its shape and starts reading the chunk of `firstRow`.
  void startReading(std::int64_t firstRow);
  /// Copies row `row` into z; rows must come in non-increasing order. Prefetches the chunk before.
  void read(std::int64_t row, double* z);
  /// Stops the thread, closes the file and removes it unless keepFile. Idempotent, never throws.
  void close() noexcept;

  std::int64_t rows() const;
  /// Size of the file after finishWriting().
  std::int64_t fileBytes() const;
  /// Bytes the /states dataset occupies in the file after finishWriting() (compressed).
  std::int64_t storedStateBytes() const;
  /// Seconds the background thread spent in HDF5 calls (including compression) so far.
  double ioSeconds() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// True when an HDF5 filter with id 32015 (zstd) is available, registering ours if needed.
bool ensureZstdFilter();

}  // namespace hindsight::internal
