// A strategy's plan as a typed action stream in the vocabulary of checkpoint_schedules (Maddison, Dolci &
// Ham's Python package, used by Firedrake and tlm_adjoint), so that any time-stepper -- not only
// hindsight's engine -- can reverse its run by it. docs/guides/checkpoint_schedule.md shows a host loop.
//
// Steps are indexed as there: step n advances the state at the start of step n (x_n) to x_{n+1}; N steps.
//   Forward(n0, n1, writeIcs, writeAdjDeps, storage)  advance x_{n0} -> x_{n1} in WORK; writeIcs: first
//       store x_{n0} (the restart data, "initial conditions") in `storage`; writeAdjDeps: store what the
//       adjoint of each step n0..n1-1 needs from the forward (the step's stage values, its "tape") in
//       `storage` (WORK: kept for the Reverse that follows).
//   Reverse(n1, n0, clearAdjDeps)  the adjoint over steps n1-1 down to n0, from their adjoint data;
//       clearAdjDeps: that data is released afterwards.
//   Copy(n, from, to) / Move(n, from, to)  x_n from one storage to another (to WORK: it becomes the state
//       advanced next); Move releases it in `from`.
//   EndForward  the forward run has reached x_N;   EndReverse  the adjoint has reached step 0.
//
// Every stream keeps checkpoint_schedules' contract (docs/guides/checkpoint_schedule.md, "The
// contract"): restart data is written by the Forward that leaves a state and covers the steps it runs;
// Copy/Move need an empty WORK and never copy from WORK; a Reverse reads its adjoint data from WORK only;
// Move is not a kind of Copy (online relaxes the first rule for state checkpoints and declares it:
// RestartData::kState). binomial, full, disk, multilevel and cams streams are generated as they are
// consumed (storage/checkpoint_stream.h); cams and multilevel translate the plan the strategy itself
// executes (the actions `hindsight schedule --actions` prints, from the same plan code as a run):
//   a checkpoint store is writeIcs on the Forward that leaves the state, or a Copy/Move between storages
//   when the state was just loaded; a load is Copy (Move at the checkpoint's last use); a recomputation
//   is a Forward without adjoint data; a cams step record is a one-step Forward writing its adjoint data
//   to RAM, moved to WORK for its Reverse; every other adjoint step first re-runs its step with
//   writeAdjDeps to WORK -- what hindsight's adjoint step does itself when it recomputes the step's
//   stages. When the plan holds x_{N-1}, the forward run's last step writes its adjoint data instead and
//   the first Reverse follows EndForward, as in checkpoint_schedules; when the plan replays x_{N-1} from
//   a checkpoint, the replay is in the stream. So the stream recomputes exactly the steps the strategy
//   recomputes. Checkpoint stores whose state is never loaded again are left out.
#pragma once

