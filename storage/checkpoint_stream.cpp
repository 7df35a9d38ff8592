#include <hindsight/storage/checkpoint_stream.h>

#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/cams_checkpointing.h>
#include <hindsight/engine/online_checkpointing.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/storage/mixed_plan.h>
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_factory.h>

#include <algorithm>
#include <cassert>
#include <deque>
#include <stdexcept>
#include <vector>

namespace hindsight {

bool CheckpointStream::next(CheckpointAction* action) {
  if (exhausted_) return false;
  if (!doNext(action)) {
    exhausted_ = true;
    return false;
  }
  const auto key = [](CheckpointStorage s, std::int64_t n) { return std::make_pair(static_cast<int>(s), n); };
  switch (action->kind) {
    case CheckpointAction::Kind::kForward:
      if (action->storage != CheckpointStorage::kWork && action->storage != CheckpointStorage::kNone) {
        if (action->writeIcs)
          ++restart_;
        else
          adjointOnly_.insert(key(action->storage, action->n0));
      }
      forwardStart_ = action->n0;
      n_ = action->n1;
      break;
    case CheckpointAction::Kind::kReverse:
      r_ += action->n1 - action->n0;
      break;
    case CheckpointAction::Kind::kCopy:
    case CheckpointAction::Kind::kMove: {
      const bool restart = adjointOnly_.count(key(action->from, action->n0)) == 0;
      if (action->kind == CheckpointAction::Kind::kMove) {
        if (restart)
          --restart_;
        else
          adjointOnly_.erase(key(action->from, action->n0));
      }
      if (action->to == CheckpointStorage::kNone) {
        // A release (RestartData::kState streams only): the forward stays where it is.
      } else if (action->to == CheckpointStorage::kWork) {
        // Adjoint data alone puts the forward nowhere; checkpoint_schedules' own schedules then report
        // the step after it, which is where the forward would stand.
        n_ = restart ? action->n0 : action->n0 + 1;
      } else if (restart) {
        ++restart_;
      } else {
        adjointOnly_.insert(key(action->to, action->n0));
      }
      break;
    }
    case CheckpointAction::Kind::kEndForward:
      break;
    case CheckpointAction::Kind::kEndReverse:
      exhausted_ = true;
      break;
  }
  return true;
}

bool BatchedCheckpointStream::doNext(CheckpointAction* action) {
  while (queue_.empty()) {
    if (!refill()) return false;
  }
  *action = queue_.front();
  queue_.pop_front();
  return true;
}

void CheckpointStream::finalize(std::int64_t n) {
  const std::string call = "finalize(" + std::to_string(n) + "): ";
  if (n < 1) throw std::logic_error(call + "n must be >= 1");
  if (openedWithoutN_ && maxN_ >= 0)
    throw std::logic_error(call + "finalize was called already (N = " + std::to_string(maxN_) + ")");
  if (maxN_ >= 0) {
    if (n != maxN_ || n_ != n) {
      throw std::logic_error(call + "the forward is at step " + std::to_string(n_) +
                             " and the stream is for N = " + std::to_string(maxN_));
    }
    return;
  }
  // The host stops inside the last Forward (checkpoint_schedules' finalize with max_n None): n0 < n <= n1.
  if (n > n_ || n <= forwardStart_) {
    throw std::logic_error(call + "the forward is at step " + std::to_string(n_) +
                           (n <= forwardStart_ && n < n_
                                ? ", and n is behind the start " + std::to_string(forwardStart_) +
                                      " of its last Forward (n must be in (" + std::to_string(forwardStart_) +
                                      ", " + std::to_string(n_) + "])"
                                : std::string()));
  }
  n_ = n;
  maxN_ = n;
}

// storage/checkpoint_actions.cpp: cams' stream of a run of `steps` steps in the online mode, its forward run
// holding `positions` (the online placement's at the end).
std::unique_ptr<CheckpointStream> openCamsOnlineStreamAt(std::int64_t steps,
                                                         std::vector<std::int64_t> positions,
                                                         std::int64_t memoryUnits, std::int64_t recordUnits);

namespace {

using Kind = CheckpointAction::Kind;

constexpr auto forward = &CheckpointAction::forward;
constexpr auto reverseStep = &CheckpointAction::reverseStep;
constexpr auto toWork = &CheckpointAction::toWork;
constexpr auto marker = &CheckpointAction::marker;

// full and disk keep every state x_0..x_{N-2} (x_{N-1} is the working state when the forward run ends): the
// forward run writes each as restart data of its own step, and the adjoint of step e re-runs it from x_e
// (the stage values hindsight's own adjoint step recomputes). No step is recomputed otherwise. With N
// unknown (kUnknownSteps), the forward run writes x_{N-1} too, one step at a time until finalize(); its
// reverse then starts, like every other, from that checkpoint.
class EveryStateStream final : public BatchedCheckpointStream {
 public:
  EveryStateStream(std::int64_t steps, CheckpointStorage level)
      : BatchedCheckpointStream(steps), level_(level), unknown_(steps < 0) {}

