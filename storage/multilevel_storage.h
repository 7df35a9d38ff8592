// Strategy "multilevel": states in RAM up to a RAM budget and on disk up to a disk budget, exact
// (gradients bitwise identical to "full", recomputation included; docs/design.md §6).
//
// Spec: multilevel:ram=BYTES,disk=BYTES[,costs=uf:ub:wd:rd][,schedule=optimal|stride][,dir=PATH]
//                  [,level=1..22][,keep=true|false][,overlap=0|1][,sync=0|1]
//   or, for K levels (RAM and K - 1 slower ones, each its own size, directory and costs):
//       multilevel:ram=BYTES,levels=LEVEL;LEVEL;...[,costs=uf:ub][,schedule=...][,dir=PATH][,keep=...]
//       LEVEL = NAME:BYTES[:PATH][@WRITE:READ]   e.g. levels=ssd:80@1:1;hdd:1600:/mnt/hdd@2:2
//   levels    the levels below RAM, fastest first: a name (letters, digits, '_' or '-'; not "ram"), the
//             bytes of states it holds, its directory (default: the subfolder NAME of dir=, made and
//             removed when empty by the run) and its write and read costs of one state in seconds.
//             Costs are given completely (every level's @WRITE:READ and costs=uf:ub) or not at all (each
//             level's write and read measured at the start of the run in its directory, the forward step
//             as for two levels). One level is the two-level form (disk= with that level's directory and
//             costs uf:ub:WRITE:READ: the same plans and bits); two or more are planned by
//             KLevelPlan::choose (storage/k_level_plan.h) for fixed steps up to kMaxLevelSteps, and
//             adaptive steps and schedule=stride use RAM and the first level only.
//   ram       bytes held in memory (the strategy's budget)
//   disk      bytes of states on disk (raw states for schedule=optimal; rows with their times,
//             counted uncompressed, for schedule=stride)
//   costs     the cost model of storage/schedule.h in seconds: forward step, adjoint step, disk write
//             and disk read of one state. Default: measured at the start of each run -- a disk write
//             and read of one state at begin(), and the forward step as the median time between the
//             first (up to) 16 records, whose states wait in RAM until the plan is chosen.
//   schedule  optimal (default): for fixed steps, the two-level plan of storage/schedule.h that is
//             cheapest under the cost model (the two-level optimum over stack schedules by dynamic
//             programming, which reuses disk slots, where its work limit allows; else Disk-Revolve's
//             leaves, or revolve over all slots with the long-lived checkpoints on disk); adaptive
//             steps (N unknown) fall back to the stride. A RAM of one or two states plans too: the
//             forward step is then timed from the first two records (one interval).
//             stride: the uniform stride of hindsight <= 0.13 (below), kept for comparison; its
//             prediction warns (SchedulePrediction::warning) when it costs more than kTrapFactor times
//             the plan schedule=optimal runs with the same levels and costs.
//   dir       directory of the file (default: the system temp directory); level, keep as for "disk"
//             (level only matters for schedule=stride, whose file is compressed).
//   overlap   1 (default): schedule=optimal's disk level writes behind and reads ahead on a second
//             thread (storage/overlapped_io.h: two write buffers and one read-ahead buffer of a state
//             each, beside ram= as the slot file's own record buffer is); 0: every write and read waits
//             for the disk. The same bits either way; the predicted seconds subtract what the overlap
//             hides (internal::hiddenDiskSeconds), and the measured ones count the waits only.
//   sync      1: schedule=optimal's slot file is opened O_DSYNC, so each write has reached the device when
//             it returns (a disk without a write cache; bench/disk_bench.cpp's disk-bound case); default 0.
// schedule=optimal keeps its disk level in a file of fixed-size slots of raw states
// ("hindsight-multilevel-*.slots", written and read with pwrite/pread: the plan rewrites and rereads
// slots in any order, which the append-only compressed file cannot), RAM slots allocated once at
// begin(). Changing the default from stride to optimal changes no gradient bit (both are exact), only
// recomputed steps, disk traffic and time. The run's predicted schedule seconds (R uf + W wd + Q rd)
// and the measured ones (time in recomputation and disk I/O) are reported by predictedSeconds() and
// measuredSeconds(); plan() describes the plan.
//
// schedule=stride: the file has the format of storage/chunked_state_file.h: its rows are the kept
// states that went to disk, /times gives their times. It is only created when RAM cannot hold the
// kept states.
// Placement: kept states fill RAM first, then the disk. Which states are kept:
//   N known (fixed steps): the smallest stride k such that ceil(N / k) kept states plus k - 1
//   scratch states fit into RAM and disk together (k = 1: everything kept, no recomputation);
//   N unknown (adaptive steps): k starts at 1 and doubles whenever both levels are full; states in
//   RAM that are no longer multiples of k are dropped to make room (states on disk stay).
// Backward sweep: the state of step s comes from the nearest kept state c <= s; the states between
// are recomputed once into scratch slots of RAM when they fit (then each segment costs s - c
// recomputed steps), otherwise in rounds that keep as many as fit (never wrong, only slower).
// In the spirit of Stumm & Walther 2009, "MultiStage approaches for optimal offline checkpointing"
// (SIAM J. Sci. Comput. 31(3)).
//
// Integrity: the slots of schedule=optimal carry their index and an FNV-1a checksum, the stride's file
// Fletcher32 per chunk; a state that does not read back as written is a StorageError naming the file
// (and the slot), never a restored state. Scratch files of killed runs are removed as
// storage/scratch_files.h says.
// Faults as for "disk" (StorageError naming the file); thread-safety: one object, one thread, one
// background I/O thread per run while the disk level of schedule=stride is used.
#pragma once

