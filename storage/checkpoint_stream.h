// A strategy's checkpoint_schedules action stream (storage/checkpoint_actions.h), produced one action at a
// time as the host asks for it, with the schedule state checkpoint_schedules' CheckpointSchedule exposes
// (n, r, max_n, is_exhausted, finalize). docs/guides/checkpoint_schedule.md states the contract every
// stream keeps; python/tests/stream_contract.py checks it.
//
// binomial, full, disk, multilevel and cams are generated lazily: memory O(checkpoints) besides the plan
// (binomial drives engine/binomial_checkpointing.h's BinomialSchedule, multilevel its TwoLevelPlan
// (MultilevelStorage::fixedStepPlan), cams its plan's cams::Executor, the state machines their runs use, so
// the stream recomputes exactly what a run recomputes); the first action comes after the plan is made
// (binomial: O(checkpoints); multilevel: TwoLevelPlan::choose, 0.03 s at N = 10^6; cams: its dynamic
// programme over N, tables of N (M + 1) entries, seconds at N = 10^4: bench/checkpoint_stream_bench.py).
// mixed translates its whole plan when the stream is opened and then hands it out action by action.
// online, with N or without (openCheckpointStream with kUnknownSteps), and cams without N keep states as
// checkpoints (RestartData::kState, docs/guides/checkpoint_schedule.md, "An unknown N"): memory
// O(checkpoints) (cams: until finalize, then its interval plan).
#pragma once

#include <hindsight/storage/checkpoint_actions.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <set>
#include <string>
#include <utility>

namespace hindsight {

class CheckpointStream {
 public:
  virtual ~CheckpointStream() = default;

  /// The next action in `*action`; false once EndReverse has been handed out (and ever after).
  bool next(CheckpointAction* action);

  /// The step the forward is at (checkpoint_schedules' `n`): after a Forward its n1, after a Copy/Move
  /// of restart data to WORK that step.
  std::int64_t n() const { return n_; }
  /// Adjoint steps taken (`r`).
  std::int64_t r() const { return r_; }
  /// N, or -1 while it is unknown (a stream opened without N, before finalize()).
  std::int64_t maxN() const { return maxN_; }
  /// The forward run ends at step n (checkpoint_schedules' finalize): for a stream opened without N, n
  /// becomes N, once, with n inside the last Forward handed out (n0 < n <= n1; the host stops there);
  /// for one with N, n must be N and the forward there. Throws std::logic_error otherwise (a second call
  /// on a stream opened without N, n behind the last Forward's start or ahead of its end;
  /// checkpoint_schedules raises "Invalid checkpointing state").
  void finalize(std::int64_t n);
  /// EndReverse has been handed out.
  bool isExhausted() const { return exhausted_; }
  /// Restart checkpoints (RAM and DISK) the host holds now.
  std::int64_t heldCheckpoints() const { return restart_; }
  /// What the stream's checkpoints are (RestartData): kState for online (its placement drops checkpoints
  /// during the forward run, with N known or not).
  virtual RestartData restartData() const { return RestartData::kInterval; }

 protected:
  explicit CheckpointStream(std::int64_t maxN) : maxN_(maxN), openedWithoutN_(maxN < 0) {}
  /// The next action of the strategy; false after EndReverse.
  virtual bool doNext(CheckpointAction* action) = 0;
  /// Opened with steps = kUnknownSteps (N comes from finalize()).
  bool openedWithoutN() const { return openedWithoutN_; }
  std::int64_t maxN_;