 private:
  bool refill() override {
    const std::int64_t steps = maxN_;
    // With N unknown the forward run goes on until finalize(); then every state x_0..x_{N-1} is a
    // checkpoint, and the reverse starts from x_{N-1}'s.
    const std::int64_t lastWritten = unknown_ ? (steps < 0 ? forward_ + 1 : steps) : steps - 1;
    if (forward_ < lastWritten) {
      queue_.push_back(forward(forward_, forward_ + 1, true, false, level_));
      ++forward_;
    } else if (unknown_ && forward_ == steps) {
      queue_.push_back(marker(Kind::kEndForward));
      ++forward_;
      reverse_ = steps - 1;
    } else if (!unknown_ && forward_ == steps - 1) {
      queue_.push_back(forward(steps - 1, steps, false, true, CheckpointStorage::kWork));
      queue_.push_back(marker(Kind::kEndForward));
      queue_.push_back(reverseStep(steps - 1));
      ++forward_;
      reverse_ = steps - 2;
    } else if (reverse_ >= 0) {
      queue_.push_back(toWork(reverse_, level_, true));
      queueAdjointStep(reverse_);
      --reverse_;
    } else if (!done_) {
      queue_.push_back(marker(Kind::kEndReverse));
      done_ = true;
    } else {
      return false;
    }
    return true;
  }
  CheckpointStorage level_;
  bool unknown_;
  std::int64_t forward_ = 0, reverse_ = -1;
  bool done_ = false;
};

// binomial: the BinomialSchedule a run of computeGradient executes (engine/binomial_checkpointing.cpp:
// revolve over the positions 0..N-1 with BinomialCheckpointing::slotsFor(N, C, true) slots, its first sweep
// the forward sweep, x_{N-1} the working state), translated as it goes.
// A checkpoint's restart data is written by the Forward that leaves it, which runs to the next checkpoint
// of the same sweep (or to x_{N-1} or the step re-run for the adjoint): every later load of it then finds
// the adjoint at or below that end, as the contract asks. The load of a checkpoint at the position being
// reversed is its last (the schedule pops it): a Move; every other load a Copy. x_{N-1} is WORK: the
// forward run's last step writes its adjoint data there, as in checkpoint_schedules.
class BinomialStream final : public BatchedCheckpointStream {
 public:
  BinomialStream(std::int64_t steps, std::int64_t checkpoints) : BatchedCheckpointStream(steps) {
    schedule_.reset(BinomialCheckpointing::planLength(steps, true),
                    BinomialCheckpointing::slotsFor(steps, checkpoints, true), true);
    stack_.push_back(0);
  }

 private:
  struct Visitor {
    BinomialStream& s;
    void loadWorking() {}  // x_{N-1}, reversed right after the forward run
    void load(std::int64_t slot) {
      const std::int64_t position = s.stack_[static_cast<std::size_t>(slot)];
      const bool last = position == s.restoring_;
      s.queue_.push_back(toWork(position, CheckpointStorage::kRam, last));
      if (last) s.stack_.pop_back();
      s.at_ = position;
      s.pendingStore_ = false;
    }
    void advance(std::int64_t from, std::int64_t to) {
      assert(from == s.at_);
      s.queue_.push_back(forward(from, to, s.pendingStore_, false,
                                 s.pendingStore_ ? CheckpointStorage::kRam : CheckpointStorage::kWork));
      s.pendingStore_ = false;
      s.at_ = to;
    }
    void store(std::int64_t slot) {
      static_cast<void>(slot);  // the schedule's stack depth, which stack_ mirrors
      assert(static_cast<std::size_t>(slot) == s.stack_.size());
      s.stack_.push_back(s.at_);
      s.pendingStore_ = true;
    }
  };