#include <hindsight/engine/storage_registry.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>
#include <hindsight/storage/schedule.h>

#include <functional>
#include <iosfwd>
#include <optional>
#include <utility>

#include <memory>
#include <string>
#include <vector>

namespace hindsight {

namespace internal {
class ChunkedStateFile;
class OverlappedSlotIo;
class DiskEventLookahead;
}  // namespace internal

class MultilevelStorage final : public TrajectoryStorage {
 public:
  /// A prediction whose cost exceeds a simple alternative's by more than this factor says so
  /// (SchedulePrediction::warning; docs/theory/storage.md, "No silent trap").
  static constexpr double kTrapFactor = 2.0;
  struct Options {
    std::int64_t ramBytes = 0;
    std::int64_t diskBytes = 0;
    std::string directory;  ///< empty: the system temp directory
    int compressionLevel = 3;
    bool keepFile = false;
    /// Test hook passed to the disk level (see DiskStorage::Options).
    std::int64_t failWriteAfterChunks = -1;
    /// Test hook: called with the disk level's file after the forward sweep (schedule=stride: the
    /// complete, closed file before it is reopened; optimal: the slot file), e.g. to corrupt it.
    std::function<void(const std::string& path)> afterForwardSweep;
    /// The uniform stride instead of the cost-optimal plan (spec schedule=stride).
    bool stride = false;
    /// The cost model; measured at the start of each run when empty. With levels: uf and ub, and the first
    /// level's write and read (the stride's disk).
    std::optional<ScheduleCosts> costs;
    /// schedule=optimal: write behind and read ahead on a second thread (spec overlap=1, the default).
    bool overlap = true;
    /// schedule=optimal: slot writes reach the device before they return (O_DSYNC; spec sync=1).
    bool syncWrites = false;
    /// levels= (storage/multilevel_storage.h's spec); empty for ram=,disk=. diskBytes and directory are the
    /// first level's.
    struct Level {
      std::string name;
      std::int64_t bytes = 0;
      std::string path;  ///< given directory, or empty: the subfolder `name` of directory
      bool costed = false;
      double write = 0.0, read = 0.0;
    };
    std::vector<Level> levels;
    bool IsValid(std::string* error) const;
  };

