// Strategy "multilevel": states in memory up to a RAM budget, then in an HDF5 file up to a disk
// budget, and when even both are too small for all N states, checkpoints every k-th state and
// recomputes the others through recompute(step, z) (docs/design.md §6). Lossless: gradients are
// bitwise identical to "full" storage, recomputation included.
//
// Spec: multilevel:ram=BYTES,disk=BYTES[,dir=PATH][,level=1..22][,keep=true|false]
//   ram    bytes held in memory (the strategy's budget): kept states, the two chunk buffers of the
//          disk tier (each at most ram/8) and the scratch states of the backward sweep
//   disk   bytes of states (and their times) written to the file, counted uncompressed, so the
//          file (compressed, plus a few KiB of HDF5 metadata) stays near or below it
//   dir    directory of the file (default: the system temp directory); level, keep as for "disk"
// The file has the format of storage/chunked_state_file.h: its rows are the kept states that went
// to disk, /times gives their times. It is only created when RAM cannot hold the kept states.
//
// Placement: kept states fill RAM first, then the disk. Which states are kept:
//   N known (fixed steps): the smallest stride k such that ceil(N / k) kept states plus k - 1
//   scratch states fit into RAM and disk together (k = 1: everything kept, no recomputation);
//   N unknown (adaptive steps): k starts at 1 and doubles whenever both levels are full; states in
//   RAM that are no longer multiples of k are dropped to make room (states on disk stay).
// Backward sweep: the state of step s comes from the nearest kept state c <= s; the states between
// are recomputed once into scratch slots of RAM when they fit (then each segment costs s - c
// recomputed steps), otherwise in rounds that keep as many as fit (never wrong, only slower).
// In the spirit of Stumm & Walther 2009, "MultiStage approaches for optimal offline checkpointing"
// (SIAM J. Sci. Comput. 31(3)); this is not their optimal schedule but a uniform stride over two
// levels, and Aupy & Herrmann's H-Revolve would reduce recomputation further.
//
// Faults as for "disk" (StorageError naming the file); thread-safety: one object, one thread, one
// background I/O thread per run while the disk level is used.
#pragma once

#include <hindsight/engine/trajectory_storage.h>
#include <hindsight/storage/storage_spec.h>

#include <memory>
#include <string>
#include <vector>

namespace hindsight {

namespace internal {
class ChunkedStateFile;
}

class MultilevelStorage final : public TrajectoryStorage {
 public:
  struct Options {
    std::int64_t ramBytes = 0;
    std::int64_t diskBytes = 0;
    std::string directory;  ///< empty: the system temp directory
    int compressionLevel = 3;
    bool keepFile = false;
    /// Test hook passed to the disk level (see DiskStorage::Options).
    std::int64_t failWriteAfterChunks = -1;
    bool IsValid(std::string* error) const;
  };

  /// Throws std::invalid_argument when !options.IsValid().
  explicit MultilevelStorage(Options options);
  ~MultilevelStorage() override;
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  static std::vector<std::string> keys() { return {"ram", "disk", "dir", "level", "keep"}; }

  std::string spec() const override;
  bool isExact() const override { return true; }

  /// Stride between kept states in the current or last run (1: all states kept).
  std::int64_t stride() const { return stride_; }
  /// Kept states in RAM and on disk at the end of the last forward sweep.
  std::int64_t statesInRam() const { return statesInRam_; }
  std::int64_t statesOnDisk() const { return diskRows_; }
  /// The disk level's file of the current or last run (empty when none was needed).
  const std::string& filePath() const { return filePath_; }

 private:
  void doBegin() override;
  void doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doFinish(double t, ConstVectorRef z, ConstVectorRef zdot) override;
  void doRestore(std::int64_t step, VectorRef z) override;

  std::int64_t availableSlots() const;
  /// A free RAM slot; allocates a block of up to `wanted` slots when none is free.
  std::int64_t acquireSlot(std::int64_t wanted);
  void releaseSlot(std::int64_t slot) { freeSlots_.push_back(slot); }
  void openFile();
  void closeFile();
  void loadKept(std::size_t index, VectorRef z);
  void releaseScratch();

  struct Kept {
    std::int64_t step;
    std::int64_t slot;  ///< RAM slot, or -1 when on disk
    std::int64_t row;   ///< disk row, or -1 when in RAM
  };

  Options options_;
  std::int64_t ramCapacity_ = 0;   // slots that fit beside the disk buffers
  std::int64_t ramKeptLimit_ = 0;  // slots kept states may use (the rest is scratch)
  std::int64_t diskCapacity_ = 0;  // rows
  std::int64_t diskBufferBytes_ = 0;
  std::int64_t chunkStates_ = 1;
  std::int64_t stride_ = 1;
  std::vector<std::unique_ptr<double[]>> slotBlocks_;
  std::vector<double*> slots_;
  std::vector<std::int64_t> freeSlots_;
  std::int64_t slotsInUseByKept_ = 0;
  std::vector<Kept> kept_;
  std::int64_t statesInRam_ = 0;
  std::int64_t diskRows_ = 0;
  std::unique_ptr<internal::ChunkedStateFile> file_;
  std::string filePath_;
  // Backward sweep.
  std::int64_t cursor_ = -1;
  std::int64_t scratchFirst_ = 0;  // scratch holds states scratchFirst_ .. scratchFirst_ + size - 1
  std::vector<std::int64_t> scratch_;
};

}  // namespace hindsight