  bool refill() override {
    const std::int64_t steps = maxN_;
    if (phase_ == Phase::kForward) {
      // The forward run, cut where the first sweep keeps a state: each piece writes the restart data of
      // the checkpoint it leaves (x_0 first). The schedule keeps none at x_{N-1}, the working state.
      const std::int64_t target = schedule_.nextForward();
      if (target > 0) {
        queue_.push_back(forward(at_, target, true, false, CheckpointStorage::kRam));
        schedule_.recordForward(target);
        stack_.push_back(target);
        at_ = target;
        return true;
      }
      // The last step writes the adjoint data of x_{N-1} to WORK, and the schedule's first restore (its
      // working state; for N = 1 the load and pop of x_0's slot) is the forward run itself.
      if (at_ < steps - 1) queue_.push_back(forward(at_, steps - 1, true, false, CheckpointStorage::kRam));
      queue_.push_back(forward(steps - 1, steps, false, true, CheckpointStorage::kWork));
      queue_.push_back(marker(Kind::kEndForward));
      queue_.push_back(reverseStep(steps - 1));
      NullVisitor none;
      schedule_.restoreStep(steps - 1, none);
      if (steps == 1) stack_.pop_back();
      restoring_ = steps - 2;
      at_ = -1;
      phase_ = Phase::kReverse;
      return true;
    }
    if (restoring_ >= 0) {
      Visitor visitor{*this};
      schedule_.restoreStep(restoring_, visitor);
      assert(at_ == restoring_);
      queueAdjointStep(restoring_);
      at_ = -1;
      --restoring_;
      return true;
    }
    return queueEndReverse(phase_);
  }

  struct NullVisitor {
    void loadWorking() {}
    void load(std::int64_t) {}
    void advance(std::int64_t, std::int64_t) {}
    void store(std::int64_t) {}
  };

  enum class Phase { kForward, kReverse, kDone };
  Phase phase_ = Phase::kForward;
  BinomialSchedule schedule_;
  std::vector<std::int64_t> stack_;  // positions of the slots, as the schedule's stack
  std::int64_t at_ = 0, restoring_ = -1;
  bool pendingStore_ = false;
};

// online: the checkpoints are states (RestartData::kState), placed by online's
// internal::TwoHorizonPlacement. With N known the stream is an engine run of N steps (the constructor's
// comment); without it, when the host finalizes at n its WORK holds x_n, which the adjoint does not
// need (the adjoint of step n - 1 starts from x_{n-1}), as the working state x_{N-1} of an engine run of
// N = n + 1 steps: so the stream is that run's game (engine/online_checkpointing.h) -- c + 1 RAM slots,
// the records x_1..x_n offered in order, each interval reversed by revolve with c + 1 - i slots
// (internal::OnlineReversal) -- and recomputes exactly what online's prediction for n + 1 steps counts.
// A record's decision depends on its step alone, not on N, and a record that is not stored leaves the
// placement as it was: so each Forward runs from the last stored state to the next record k the placement
// stores, found by offering the records ahead. The placement takes k at once; the stream's own list of
// the positions (positions_) follows it, O(1) per store into a free slot and O(m - j) per replacement of
// p_j, as the placement's tables do, and is put back (p_j reinserted, k removed) if the host finalizes
// before k. When the host goes on past k, the dropped checkpoint is released by Move(p_j, RAM, NONE)
// before the Forward that writes x_k (at most c + 1 held). Memory O(c).
class OnlineStateStream final : public BatchedCheckpointStream {
 public:
  // maxForward: a Forward advances at most this many steps; the next one then starts from a state that
  // is not stored (writeIcs false). The probe of a record is O(1), so this bounds the wait for an action
  // (openCheckpointStream: 2^20; with one checkpoint the gaps between stores grow like sqrt(N): 3 997
  // steps at N = 2 * 10^6).
  // steps: N, or kUnknownSteps until the host calls finalize(). With N known the forward run is an engine
  // run's: the records 1 .. N - 1 are offered, the last Forward writes step N - 1's adjoint data (x_{N-1}
  // is the working state, never written) and the count is online's prediction for N itself.
  // intervals (N known only): the placement of the whole run is walked first (O(N)) and the forward run
  // writes only the positions it holds at the end, each by the Forward that runs to the next one, so
  // every checkpoint's restart data covers its interval: checkpoint_schedules' contract
  // (RestartData::kInterval), the same reversal and count.
  OnlineStateStream(std::int64_t steps, std::int64_t checkpoints, std::int64_t maxForward, bool intervals)
      : BatchedCheckpointStream(steps), c_(checkpoints), maxForward_(maxForward), intervals_(intervals) {
    if (intervals_ && steps < 1)
      throw std::invalid_argument("online's stream within checkpoint_schedules' contract needs N");
    placement_.reset(c_);
    positions_.reserve(static_cast<std::size_t>(std::min<std::int64_t>(c_ + 2, 1 << 16)));
    positions_.assign(1, 0);  // into the reserved buffer: the state stream's stores allocate nothing
    if (intervals_) positions_ = Placement::simulate(steps, c_, nullptr, nullptr);
    stack_.reserve(static_cast<std::size_t>(std::min<std::int64_t>(c_ + 1, 1 << 16)));
  }
  RestartData restartData() const override {
    return intervals_ ? RestartData::kInterval : RestartData::kState;
  }