  /// Throws std::invalid_argument when !options.IsValid().
  explicit MultilevelStorage(Options options);
  ~MultilevelStorage() override;
  static std::unique_ptr<TrajectoryStorage> create(const StorageSpec& spec);
  /// The levels= form of create().
  static std::unique_ptr<TrajectoryStorage> createLevels(const StorageSpec& spec);
  /// The registry's prediction (engine/storage_registry.h): the counts of N fixed steps.
  static void predict(const TrajectoryStorage& storage, const StorageSpec& spec,
                      const PredictionRequest& request, SchedulePrediction& p);
  /// The registry's action stream: the TwoLevelPlan a run executes, written action by action;
  /// schedule=stride is refused, its scratch rounds not being a plan of slots.
  static void writeActions(const TrajectoryStorage& storage, const StorageSpec& spec,
                           const PredictionRequest& request, std::ostream& out);
  /// The TwoLevelPlan of schedule=optimal for the request's N fixed steps, as predict counts it, a run
  /// executes it and writeActions and the checkpoint action stream (storage/checkpoint_stream.h) walk it.
  /// Throws std::invalid_argument naming the levels when they cannot hold the slots N steps need.
  static TwoLevelPlan fixedStepPlan(const TrajectoryStorage& storage, const PredictionRequest& request);

  /// Slots of each level schedule=optimal has for N steps of stateSize entries.
  struct Layout {
    std::int64_t ramSlots = 0;
    std::int64_t diskSlots = 0;
    std::vector<std::int64_t> levelSlots;  ///< levels=: each level's below RAM (diskSlots: the first's)
  };
  /// K-level plans (three or more levels) are planned and predicted up to this many steps (their plan is
  /// walked once to count it).
  static constexpr std::int64_t kMaxLevelSteps = std::int64_t{1} << 24;
  Layout layoutFor(std::int64_t steps, int stateSize) const;
  const Options& options() const { return options_; }
  /// schedule=optimal with fixed steps in the current or last run: its plan, the costs it was chosen
  /// by (given or measured), and the schedule's predicted and measured seconds (recomputation + disk).
  bool usesPlan() const { return usesPlan_; }
  const TwoLevelPlan& plan() const { return plan_; }
  /// Three or more levels: the K-level plan of the current or last run (else nullptr).
  const KLevelPlan* levelPlan() const { return levelPlan_ ? &*levelPlan_ : nullptr; }
  const ScheduleCosts& costs() const { return costsInUse_; }
  double predictedSeconds() const {
    if (!usesPlan_) return 0.0;
    return levelPlan_ ? levelPlan_->counts().cost : plan_.counts().cost(costsInUse_) - hiddenSeconds_;
  }
  /// Disk seconds the overlap hides by the cost model in the current or last run (0 without overlap).
  double hiddenSeconds() const { return hiddenSeconds_; }
  /// Disk reads of the last run served by a read-ahead (overlap=1; every disk read when it works).
  std::int64_t prefetchedReads() const { return prefetchedReads_; }
  /// States written to and read from each level below RAM in the last run (schedule=optimal).
  const std::vector<std::int64_t>& levelWrites() const { return levelWrites_; }
  const std::vector<std::int64_t>& levelReads() const { return levelReads_; }
  /// The directory of level k >= 1 below RAM (1: the disk of the two-level form).
  std::string levelDirectory(std::size_t k) const;
  double measuredSeconds() const { return recomputeSeconds_ + slotIoSeconds_; }
  /// States written to and read from the disk level in the last run (either schedule).
  std::int64_t diskWrites() const { return diskWrites_; }
  std::int64_t diskReads() const { return diskReads_; }

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

