// Strategy "disk": every step's state in an HDF5 file, chunked, each chunk coded along time
// (storage/time_codec.h; or byte-shuffled and zstd-compressed with codec=zstd), written and read by a
// background thread (docs/design.md §6). Exact: restore() returns the recorded
// bits, so gradients are bitwise identical to "full" storage; nothing is recomputed.
//
// Spec: disk:dir=PATH[,level=1..22][,chunk=STATES][,budget=BYTES][,keep=true|false][,codec=time|zstd]
//   dir     directory for the file (created if missing); required
//   level   zstd level (default 3)
//   codec   time (default): each chunk's states predicted along time, residuals coded losslessly
//           (storage/time_codec.h, 2.4-3.3x on the rod); zstd: byte shuffle + zstd per chunk (the
//           older format, 1.3-1.4x). Both restore every bit.
//   chunk   states per HDF5 chunk and per I/O buffer (default: about 1 MiB of states, at most 4096,
//           at least 16 with codec=time)
//   budget  bytes held in memory (default 64 MiB): the pool of up to three chunk buffers (one being
//           filled or consumed, the others queued for writing or prefetched), charged with
//           holdBytes() at begin(); the default chunk shrinks to fit, an explicit one does not.
//           HDF5 runs with its chunk cache off; zstd's scratch buffers while a chunk is being
//           (de)compressed are transient and not charged.
//   keep    keep the file after the backward sweep (default false: it is removed after restore(0),
//           or when the storage is destroyed or begins a new run)
//   stages  1: every row holds the state and the step's stage values, so no adjoint step
//           evaluates the right-hand side; the file's rows are n + stepDataSize wide (the final row's
//           stage part is zero). Default 0.
// File format: see storage/chunked_state_file.h. The file holds rows 0..N (the final state too) and
// is named "<dir>/hindsight-<pid>-<counter>-<clock>.h5", unique per run; filePath() gives it.
//
// Faults are StorageError naming the file (never a crash, never a wrong gradient): a directory that
// cannot be created or written (at begin), a write error such as a full disk (on the background
// thread, thrown by the next record/finish/restore), a truncated file (at finish, when the file is
// reopened for reading) or a corrupted chunk (Fletcher32 checksum mismatch, thrown by restore).
//
// Thread-safety: one storage object is used from one thread; it owns one background I/O thread per
// run, joined at the end of the backward sweep, at the next begin() and in the destructor.
//
// References: HDF5 registered filter 32015 (zstd), https://github.com/HDFGroup/hdf5_plugins/blob/
// master/docs/RegisteredFilterPlugins.md; Collet & Kucherawy, RFC 8878 (Zstandard).
#pragma once

#include <hindsight/engine/storage_registry.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>

#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {

namespace internal {
class ChunkedStateFile;
}

class DiskStorage final : public TrajectoryStorage {
 public:
  static constexpr std::int64_t kDefaultBudget = std::int64_t{64} << 20;

  struct Options {
    std::string directory;
    int compressionLevel = 3;
    std::int64_t chunkStates = 0;  ///< 0: automatic
    std::int64_t budgetBytes = kDefaultBudget;
    bool keepFile = false;
    bool timeCodec = true;  ///< codec=time (true) or codec=zstd
    bool stages = false;
    /// Test hook: writes of chunk K and later fail as on a full disk (-1: off).
    std::int64_t failWriteAfterChunks = -1;
    /// Test hook: called with the file's path after the forward sweep, when the file is complete and
    /// closed and before it is reopened for the backward sweep (e.g. to truncate or corrupt it).
    std::function<void(const std::string& path)> afterForwardSweep;

    /// False with a message naming the field, its value and the allowed range.
    bool IsValid(std::string* error) const;
  };

  /// Throws std::invalid_argument when !options.IsValid().
  explicit DiskStorage(Options options);
  ~DiskStorage() override;

  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  /// The registry's prediction (engine/storage_registry.h): the counts of N fixed steps.
  static void predict(const TrajectoryStorage& storage, const StorageSpec& spec,
                      const PredictionRequest& request, SchedulePrediction& p);
  /// The registry's action stream: every state recorded into its own disk slot and loaded back.
  static void writeActions(const TrajectoryStorage& storage, const StorageSpec& spec,
                           const PredictionRequest& request, std::ostream& out);

  std::string spec() const override;
  bool isExact() const override { return true; }
  bool keepsStepData() const override { return options_.stages; }

  /// The file of the current or last run (empty before the first begin()).
  const std::string& filePath() const { return filePath_; }
  /// States per chunk of the current or last run.
  std::int64_t chunkStates() const { return chunkStates_; }

  /// The chunk and buffer sizes begin() uses for rows of `rowDoubles` doubles and `rows` rows (N + 1
  /// for N fixed steps); `hindsight schedule` predicts with the same rule (storage/schedule.h).
  struct Layout {
    std::int64_t chunkStates = 0;
    std::int64_t bufferBytes = 0;
    int bufferCount = 0;
  };
  Layout layoutFor(std::int64_t rowDoubles, std::int64_t rows) const;

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;
  void doRecordStepData(std::int64_t step, ConstVectorRef data) override;
  bool doRestoreStepData(std::int64_t step, VectorRef data) override;
  void closeFile();

  Options options_;
  std::unique_ptr<internal::ChunkedStateFile> file_;
  std::string filePath_;
  std::int64_t chunkStates_ = 0;
  std::int64_t heldBytes_ = 0;
  double rowTime_ = 0.0;
  std::vector<double> row_;  // stages=1: one row, state then stage values (allocated in begin)
};

}  // namespace hindsight