 private:
  using Placement = internal::TwoHorizonPlacement;

  struct Visitor {
    OnlineStateStream& s;
    std::int64_t start, e;  // the interval's first step; the step restored
    void loadWorking() { throw std::logic_error("online stream: revolve used a working state"); }
    void load(std::int64_t slot) {
      const std::int64_t position = s.stack_[static_cast<std::size_t>(slot)];
      const bool last = position == e;  // the schedule pops it
      s.queue_.push_back(toWork(position, CheckpointStorage::kRam, last));
      if (last) s.stack_.pop_back();
      s.at_ = position;
      s.pendingStore_ = false;
    }
    void advance(std::int64_t from, std::int64_t to) {
      if (start + from != s.at_) throw std::logic_error("online stream: revolve advances from elsewhere");
      s.queue_.push_back(forward(s.at_, start + to, s.pendingStore_, false,
                                 s.pendingStore_ ? CheckpointStorage::kRam : CheckpointStorage::kWork));
      s.pendingStore_ = false;
      s.at_ = start + to;
    }
    void store(std::int64_t slot) {
      if (static_cast<std::size_t>(slot) != s.stack_.size())
        throw std::logic_error("online stream: revolve's slots are not a stack");
      s.stack_.push_back(s.at_);
      s.pendingStore_ = true;
    }
  };