  void beginStride();
  void recordStride(std::int64_t step, double t, ConstVectorRef z);
  void finishStride();
  void restoreStride(std::int64_t step, VectorRef z);
  static void predictStride(const Options& options, const PredictionRequest& request, SchedulePrediction& p);
  /// The costs a run plans by, for a prediction: costs=, else --costs (standing for the measured ones),
  /// else 1:1:0:0 when there is nothing to choose; throws std::invalid_argument when --costs is needed.
  static ScheduleCosts planningCosts(const Options& options, const PredictionRequest& request,
                                     const Layout& layout);
  /// Sets p.warning when the stride's predicted schedule cost exceeds kTrapFactor times the optimal plan's.
  static void warnAgainstStride(const Layout& layout, const PredictionRequest& request,
                                SchedulePrediction& p);
  /// The K-level plan a run with levels= executes for a prediction's N and sizes, and the costs it is
  /// chosen by (throws std::invalid_argument naming the flags and fields); `levelsOut`, when given, receives
  /// the levels below RAM it is planned on.
  static KLevelPlan levelPlanFor(const MultilevelStorage& multilevel, const PredictionRequest& request,
                                 const Layout& layout, ScheduleCosts& costs,
                                 std::vector<StorageLevelCosts>* levelsOut = nullptr);
  static void predictLevels(const MultilevelStorage& multilevel, const PredictionRequest& request,
                            const Layout& layout, SchedulePrediction& p);
  void beginPlan();
  void choosePlan(const ScheduleCosts& costs);
  void recordPlanned(std::int64_t step, const double* z);
  void measureDiskCosts(ScheduleCosts& costs);
  /// With overlap=1, starts the plan's next disk read when it is the next disk event.
  void startNextRead();
  /// The median of five writes and reads of one state in `directory`.
  std::pair<double, double> measureLevelCosts(const std::string& directory);
  bool usesLevels() const { return options_.levels.size() >= 2; }
  void storeSlot(int level, std::int64_t slot, const double* z);
  void loadSlot(int level, std::int64_t slot, double* z);
  /// Removes the default level subfolders the run made, when empty.
  void removeLevelDirectories() const;
  struct PlanVisitor;

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
  // schedule=optimal.
  struct SlotFile;
  bool usesPlan_ = false;
  TwoLevelPlan plan_;
  ScheduleCosts costsInUse_;
  std::int64_t planRamSlots_ = 0, planDiskSlots_ = 0;
  std::unique_ptr<double[]> ramPool_;
  std::int64_t poolSlots_ = 0;
  std::vector<std::unique_ptr<SlotFile>> slotFiles_;  // [k - 1]: level k below RAM
  std::optional<KLevelPlan> levelPlan_;               // three or more levels
  std::vector<StorageLevelCosts> levelsInUse_;        // their slots and costs (given or measured)
  std::vector<std::int64_t> levelWrites_, levelReads_, levelRows_;
  std::int64_t probeSteps_ = 0;  // states buffered before the plan is chosen (costs measured)
  std::vector<double> probeTimes_;
  double recomputeSeconds_ = 0.0;
  double slotIoSeconds_ = 0.0;
  std::int64_t diskWrites_ = 0, diskReads_ = 0;
  // overlap=1: the I/O thread over slotFiles_[0] and the plan's disk events ahead of the run (reads start
  // only after the forward sweep, whose end waits for every write: the file is then complete).
  std::unique_ptr<internal::OverlappedSlotIo> io_;
  std::unique_ptr<internal::DiskEventLookahead> lookahead_;
  bool backwardSweep_ = false;
  double hiddenSeconds_ = 0.0;
  std::int64_t prefetchedReads_ = 0;
  // The stride's counting executor (predict): the same placement, slots and scratch rounds, with no
  // state copied, no RAM slot allocated (only charged) and no file written; recompute() reaches a
  // recomputer that only counts.
  bool counting_ = false;
};

}  // namespace hindsight