 private:
  std::int64_t n_ = 0, r_ = 0;
  std::int64_t forwardStart_ = -1;  // n0 of the last Forward handed out
  bool openedWithoutN_;
  bool exhausted_ = false;
  // Checkpoints holding restart data, counted; those holding adjoint data only (cams' records without
  // restart data), by (storage, step): a Copy/Move of any other to WORK moves n. O(1) memory for full and
  // disk, which hold N - 1 checkpoints.
  std::int64_t restart_ = 0;
  std::set<std::pair<int, std::int64_t>> adjointOnly_;
};

/// The driver of every lazily generated stream (binomial, full, disk, multilevel, cams): the strategy's
/// state machine appends the actions of its next step to queue_ (refill()), which doNext hands out in
/// order, refilling it whenever it is empty; memory is one step's actions besides the strategy's state.
class BatchedCheckpointStream : public CheckpointStream {
 protected:
  explicit BatchedCheckpointStream(std::int64_t maxN) : CheckpointStream(maxN) {}
  /// Appends the actions of the strategy's next step to queue_ (none, when the step writes nothing);
  /// false when there is no step left.
  virtual bool refill() = 0;
  bool doNext(CheckpointAction* action) final;
  /// Queues the adjoint of `step` once WORK holds x_step: the Forward that writes its adjoint data, then
  /// its Reverse (every stream's backward sweep ends each step so).
  void queueAdjointStep(std::int64_t step) {
    queue_.push_back(CheckpointAction::forward(step, step + 1, false, true, CheckpointStorage::kWork));
    queue_.push_back(CheckpointAction::reverseStep(step));
  }
  /// The last refill of a backward sweep driven step by step: queues EndReverse once while `phase` is
  /// kReverse (then kDone); false ever after.
  template <class Phase>
  bool queueEndReverse(Phase& phase) {
    if (phase != Phase::kReverse) return false;
    queue_.push_back(CheckpointAction::marker(CheckpointAction::Kind::kEndReverse));
    phase = Phase::kDone;
    return true;
  }
  std::deque<CheckpointAction> queue_;
};

/// The stream of `spec` for N = `steps` fixed steps, with the arguments and checks of predictSchedule
/// (storage/schedule.h): full, disk, binomial, multilevel and cams (any N their plans support), mixed,
/// and online (state checkpoints, RestartData::kState: the placement and count of a run of N steps).
/// steps = kUnknownSteps: N is unknown until the host calls finalize(): full and disk, which keep every
/// state and so discard nothing (the forward run writes each step's restart data, as checkpoint_schedules'
/// SingleMemoryStorageSchedule/SingleDiskStorageSchedule do for an unknown N), and online, whose
/// checkpoints are states (RestartData::kState): at most c + 1 in RAM, placed as a run of N + 1 steps
/// places them (internal::TwoHorizonPlacement: the host's WORK holds x_N when it finalizes, as the
/// engine's working state holds x_{N-1}), so it recomputes what online's prediction for N + 1 steps
/// counts; and cams (online=1 or not: its online mode), whose states are placed by its online placement
/// with M - 1 checkpoints and whose backward sweep is a cams run's of N + 1 steps, so it recomputes what
/// cams' online prediction for N + 1 steps counts. Throws std::invalid_argument as checkpointSchedule()
/// does, and for an unknown N with other strategies.
/// hostRestarts = RestartData::kInterval: the host's restart data serves only the steps of the Forward that
/// wrote it (checkpoint_schedules' contract): online with N known then walks its placement first (O(N):
/// 0.45-1.1 s at N = 10^6, C = 100) and writes only the checkpoints it holds at the end, a stream within that
/// contract with the same count; streams without N keep states whatever is asked (their restartData() says
/// so, for the caller to refuse).
constexpr std::int64_t kUnknownSteps = -1;
std::unique_ptr<CheckpointStream> openCheckpointStream(const std::string& spec, std::int64_t steps,
                                                       std::int64_t stateBytes, int stages,
                                                       const ScheduleCosts* costs,
                                                       RestartData hostRestarts = RestartData::kState);

/// cams' stream for an unknown N (openCheckpointStream's for cams with kUnknownSteps, which caps a Forward
/// at 2^20 steps): M = memoryUnits units, records of recordUnits units, each Forward capped at
/// `maxForward` >= 1 steps.
std::unique_ptr<CheckpointStream> openCamsOnlineStateStream(std::int64_t memoryUnits,
                                                            std::int64_t recordUnits,
                                                            std::int64_t maxForward);

/// online's stream for N = `steps` (or kUnknownSteps) and c checkpoints (openCheckpointStream's, which
/// caps a Forward at 2^20 steps), with each Forward capped at `maxForward` >= 1 steps: tests reach the
/// cap with it. intervals (N known): the stream within checkpoint_schedules' contract (openCheckpointStream
/// with hostRestarts = RestartData::kInterval), whose Forwards run between the positions held at the end.
std::unique_ptr<CheckpointStream> openOnlineStateStream(std::int64_t steps, std::int64_t checkpoints,
                                                        std::int64_t maxForward, bool intervals = false);

}  // namespace hindsight