  bool refill() override {
    const bool known = !openedWithoutN();
    if (phase_ == Phase::kForward && intervals_ && at_ < maxN_ - 1) {
      // From a held position (x_0, then each Forward's end) to the next one, whose state the next Forward
      // writes, or to x_{N-1}, which held or not is the working state and not written.
      const auto next = std::upper_bound(positions_.begin(), positions_.end(), at_);
      const std::int64_t k = next == positions_.end() ? maxN_ - 1 : std::min(*next, maxN_ - 1);
      queue_.push_back(forward(at_, k, true, false, CheckpointStorage::kRam));
      at_ = k;
      return true;
    }
    if (phase_ == Phase::kForward && (maxN_ < 0 || (known && at_ < maxN_ - 1))) {
      if (accepted_) {  // the host went on past the stored record: x_{at_} is written next
        releaseDropped();
        accepted_ = false;
        storeAt_ = true;
      }
      std::int64_t k = at_ + 1;
      for (;; ++k) {
        dropped_ = placement_.offer(k);
        if (dropped_ != Placement::kSkipped || k - at_ >= maxForward_ || (known && k == maxN_ - 1)) break;
      }
      accepted_ = dropped_ != Placement::kSkipped;
      if (dropped_ >= 0) {
        droppedPosition_ = positions_[static_cast<std::size_t>(dropped_)];
        positions_.erase(positions_.begin() + dropped_);
      }
      if (accepted_) positions_.push_back(k);
      queue_.push_back(
          forward(at_, k, storeAt_, false, storeAt_ ? CheckpointStorage::kRam : CheckpointStorage::kWork));
      storeAt_ = false;
      at_ = k;
      return true;
    }
    if (phase_ == Phase::kForward && known) {
      // at_ = N - 1, the placement's decision on x_{N-1} taken (as the engine's working state it is held
      // where a run holds it, and not written): step N - 1 runs with its adjoint data and is reversed at
      // once, the rest by the intervals of a run of N steps.
      const std::int64_t n = maxN_;
      if (accepted_) releaseDropped();
      queue_.push_back(forward(at_, n, false, true, CheckpointStorage::kWork));
      queue_.push_back(marker(Kind::kEndForward));
      queue_.push_back(reverseStep(n - 1));
      at_ = -1;
      beginReverse(n, n - 2);
      return true;
    }
    if (phase_ == Phase::kForward) {
      // finalize(n), n0 < n <= at_: the records up to n - 1 were not stored (at_ is the first the
      // placement stores); x_n is offered too, as an engine run of n + 1 steps offers its working state,
      // so when at_ = n its decision stands (x_n itself is not needed and not written) and p_j is
      // released; before it, the placement is put back. (placement_ is not used after this.)
      const std::int64_t n = maxN_;
      if (accepted_ && n == at_) {
        releaseDropped();
      } else if (accepted_ && n < at_) {
        positions_.pop_back();
        if (dropped_ >= 0) positions_.insert(positions_.begin() + dropped_, droppedPosition_);
      }
      queue_.push_back(marker(Kind::kEndForward));
      beginReverse(n + 1, n - 1);
      return true;
    }
    if (restoring_ >= 0) {
      const internal::OnlinePlacement::Interval& interval = reversal_.enter(restoring_);
      if (interval.start != intervalStart_) {
        intervalStart_ = interval.start;
        stack_.assign(1, interval.start);  // revolve's slot 0: the interval's checkpoint
      }
      Visitor visitor{*this, interval.start, restoring_};
      reversal_.restoreStep(restoring_, visitor);
      if (at_ != restoring_ || pendingStore_)
        throw std::logic_error("online stream: revolve missed its step");
      queueAdjointStep(restoring_);
      at_ = -1;
      --restoring_;
      return true;
    }
    return queueEndReverse(phase_);
  }

  // The checkpoint the placement dropped for the record at at_, once that record is kept.
  void releaseDropped() {
    if (dropped_ >= 0) queue_.push_back(CheckpointAction::release(droppedPosition_, CheckpointStorage::kRam));
  }
  // The forward run is over: the placement is final, and the backward sweep reverses the intervals of an
  // engine run of `runSteps` steps from step `first` down.
  void beginReverse(std::int64_t runSteps, std::int64_t first) {
    accepted_ = false;
    reversal_.reserve(c_ + 1);
    reversal_.reset(&positions_, runSteps, c_);
    restoring_ = first;
    phase_ = Phase::kReverse;
  }