#include <hindsight/storage/schedule.h>

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace hindsight {

/// Where data lives (checkpoint_schedules' StorageType): RAM and DISK hold checkpoints; WORK is the
/// state being advanced (and the adjoint data of the step about to be reversed); NONE: released.
enum class CheckpointStorage { kRam, kDisk, kWork, kNone };
const char* checkpointStorageName(CheckpointStorage storage);  ///< "RAM", "DISK", "WORK", "NONE"

/// What a checkpoint's restart data is. kInterval: checkpoint_schedules' rule -- the restart data written
/// by Forward(n0, n1, writeIcs, ...) serves the steps n0..n1-1 only. kState: it is x_{n0} itself, which
/// a host whose step is a function of the state alone advances any distance, and Move(n, RAM|DISK, NONE)
/// releases a checkpoint (the relaxation docs/guides/checkpoint_schedule.md, "An unknown N", states;
/// checkpoint_schedules' own classes refuse such a stream).
enum class RestartData { kInterval, kState };

struct CheckpointAction {
  enum class Kind { kForward, kReverse, kCopy, kMove, kEndForward, kEndReverse };
  Kind kind = Kind::kEndForward;
  /// Forward: n0 -> n1; Reverse: n1 -> n0 (n1 > n0 always); Copy/Move: n0 is the step n, n1 = n0.
  std::int64_t n0 = 0, n1 = 0;
  bool writeIcs = false, writeAdjDeps = false;           ///< Forward
  bool clearAdjDeps = false;                             ///< Reverse
  CheckpointStorage storage = CheckpointStorage::kWork;  ///< Forward: where it writes
  CheckpointStorage from = CheckpointStorage::kNone, to = CheckpointStorage::kNone;  ///< Copy/Move
  /// checkpoint_schedules' repr, e.g. "Forward(0, 10, True, False, StorageType.RAM)".
  std::string text() const;

  /// The actions every stream builds: Forward(n0, n1, writeIcs, writeAdjDeps, storage); Reverse(e + 1, e,
  /// clearing the adjoint data); Copy or Move(n, from, WORK); a marker (EndForward, EndReverse).
  static CheckpointAction forward(std::int64_t n0, std::int64_t n1, bool writeIcs, bool writeAdjDeps,
                                  CheckpointStorage storage) {
    CheckpointAction a;
    a.kind = Kind::kForward;
    a.n0 = n0;
    a.n1 = n1;
    a.writeIcs = writeIcs;
    a.writeAdjDeps = writeAdjDeps;
    a.storage = storage;
    return a;
  }
  static CheckpointAction reverseStep(std::int64_t e) {
    CheckpointAction a;
    a.kind = Kind::kReverse;
    a.n0 = e;
    a.n1 = e + 1;
    a.clearAdjDeps = true;
    return a;
  }
  static CheckpointAction toWork(std::int64_t n, CheckpointStorage from, bool move) {
    CheckpointAction a;
    a.kind = move ? Kind::kMove : Kind::kCopy;
    a.n0 = a.n1 = n;
    a.from = from;
    a.to = CheckpointStorage::kWork;
    return a;
  }
  /// Move(n, from, NONE): the release of a state checkpoint (RestartData::kState streams only).
  static CheckpointAction release(std::int64_t n, CheckpointStorage from) {
    CheckpointAction a = toWork(n, from, true);
    a.to = CheckpointStorage::kNone;
    return a;
  }
  static CheckpointAction marker(Kind kind) {
    CheckpointAction a;
    a.kind = kind;
    return a;
  }
};

/// The action stream of `spec` for N = `steps` fixed steps, collected (openCheckpointStream() in
/// storage/checkpoint_stream.h hands it out one action at a time), with the arguments and checks of
/// predictSchedule (storage/schedule.h): full, disk, binomial, multilevel, cams (offline; N <= 2^24 for
/// cams) and mixed (storage/mixed_plan.h). Throws std::invalid_argument naming the field for bad input,
/// and for what has no fixed plan (online, cams online=1, lossy, hermite, packed, multilevel
/// schedule=stride) or keeps stage values by a rule of its own (stages=1; cams' step records are expressed).
std::vector<CheckpointAction> checkpointSchedule(const std::string& spec, std::int64_t steps,
                                                 std::int64_t stateBytes, int stages,
                                                 const ScheduleCosts* costs);

/// The whole plan of `spec` translated at once from the text writeScheduleActions prints (`hindsight
/// schedule --actions`), the counted way: a first pass counts every checkpoint's reads. The cams stream
/// is made as it is consumed instead (openCheckpointStream) and must equal this, action for action
/// (tests/storage/checkpoint_actions_test.cpp); for strategies without actions it throws their refusal.
std::vector<CheckpointAction> translateCheckpointPlan(const std::string& spec, std::int64_t steps,
                                                      std::int64_t stateBytes, int stages,
                                                      const ScheduleCosts* costs);

/// Counts of a stream, as a host executing it would see them (tests and docs).
struct CheckpointStreamCounts {
  std::int64_t forwardSteps = 0;     ///< steps advanced before EndForward (N)
  std::int64_t recomputedSteps = 0;  ///< steps advanced after it, except the one-step re-runs below
  std::int64_t adjointReruns =
      0;  ///< one-step Forwards writing adjoint data to WORK (incl. the forward's last)
  std::int64_t ramIcsWrites = 0, diskIcsWrites = 0;
  std::int64_t peakRamCheckpoints = 0, peakDiskCheckpoints = 0;  ///< restart states held at once
};

/// checkCheckpointStream() one action at a time, for a stream that is counted as it is made (no vector of
/// it): take() throws std::logic_error naming the action that breaks the contract, finish() when the stream
/// ends without EndReverse or leaves checkpoints behind, else returns the counts. restartData: the
/// stream's declaration (CheckpointStream::restartData()); kState replaces the rule that restart data
/// serves only the steps its Forward ran by "a state checkpoint restarts any distance" and accepts
/// Move(n, RAM|DISK, NONE) as its release; every other rule stays.
class CheckpointStreamChecker {
 public:
  explicit CheckpointStreamChecker(std::int64_t steps, RestartData restartData = RestartData::kInterval)
      : steps(steps), states(restartData == RestartData::kState) {}
  void take(const CheckpointAction& a);
  CheckpointStreamCounts finish();

 private:
  using Range = std::pair<std::int64_t, std::int64_t>;  // [first, end), empty when first == end
  struct Snapshot {
    Range ics{0, 0}, adjDeps{0, 0};
  };
  std::int64_t steps;
  bool states;
  CheckpointStreamCounts counts;
  std::int64_t at = 0, reversed = 0;  // at: the step of the WORK state, -1 none
  Range workIcs{0, 0}, workAdjDeps{0, 0};
  std::map<CheckpointStorage, std::map<std::int64_t, Snapshot>> held;
  bool forwardDone = false, reverseDone = false;
};

/// Executes `actions` on a host that tracks only which steps each piece of data belongs to, and throws
/// std::logic_error naming the action when the stream breaks the contract for N steps (the rules of
/// docs/guides/checkpoint_schedule.md, "The contract"; python/tests/stream_contract.py states the same
/// rules in Python), or leaves checkpoints behind at EndReverse.
CheckpointStreamCounts checkCheckpointStream(const std::vector<CheckpointAction>& actions, std::int64_t steps,
                                             RestartData restartData = RestartData::kInterval);

}  // namespace hindsight