  enum class Phase { kForward, kReverse, kDone };
  Phase phase_ = Phase::kForward;
  std::int64_t c_, maxForward_;
  bool intervals_;
  Placement placement_;
  std::int64_t dropped_ = Placement::kSkipped;  // the placement's decision at at_ (an index before it)
  std::int64_t droppedPosition_ = -1;           // the checkpoint it dropped there
  bool accepted_ = false;                       // the placement stored the record at at_
  bool storeAt_ = true;  // the next Forward writes x_{at_} (x_0 is held from the start)
  std::int64_t at_ = 0;
  std::vector<std::int64_t> positions_;  // the placement's positions, as the host holds them
  internal::OnlineReversal reversal_;
  std::vector<std::int64_t> stack_;  // revolve's slots in the current interval: their positions
  std::int64_t intervalStart_ = -1, restoring_ = -1;
  bool pendingStore_ = false;
};

// cams without N (with online=1 or without it: a cams run whose step count is unknown uses the online mode
// too): the checkpoints are states (RestartData::kState) placed by cams' online placement
// (internal::OnlinePlacement, c = M - 1 of the M units) as the host goes. A run offers x_q, when q is a
// multiple of the spacing d, at its record of step q + 1; so each Forward runs from one candidate to the
// next (or as far as the cap), and the placement takes x_q when the host asks to go on from q -- it then
// reaches q + 1, since finalize(n) needs n0 < n. The checkpoints a thinning drops are released then,
// Move(p, RAM, NONE): at most c are held. When the host finalizes at n its WORK holds x_n, as the working
// state of a cams run of n + 1 steps holds x_n (offered x_0 .. x_{n-1}, as here by then); the backward
// sweep is that run's, each interval reversed by the interval plan as cams::simulateOnline does: the
// stream of N = n + 1 steps with the same positions (openCamsOnlineStreamAt) without its forward run and
// the reverse of step n (the working state's; the host does not need it). So it recomputes what cams'
// online prediction for n + 1 steps counts. Intervals longer than the interval plan reverses are
// revolve's in a run, which the translation does not express: the stream refuses to go on when the
// spacing passes that length, before any checkpoint is released. Memory O(M) until the host finalizes.
class CamsOnlineStateStream final : public BatchedCheckpointStream {
 public:
  // maxForward as OnlineStateStream's (the gaps between candidates double with every thinning).
  CamsOnlineStateStream(std::int64_t memoryUnits, std::int64_t recordUnits, std::int64_t maxForward)
      : BatchedCheckpointStream(kUnknownSteps),
        units_(memoryUnits),
        recordUnits_(recordUnits),
        maxForward_(maxForward),
        longestPlanned_(
            cams::onlineIntervalPlanSteps(cams::kMaxIntervalPlanSteps, memoryUnits, recordUnits)) {
    placement_.reset(units_ - 1);
    held_.reserve(static_cast<std::size_t>(std::min<std::int64_t>(units_, 1 << 16)));
  }
  RestartData restartData() const override { return RestartData::kState; }

 private:
  bool refill() override {
    if (!reverse_ && maxN_ < 0) {
      forwardOn();
      return true;
    }
    CheckpointAction a;
    if (!reverse_) {
      // finalize(n): the backward sweep of a run of n + 1 steps, after its EndForward (passed on) and
      // the reverse of step n (skipped with the actions before it).
      reverse_ = openCamsOnlineStreamAt(maxN_ + 1, placement_.positions(), units_, recordUnits_);
      while (reverse_->next(&a) && a.kind != Kind::kEndForward) {
      }
      queue_.push_back(a);
      while (reverse_->next(&a) && !(a.kind == Kind::kReverse && a.n0 == maxN_)) {
      }
      return true;
    }
    if (!reverse_->next(&a)) return false;
    queue_.push_back(a);
    return true;
  }

  // The host goes on from at_: the placement's decision on x_{at_}, then the Forward to the next
  // candidate.
  void forwardOn() {
    bool store = false;
    if (placement_.isCandidate(at_)) {
      const std::int64_t spacing = placement_.spacing();
      const std::int64_t slot = placement_.commit(at_, [](std::int64_t, std::int64_t) {});
      const std::vector<std::int64_t>& kept = placement_.positions();
      if (placement_.spacing() != spacing) {
        if (placement_.spacing() > longestPlanned_) {
          throw std::invalid_argument(
              "cams without N: at step " + std::to_string(at_) + " its online placement spaces the " +
              "checkpoints " + std::to_string(placement_.spacing()) + " steps apart, beyond the " +
              std::to_string(longestPlanned_) +
              " steps its interval plan reverses (a run reverses longer intervals by revolve, which the "
              "action stream does not translate); give N, or raise cams.checkpoints/cams.budget");
        }
        std::size_t k = 0;
        for (const std::int64_t p : held_) {
          if (k < kept.size() && kept[k] == p)
            ++k;
          else
            queue_.push_back(CheckpointAction::release(p, CheckpointStorage::kRam));
        }
        held_.assign(kept.begin(), kept.end());
      } else if (slot >= 0) {
        held_.push_back(at_);
      }
      store = slot >= 0;
    }
    const std::int64_t spacing = placement_.spacing();
    const std::int64_t next = std::min((at_ / spacing + 1) * spacing, at_ + maxForward_);
    queue_.push_back(CheckpointAction::forward(at_, next, store, false,
                                               store ? CheckpointStorage::kRam : CheckpointStorage::kWork));
    at_ = next;
  }

  std::int64_t units_, recordUnits_, maxForward_, longestPlanned_;
  internal::OnlinePlacement placement_;
  std::vector<std::int64_t> held_;  // the positions the host holds (the placement's before a thinning)
  std::int64_t at_ = 0;
  std::unique_ptr<CheckpointStream> reverse_;  // after finalize: the stream of n + 1 steps
};

// mixed: the whole translated plan, handed out in order.
class StoredStream final : public CheckpointStream {
 public:
  StoredStream(std::int64_t steps, std::vector<CheckpointAction> actions)
      : CheckpointStream(steps), actions_(std::move(actions)) {}

 private:
  bool doNext(CheckpointAction* action) override {
    if (next_ == actions_.size()) return false;
    *action = actions_[next_++];
    return true;
  }
  std::vector<CheckpointAction> actions_;
  std::size_t next_ = 0;
};

}  // namespace

std::unique_ptr<CheckpointStream> openOnlineStateStream(std::int64_t steps, std::int64_t checkpoints,
                                                        std::int64_t maxForward, bool intervals) {
  return std::make_unique<OnlineStateStream>(steps, checkpoints, maxForward, intervals);
}

std::unique_ptr<CheckpointStream> openCamsOnlineStateStream(std::int64_t memoryUnits,
                                                            std::int64_t recordUnits,
                                                            std::int64_t maxForward) {
  return std::make_unique<CamsOnlineStateStream>(memoryUnits, recordUnits, maxForward);
}

std::unique_ptr<CheckpointStream> openTwoLevelPlanStream(std::int64_t steps, TwoLevelPlan plan);
std::unique_ptr<CheckpointStream> openCamsPlanStream(std::int64_t steps, std::unique_ptr<cams::Plan> plan);
std::unique_ptr<CheckpointStream> openCamsOnlineStream(std::int64_t steps, std::int64_t memoryUnits,
                                                       std::int64_t recordUnits);

std::unique_ptr<CheckpointStream> openCheckpointStream(const std::string& specText, std::int64_t steps,
                                                       std::int64_t stateBytes, int stages,
                                                       const ScheduleCosts* costs, RestartData hostRestarts) {
  const StorageSpec spec = StorageSpec::parse(specText);
  const std::string& name = spec.name();
  if (name == "online") {
    // Every check of the spec and the sizes (the prediction at two steps, or at N), then c as a run
    // derives it.
    predictSchedule(specText, steps == kUnknownSteps ? 2 : steps, stateBytes, stages, costs);
    const std::unique_ptr<TrajectoryStorage> storage = createFromRows(storageStrategies(), specText);
    const auto& online = dynamic_cast<const OnlineCheckpointing&>(*storage);
    if (online.keepsStages() && stages > 1) {
      throw std::invalid_argument(
          "online.stages = 1 keeps stage values by a rule of its own, which the action stream does not "
          "express; use online without stages=1");
    }
    return openOnlineStateStream(steps, online.checkpointsFor(stateBytes, 0), std::int64_t{1} << 20,
                                 hostRestarts == RestartData::kInterval && steps != kUnknownSteps);
  }
  if (steps == kUnknownSteps && name == "cams") {
    // Every check of the spec and the sizes (at one step), then the units as a run in the online mode
    // derives them: a run with an unknown step count is in the online mode whether online=1 is given or
    // not, and so is its stream.
    predictSchedule(specText, 1, stateBytes, stages, costs);
    const std::unique_ptr<TrajectoryStorage> storage = createFromRows(storageStrategies(), specText);
    const auto& strategy = dynamic_cast<const CamsCheckpointing&>(*storage);
    return openCamsOnlineStateStream(strategy.usableUnits(stateBytes, true),
                                     CamsCheckpointing::recordUnitsOfStages(stages), std::int64_t{1} << 20);
  }
  if (steps == kUnknownSteps && name != "full" && name != "disk") {
    // Why the others need N (docs/guides/checkpoint_schedule.md, "An unknown N"): their plans are made
    // for N.
    throw std::invalid_argument(
        "steps unknown: only full, disk, online and cams streams are made without N "
        "(full and disk discard no checkpoint; online and cams keep states, "
        "restart_data = state); " +
        name + " needs N: its plan is made for N");
  }
  if (name == "binomial" || name == "full" || name == "disk") {
    if (spec.has("stages") && spec.integer("stages", 0, 0, 1) == 1 && stages > 1) {
      throw std::invalid_argument(name +
                                  ".stages = 1 keeps stage values by a rule of its own, which the action "
                                  "stream does not express; use " +
                                  name + " without stages=1, or cams (whose step records it expresses)");
    }
    if (name != "binomial") {
      // Every check of the plan, O(1) here (with N unknown: the spec and the sizes).
      predictSchedule(specText, steps == kUnknownSteps ? 1 : steps, stateBytes, stages, costs);
    } else {
      // Every check of the plan: the spec first (a missing checkpoints= is named), then the budget at
      // the slotsFor(N, C, true) slots the stream uses (the same at min(N, C + 2) steps). The prediction at
      // N itself walks the plan up to 2^24 steps (100 ms at N = 10^6), which a stream that walks it as the
      // host goes does not need.
      predictSchedule(specText, 1, stateBytes, stages, costs);
      const std::int64_t checkpoints =
          spec.integer("checkpoints", 1, 1, BinomialCheckpointing::kMaxCheckpoints);
      predictSchedule(specText, std::min(steps, checkpoints + 2), stateBytes, stages, costs);
      return std::make_unique<BinomialStream>(steps, checkpoints);
    }
    return std::make_unique<EveryStateStream>(
        steps, name == "disk" ? CheckpointStorage::kDisk : CheckpointStorage::kRam);
  }
  if (name == "multilevel") {
    // Every check of the plan: the spec and the sizes (at one step: the prediction at N would choose the
    // plan a second time), the levels and the plan at N (fixedStepPlan).
    if (steps < 1 || steps > kMaxScheduleSteps) predictSchedule(specText, steps, stateBytes, stages, costs);
    predictSchedule(specText, 1, stateBytes, stages, costs);
    const std::unique_ptr<TrajectoryStorage> storage = createFromRows(storageStrategies(), specText);
    if (dynamic_cast<const MultilevelStorage&>(*storage).options().stride) {
      throw std::invalid_argument(
          "multilevel.schedule = stride has no action stream: its scratch rounds are not a plan of slots "
          "(drop schedule=stride: the default plan has one)");
    }
    return openTwoLevelPlanStream(
        steps,
        MultilevelStorage::fixedStepPlan(*storage, PredictionRequest{steps, stateBytes, stages, costs, 0}));
  }
  if (name == "cams") {
    // Every check of the plan: the spec and the sizes (at one step: the prediction at N would build the
    // plan a second time), the units of the budget, then the plan at N (refused beyond
    // cams::Plan::kMaxTableEntries table entries), built once before the first action; online=1 places
    // its checkpoints first (O(N)) and plans its intervals when the forward run ends.
    if (steps < 1 || steps > kMaxScheduleSteps) predictSchedule(specText, steps, stateBytes, stages, costs);
    predictSchedule(specText, 1, stateBytes, stages, costs);
    const std::unique_ptr<TrajectoryStorage> storage = createFromRows(storageStrategies(), specText);
    const auto& strategy = dynamic_cast<const CamsCheckpointing&>(*storage);
    const bool online = strategy.onlineRequested();
    const std::int64_t units = strategy.usableUnits(stateBytes, online);
    const std::int64_t recordUnits = CamsCheckpointing::recordUnitsOfStages(stages);
    if (online) return openCamsOnlineStream(steps, units, recordUnits);
    return openCamsPlanStream(steps, std::make_unique<cams::Plan>(steps, units, recordUnits));
  }
  if (name == "mixed") {
    predictSchedule(specText, 1, stateBytes, stages, costs);  // the spec's keys and sizes checked
    const std::int64_t units = spec.integer("checkpoints", 0, 1, MixedPlanStorage::kMaxCheckpoints);
    return std::make_unique<StoredStream>(steps, mixed::actions(mixed::Plan(steps, units)));
  }
  // Every strategy with a fixed plan is streamed above; the others' rows say why they have none
  // (writeScheduleActions refuses them; the reason does not depend on N, so one step is asked).
  translateCheckpointPlan(specText, 1, stateBytes, stages, costs);
  throw std::logic_error("openCheckpointStream: " + name + " writes actions but has no stream here");
}

}  // namespace hindsight
