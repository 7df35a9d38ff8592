#include <hindsight/storage/checkpoint_actions.h>

#include <hindsight/engine/cams_checkpointing.h>
#include <hindsight/engine/storage_spec.h>
#include <hindsight/storage/checkpoint_stream.h>

#include <algorithm>
#include <deque>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace hindsight {

const char* checkpointStorageName(CheckpointStorage storage) {
  switch (storage) {
    case CheckpointStorage::kRam:
      return "RAM";
    case CheckpointStorage::kDisk:
      return "DISK";
    case CheckpointStorage::kWork:
      return "WORK";
    case CheckpointStorage::kNone:
      break;
  }
  return "NONE";
}

std::string CheckpointAction::text() const {
  const auto flag = [](bool b) { return b ? "True" : "False"; };
  const auto where = [](CheckpointStorage s) {
    return std::string("StorageType.") + checkpointStorageName(s);
  };
  std::ostringstream out;
  switch (kind) {
    case Kind::kForward:
      out << "Forward(" << n0 << ", " << n1 << ", " << flag(writeIcs) << ", " << flag(writeAdjDeps) << ", "
          << where(storage) << ")";
      break;
    case Kind::kReverse:
      out << "Reverse(" << n1 << ", " << n0 << ", " << flag(clearAdjDeps) << ")";
      break;
    case Kind::kCopy:
      out << "Copy(" << n0 << ", " << where(from) << ", " << where(to) << ")";
      break;
    case Kind::kMove:
      out << "Move(" << n0 << ", " << where(from) << ", " << where(to) << ")";
      break;
    case Kind::kEndForward:
      out << "EndForward()";
      break;
    case Kind::kEndReverse:
      out << "EndReverse()";
      break;
  }
  return out.str();
}

namespace {

// One line of the plan's own stream (writeScheduleActions), parsed.
struct PlanEvent {
  enum class Kind { kRecord, kStore, kStoreRecord, kLoad, kAdvance, kBeginRestore, kDeliver } kind;
  CheckpointStorage level = CheckpointStorage::kRam;
  std::string key;  // kStore/kLoad: the slot ("ram 3", "disk 0", "ram working"); cams: by position
  std::int64_t a = 0, b = 0;
  bool withStages = false;  // kDeliver: the adjoint step's stage values are held (a cams record)
};

std::vector<PlanEvent> parsePlan(const std::string& text) {
  // Two dialects: binomial, multilevel, full and disk print "restore e" before the actions that produce
  // x_e; cams prints its delivery "restore e with stages|recompute stages" after them. Both become a
  // kDeliver after the actions.
  std::vector<PlanEvent> events;
  std::istringstream in(text);
  std::string line;
  bool header = false;
  std::int64_t pending = -1;
  const auto closeHeader = [&] {
    if (pending >= 0)
      events.push_back(
          PlanEvent{PlanEvent::Kind::kDeliver, CheckpointStorage::kWork, "", pending, pending, false});
    pending = -1;
  };
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string verb, w1, w2, w3;
    words >> verb >> w1 >> w2 >> w3;
    if (verb == "record") {
      events.push_back(
          PlanEvent{PlanEvent::Kind::kRecord, CheckpointStorage::kWork, "", std::stoll(w1), 0, false});
    } else if (verb == "advance") {
      events.push_back(PlanEvent{PlanEvent::Kind::kAdvance, CheckpointStorage::kWork, "", std::stoll(w1),
                                 std::stoll(w2), false});
    } else if (verb == "restore") {
      if (w2.empty()) {
        header = true;
        closeHeader();
        pending = std::stoll(w1);
        events.push_back(
            PlanEvent{PlanEvent::Kind::kBeginRestore, CheckpointStorage::kWork, "", pending, pending, false});
      } else {
        events.push_back(PlanEvent{PlanEvent::Kind::kDeliver, CheckpointStorage::kWork, "", std::stoll(w1),
                                   std::stoll(w1), w2 == "with"});
      }
    } else if (verb == "store" || verb == "load") {
      const CheckpointStorage level = w1 == "disk" ? CheckpointStorage::kDisk : CheckpointStorage::kRam;
      if (w2 == "state" || w2 == "record") {
        // cams: checkpoints named by their position; a record holds the state too.
        events.push_back(PlanEvent{w2 == "record" ? PlanEvent::Kind::kStoreRecord : PlanEvent::Kind::kStore,
                                   level, "at " + w3, std::stoll(w3), 0, false});
      } else {
        events.push_back(PlanEvent{verb == "store" ? PlanEvent::Kind::kStore : PlanEvent::Kind::kLoad, level,
                                   w1 + " " + w2, -1, 0, false});
      }
    } else if (!line.empty()) {
      throw std::logic_error("checkpointSchedule: unexpected plan action '" + line + "'");
    }
  }
  if (header) closeHeader();
  return events;
}

// The translation of a plan's events, fed one at a time (feed(), then finish()); the actions are appended
// to the caller's queue. It must know, when a state is stored, whether it is loaded later (its restart data
// is written only then) and, at each load, whether it is the state's last (a Move then, else a Copy). Two
// ways:
//  * counted (cams): the translation runs twice over the whole plan; the first pass counts the loads of
//    every stored state (Usage), the second emits with that knowledge;
//  * stack (multilevel, made as consumed): the plan keeps its checkpoints as a stack, each until its own
//    state is restored (revolve, the leaves, the dynamic programme and the hierarchical plan all do,
//    storage/schedule.h): every stored state is loaded later except x_{N-1} kept by the forward sweep
//    (the forward run's last step writes its adjoint data instead), a load is the state's last when it
//    restores that state or when the state goes on to another storage at once (a move between levels).
//    A load of a state the stream has already released throws std::logic_error, so a plan that broke
//    the rule could not go unnoticed (the tests run every plan family through the contract checker).
class Translator {
 public:
  struct Usage {
    std::map<std::int64_t, std::int64_t> loads;  // version -> number of loads
    std::map<std::int64_t, std::int64_t> seen;   // version -> loads emitted so far (second pass)
  };

  /// usage: the counted way (emit: the second pass); null: the stack way. The actions go to `out`.
  Translator(std::int64_t steps, Usage* usage, bool emit, std::deque<CheckpointAction>& out)
      : steps_(steps), usage_(usage), emit_(emit), actions_(out) {}

  void feed(const PlanEvent& ev) {
    if (phase_ == Phase::kForward) {
      // Forward sweep: records and stores, up to the first restore, load or advance. The forward run goes
      // on uninterrupted; it is cut into Forwards only where it writes something. (cams names the position
      // of each store and prints no records.)
      if (ev.kind == PlanEvent::Kind::kRecord) {
        recorded_ = ev.a;
        return;
      }
      if (ev.kind == PlanEvent::Kind::kStore || ev.kind == PlanEvent::Kind::kStoreRecord) {
        forwardTo(ev.a >= 0 ? ev.a : recorded_);
        if (ev.kind == PlanEvent::Kind::kStore)
          store(ev);
        else
          storeRecord(ev);
        return;
      }
      phase_ = Phase::kFirstRestore;
    }
    if (phase_ == Phase::kFirstRestore) {
      // Up to the delivery of x_{N-1} (a few events). When the plan holds it (a working state, loaded
      // without recomputation), the forward run's last step writes its adjoint data (to RAM for a record,
      // else WORK) and that delivery is skipped; when the plan replays it from a checkpoint, the replay is
      // translated like every other restore.
      if (ev.kind != PlanEvent::Kind::kDeliver) {
        replays_ =
            replays_ || (ev.kind != PlanEvent::Kind::kLoad && ev.kind != PlanEvent::Kind::kBeginRestore);
        firstRestore_.push_back(ev);
        return;
      }
      if (ev.a != steps_ - 1) throw std::logic_error("checkpointSchedule: the first restore is not x_{N-1}");
      if (usage_ == nullptr && !replays_) {
        // The stack way: x_{N-1} kept by the forward sweep is never loaded (its delivery is skipped).
        if (!pendingIcs_.empty() && current_ != steps_ - 1)
          throw std::logic_error("checkpointSchedule: a stored state is left unadvanced");
        pendingIcs_.clear();
      }
      forwardTo(steps_, /*last=*/!replays_);
      out(Kind::kEndForward);
      expected_ = steps_ - 1;
      current_ = -1;
      phase_ = Phase::kBackward;
      if (!replays_) {
        if (heldAdjDeps_.count(steps_ - 1) != 0) fetchHeldAdjDeps(steps_ - 1);
        reverse(steps_ - 1);
        expected_ = steps_ - 2;
        firstRestore_.clear();
        return;
      }
      std::vector<PlanEvent> replay;
      replay.swap(firstRestore_);
      for (const PlanEvent& e : replay) backward(e);
    }
    backward(ev);
  }

  void finish() {
    if (phase_ != Phase::kBackward || expected_ != -1)
      throw std::logic_error("checkpointSchedule: the plan does not restore every state");
    out(Kind::kEndReverse);
  }

  /// The version the next new checkpoint gets (the counted way's Usage is keyed by it).
  std::int64_t nextVersion() const { return nextVersion_; }

 private:
  using Kind = CheckpointAction::Kind;
  enum class Phase { kForward, kFirstRestore, kBackward };

  void backward(const PlanEvent& ev) {
    switch (ev.kind) {
      case PlanEvent::Kind::kStore:
        store(ev);
        break;
      case PlanEvent::Kind::kStoreRecord:
        storeRecord(ev);
        break;
      case PlanEvent::Kind::kLoad:
        load(slotContent(ev.level, ev.key));
        break;
      case PlanEvent::Kind::kAdvance:
        need(ev.a);
        forwardTo(ev.b);
        break;
      case PlanEvent::Kind::kDeliver:
        if (ev.a != expected_) throw std::logic_error("checkpointSchedule: restores out of order");
        deliver(ev.a, ev.withStages);
        --expected_;
        break;
      case PlanEvent::Kind::kBeginRestore:
        break;
      case PlanEvent::Kind::kRecord:
        throw std::logic_error("checkpointSchedule: a forward record in the backward sweep");
    }
  }

  struct Content {
    std::int64_t version = -1, position = -1;
    CheckpointStorage level = CheckpointStorage::kRam;
    std::string key;  // its slot
  };

  void out(Kind kind, std::int64_t n0 = 0, std::int64_t n1 = 0) {
    CheckpointAction a;
    a.kind = kind;
    a.n0 = n0;
    a.n1 = n1;
    actions_.push_back(a);
  }

  bool used(std::int64_t version) const {
    if (usage_ == nullptr) return true;  // the stack way (x_{N-1} of the forward sweep: feed())
    const auto it = usage_->loads.find(version);
    return !emit_ || (it != usage_->loads.end() && it->second > 0);
  }

  // The contract (docs/guides/checkpoint_schedule.md, "The contract"): restart data is written only by
  // the Forward that leaves the state, and it covers the steps that Forward runs; WORK must be empty for
  // a Copy/Move, and is emptied by every Forward and by a Reverse that clears; WORK is no checkpoint
  // storage (no Copy from it); a Reverse reads adjoint data only from WORK.
  //
  // A checkpoint write of the state at hand waits for the Forward that leaves it (writeIcs). When that
  // state was loaded and not yet advanced, the write is a Copy/Move between the two storages instead,
  // before the state enters WORK: loads into WORK are therefore held back (pendingLoad_) until the
  // state is advanced or reversed.
  void store(const PlanEvent& ev) {
    const std::int64_t position = ev.key.rfind("at ", 0) == 0 ? ev.a : current_;
    if (position != current_) throw std::logic_error("checkpointSchedule: a store of a state not at hand");
    const Content c{nextVersion_++, position, ev.level, key(ev.level, ev.key)};
    setSlot(c);
    if (!used(c.version)) return;
    if (pendingLoad_.version >= 0 && pendingLoad_.position == position) {
      copyBetween(pendingLoad_, ev.level);
      pendingLoad_ = c;  // the state at hand now comes from the new checkpoint
    } else {
      if (usage_ == nullptr && !pendingIcs_.empty()) {
        // The stack way: a second store of the state at hand moves the checkpoint to the other storage
        // before it was written (one checkpoint per state on the stack).
        eraseSlot(pendingStore_);
        pendingIcs_.clear();
      }
      pendingIcs_.push_back(ev.level);
      pendingStore_ = c;
    }
  }
  void storeRecord(const PlanEvent& ev) {
    // A record of step k: the stage values of step k, written to RAM by the next Forward over step k (at
    // once in the forward sweep; after an upgrade, when its interval is entered) and moved to WORK for
    // the Reverse of step k. A record also holds x_k: as a restart point it is a state checkpoint at k.
    const std::string k = key(CheckpointStorage::kRam, "at " + std::to_string(ev.a));
    const auto existing = slots_.find(k);
    if (existing == slots_.end() || existing->second.position != ev.a) {
      if (ev.a != current_) throw std::logic_error("checkpointSchedule: a record of a state not at hand");
      const Content c{nextVersion_++, ev.a, CheckpointStorage::kRam, k};
      setSlot(c);
      if (used(c.version)) pendingIcs_.push_back(CheckpointStorage::kRam);
    }
    wantAdjDeps_.insert(ev.a);
  }
  static std::string key(CheckpointStorage level, const std::string& slot) {
    return std::string(checkpointStorageName(level)) + " " + slot;
  }
  const Content& slotContent(CheckpointStorage level, const std::string& slot) {
    const auto it = slots_.find(key(level, slot));
    if (it == slots_.end()) throw std::logic_error("checkpointSchedule: a load of an empty slot " + slot);
    return it->second;
  }

  // Slots by name, and by position for need(); a slot stored again drops its old content.
  void setSlot(const Content& c) {
    const auto it = slots_.find(c.key);
    if (it != slots_.end()) eraseSlot(it->second);
    slots_[c.key] = c;
    byPosition_.emplace(c.position, c.key);
  }
  void eraseSlot(Content c) {
    const auto range = byPosition_.equal_range(c.position);
    for (auto it = range.first; it != range.second; ++it) {
      if (it->second == c.key) {
        byPosition_.erase(it);
        break;
      }
    }
    slots_.erase(c.key);
  }

  // One use of checkpoint c: true when it is its last (the data is then released: a Move). toWork: the
  // state enters WORK (else it goes on to another storage).
  bool use(const Content& c, bool toWork) {
    if (usage_ == nullptr) return !toWork || c.position == expected_;  // the stack way (class comment)
    std::int64_t& seen = usage_->seen[c.version];
    ++seen;
    if (!emit_) {
      ++usage_->loads[c.version];
      return false;
    }
    const auto loads = usage_->loads.find(c.version);
    if (loads == usage_->loads.end() || seen > loads->second)
      throw std::logic_error("checkpointSchedule: x_" + std::to_string(c.position) +
                             " is read more often than counted");
    if (seen < loads->second) return false;
    // The last read: nothing asks about this version again (the lazy stream keeps O(checkpoints) entries).
    usage_->seen.erase(c.version);
    usage_->loads.erase(loads);
    return true;
  }

  void copyBetween(const Content& c, CheckpointStorage to) {
    CheckpointAction a;
    a.kind = use(c, to == CheckpointStorage::kWork) ? Kind::kMove : Kind::kCopy;
    if (a.kind == Kind::kMove && usage_ == nullptr) {
      // Released: a later load of it would find its slot empty (and throw).
      const auto it = slots_.find(c.key);
      if (it != slots_.end() && it->second.version == c.version) eraseSlot(c);
    }
    a.n0 = a.n1 = c.position;
    a.from = c.level;
    a.to = to;
    actions_.push_back(a);
  }

  void load(const Content& c) {
    if (!pendingIcs_.empty() && emit_)
      throw std::logic_error("checkpointSchedule: a stored state is left unadvanced");
    pendingIcs_.clear();
    pendingLoad_ = c;
    current_ = c.position;
  }
  void flushLoad() {
    if (pendingLoad_.version < 0) return;
    copyBetween(pendingLoad_, CheckpointStorage::kWork);
    pendingLoad_ = Content{};
  }

  // x_n in WORK: as it is, or loaded from a checkpoint holding it (cams names no loads).
  void need(std::int64_t n) {
    if (current_ == n) return;
    const Content* best = nullptr;
    const auto range = byPosition_.equal_range(n);
    for (auto it = range.first; it != range.second; ++it) {
      const Content& c = slots_.at(it->second);
      if ((best == nullptr || (c.level == CheckpointStorage::kRam && best->level != c.level))) best = &c;
    }
    if (best == nullptr)
      throw std::logic_error("checkpointSchedule: x_" + std::to_string(n) + " is neither at hand nor stored");
    load(*best);
  }

  // Advance the WORK state to x_to in Forwards that write the pending checkpoints (the first storage as
  // writeIcs, further storages as copies from it afterwards) and the adjoint data of the record steps on
  // the way, each in a Forward of its own step. last: the forward run's final step, whose adjoint data
  // goes to WORK unless it is a record's.
  void forwardTo(std::int64_t to, bool last = false) {
    flushLoad();
    while (current_ < to) {
      std::int64_t end = to;
      bool adj = false;
      const auto next = wantAdjDeps_.lower_bound(current_);
      if (next != wantAdjDeps_.end() && *next < to) {
        if (*next == current_) {
          adj = true;
          end = current_ + 1;
        } else {
          end = *next;
        }
      }
      if (last && !adj && end == to && to - current_ > 1) end = to - 1;  // the last step on its own
      const bool tape = last && end == to && !adj;
      CheckpointAction a;
      a.kind = Kind::kForward;
      a.n0 = current_;
      a.n1 = end;
      a.writeAdjDeps = adj || tape;
      a.storage = adj ? CheckpointStorage::kRam : CheckpointStorage::kWork;
      std::vector<CheckpointStorage> copies;
      if (!pendingIcs_.empty()) {
        // (The first pass counts every store as used.)
        if (tape && emit_) throw std::logic_error("checkpointSchedule: x_{N-1} stored and loaded later");
        if (tape) {
        } else if (adj) {
          // A record's step: its restart data goes with it (a record is a restart point too); a state
          // checkpoint elsewhere is a copy of that.
          a.writeIcs = true;
          for (CheckpointStorage level : pendingIcs_)
            if (level != CheckpointStorage::kRam) copies.push_back(level);
        } else {
          a.writeIcs = true;
          a.storage = pendingIcs_.front();
          copies.assign(pendingIcs_.begin() + 1, pendingIcs_.end());
        }
        pendingIcs_.clear();
      }
      if (adj) {
        wantAdjDeps_.erase(current_);
        heldAdjDeps_.insert(current_);
      }
      actions_.push_back(a);
      for (CheckpointStorage level : copies) {
        CheckpointAction c;
        c.kind = Kind::kCopy;
        c.n0 = c.n1 = a.n0;
        c.from = a.storage;
        c.to = level;
        actions_.push_back(c);
      }
      current_ = end;
    }
  }

  void reverse(std::int64_t e) {
    CheckpointAction a;
    a.kind = Kind::kReverse;
    a.n1 = e + 1;
    a.n0 = e;
    a.clearAdjDeps = true;
    actions_.push_back(a);
  }

  // Adjoint data of a record step held in RAM: moved to WORK for its Reverse.
  void fetchHeldAdjDeps(std::int64_t e) {
    heldAdjDeps_.erase(e);
    CheckpointAction a;
    a.kind = Kind::kMove;
    a.n0 = a.n1 = e;
    a.from = CheckpointStorage::kRam;
    a.to = CheckpointStorage::kWork;
    actions_.push_back(a);
  }

  void deliver(std::int64_t e, bool withStages) {
    if (!pendingIcs_.empty() && emit_)
      throw std::logic_error("checkpointSchedule: a stored state is left unadvanced");
    pendingIcs_.clear();
    if (withStages || heldAdjDeps_.count(e) != 0) {
      if (heldAdjDeps_.count(e) == 0)
        throw std::logic_error("checkpointSchedule: a record delivered before it was filled");
      pendingLoad_ = Content{};
      fetchHeldAdjDeps(e);
    } else {
      need(e);
      flushLoad();
      CheckpointAction a;
      a.kind = Kind::kForward;
      a.n0 = e;
      a.n1 = e + 1;
      a.writeAdjDeps = true;
      a.storage = CheckpointStorage::kWork;
      actions_.push_back(a);
    }
    reverse(e);
    current_ = -1;  // the adjoint step consumes the state at hand
    // A checkpoint at e is of no use any more (restores go down); its data is released by its last load.
    // The counted way keys slots by position: forget e's, so that what is kept stays O(checkpoints).
    if (usage_ != nullptr) {
      for (auto range = byPosition_.equal_range(e); range.first != range.second;) {
        slots_.erase(range.first->second);
        range.first = byPosition_.erase(range.first);
      }
      wantAdjDeps_.erase(e);
    }
  }

  std::int64_t steps_;
  Usage* usage_;
  bool emit_;
  std::deque<CheckpointAction>& actions_;
  Phase phase_ = Phase::kForward;
  std::int64_t recorded_ = 0, expected_ = 0;
  bool replays_ = false;  // the restore of x_{N-1} does more than load it
  std::vector<PlanEvent> firstRestore_;
  std::map<std::string, Content> slots_;
  std::multimap<std::int64_t, std::string> byPosition_;
  std::vector<CheckpointStorage> pendingIcs_;
  Content pendingLoad_;   // version -1: none
  Content pendingStore_;  // the stack way: the store pendingIcs_ holds
  std::set<std::int64_t> wantAdjDeps_, heldAdjDeps_;
  std::int64_t current_ = 0, nextVersion_ = 0;
};

}  // namespace

// A plan's whole text translated the counted way (the reference of the cams stream, CamsPlanStream).
std::vector<CheckpointAction> translateCheckpointPlan(const std::string& spec, std::int64_t steps,
                                                      std::int64_t stateBytes, int stages,
                                                      const ScheduleCosts* costs) {
  const StorageSpec parsed = StorageSpec::parse(spec);
  if (parsed.has("stages") && parsed.integer("stages", 0, 0, 1) == 1 && stages > 1) {
    throw std::invalid_argument(parsed.name() +
                                ".stages = 1 keeps stage values by a rule of its own, which the action "
                                "stream does not express; use " +
                                parsed.name() +
                                " without stages=1, or cams (whose "
                                "step records it expresses)");
  }
  std::ostringstream plan;
  writeScheduleActions(spec, steps, stateBytes, stages, costs, plan);  // validates everything first
  const std::vector<PlanEvent> events = parsePlan(plan.str());
  Translator::Usage usage;
  for (bool emit : {false, true}) {
    usage.seen.clear();
    std::deque<CheckpointAction> actions;
    Translator translator(steps, &usage, emit, actions);
    for (const PlanEvent& ev : events) translator.feed(ev);
    translator.finish();
    if (emit) return std::vector<CheckpointAction>(actions.begin(), actions.end());
  }
  return {};
}

namespace {

// A stream that drives a plan as the host consumes it and translates the plan's events as they come
// (multilevel's and cams' streams): each refill feeds the plan's next step to the translation, whose
// actions land in queue_, and the translation ends (EndReverse) once the plan has no step left.
class TranslatedPlanStream : public BatchedCheckpointStream {
 protected:
  /// counted: the translation's counted way, with usage_ (cams); else the stack way (multilevel).
  TranslatedPlanStream(std::int64_t steps, bool counted)
      : BatchedCheckpointStream(steps), translator_(steps, counted ? &usage_ : nullptr, true, queue_) {}
  /// Feeds the plan's next step (a record of the forward sweep, a restore of the backward sweep) to
  /// translator_; false when there is none left.
  virtual bool feedNext() = 0;
  Translator::Usage usage_;
  Translator translator_;

 private:
  bool refill() final {
    if (feedNext()) return true;
    if (finished_) return false;
    translator_.finish();
    finished_ = true;
    return true;
  }
  bool finished_ = false;
};

// multilevel's stream: its TwoLevelPlan (MultilevelStorage::fixedStepPlan, the plan a run executes) is
// driven as the host consumes the actions -- the forward sweep record by record, then the backward sweep
// restore by restore -- and translated the stack way. Memory: the plan and the slots' contents.
class TwoLevelPlanStream final : public TranslatedPlanStream {
 public:
  TwoLevelPlanStream(std::int64_t steps, TwoLevelPlan plan)
      : TranslatedPlanStream(steps, /*counted=*/false), plan_(std::move(plan)) {
    plan_.rewind();
  }

 private:
  struct Visitor {
    TwoLevelPlanStream& s;
    PlanEvent event(PlanEvent::Kind kind, StorageLevel level, std::int64_t slot) const {
      const bool disk = level == StorageLevel::kDisk;
      return PlanEvent{kind,
                       disk ? CheckpointStorage::kDisk : CheckpointStorage::kRam,
                       (disk ? "disk " : "ram ") + std::to_string(slot),
                       -1,
                       0,
                       false};
    }
    void store(StorageLevel level, std::int64_t slot) {
      if (s.record_ >= 0) {
        s.translator_.feed(
            PlanEvent{PlanEvent::Kind::kRecord, CheckpointStorage::kWork, "", s.record_, 0, false});
        s.record_ = -1;
      }
      s.translator_.feed(event(PlanEvent::Kind::kStore, level, slot));
    }
    void load(StorageLevel level, std::int64_t slot) {
      s.translator_.feed(event(PlanEvent::Kind::kLoad, level, slot));
    }
    void advance(std::int64_t from, std::int64_t to) {
      s.translator_.feed(PlanEvent{PlanEvent::Kind::kAdvance, CheckpointStorage::kWork, "", from, to, false});
    }
  };

  bool feedNext() override {
    Visitor visitor{*this};
    if (forward_ < maxN_) {
      record_ = forward_;  // fed before the record's first store, if any
      plan_.recordForward(forward_++, visitor);
      record_ = -1;
    } else if (restore_ >= 0) {
      plan_.restoreStep(restore_, visitor);
      translator_.feed(
          PlanEvent{PlanEvent::Kind::kDeliver, CheckpointStorage::kWork, "", restore_, restore_, false});
      --restore_;
    } else {
      return false;
    }
    return true;
  }

  TwoLevelPlan plan_;
  std::int64_t forward_ = 0, restore_ = maxN_ - 1, record_ = -1;
};

}  // namespace

std::unique_ptr<CheckpointStream> openTwoLevelPlanStream(std::int64_t steps, TwoLevelPlan plan) {
  return std::make_unique<TwoLevelPlanStream>(steps, std::move(plan));
}

namespace {

// cams' stream: its plan's executor (cams::Executor, the one a run drives) is driven as the host consumes
// the actions and its events are translated the counted way, each checkpoint's reads counted when it is
// stored from the plan's decisions (Executor::lastStoredUse) instead of by a first pass over the whole
// plan. Memory: the plan's tables and O(checkpoints) of translation. The events are the ones
// CamsCheckpointing::writeActions prints (cams::simulate's actions: consecutive advances merged, no loads),
// so the stream is translateCheckpointPlan's action for action (tests/storage/checkpoint_actions_test.cpp).
//
// online=1 with N known: the forward run writes the checkpoints the online placement holds when the run
// ends (OnlinePlacement::simulate, O(N) time and O(c) memory before the first action; the ones it would
// have thinned away are never written), x_{N-1} stays the working state, and each interval is reversed by
// the interval plan as cams::simulateOnline does -- the plan made when the forward run ends, the first
// Reverse waiting for it. Intervals longer than that plan (revolve's, whose slots this translation does
// not express) are refused when the stream is opened.
class CamsPlanStream final : public TranslatedPlanStream {
 public:
  CamsPlanStream(std::int64_t steps, std::unique_ptr<cams::Plan> plan)
      : TranslatedPlanStream(steps, /*counted=*/true), plan_(std::move(plan)) {
    executor_.reset(plan_.get());
  }
  CamsPlanStream(std::int64_t steps, std::vector<std::int64_t> positions, std::int64_t memoryUnits,
                 std::int64_t recordUnits)
      : TranslatedPlanStream(steps, /*counted=*/true),
        online_(true),
        positions_(std::move(positions)),
        versions_(positions_.size(), -1),
        memoryUnits_(memoryUnits),
        recordUnits_(recordUnits) {}

 private:
  struct Visitor {
    CamsPlanStream& s;
    void load(std::int64_t) {}  // cams names no loads: the translation reads the state where it is needed
    void capture(std::int64_t, std::int64_t) {}
    void advance(std::int64_t from, std::int64_t to) {
      if (s.advance_.second == from && s.advance_.first < from) {
        s.advance_.second = to;
        return;
      }
      s.flushAdvance();
      s.advance_ = {from, to};
    }
    void upgrade(std::int64_t, std::int64_t position) {
      // The anchor grows into a record: the same checkpoint, whose reads were counted when it was stored.
      s.flushAdvance();
      s.translator_.feed(PlanEvent{PlanEvent::Kind::kStoreRecord, CheckpointStorage::kRam,
                                   "at " + std::to_string(position), position, 0, false});
    }
    void store(std::int64_t, std::int64_t position, bool record) {
      s.flushAdvance();
      s.store(position, record, /*forwardSweep=*/false);
    }
    void deliver(std::int64_t position, std::int64_t, bool filled) {
      s.flushAdvance();
      s.translator_.feed(
          PlanEvent{PlanEvent::Kind::kDeliver, CheckpointStorage::kWork, "", position, position, filled});
    }
  };

  void flushAdvance() {
    if (advance_.first >= advance_.second) return;
    translator_.feed(PlanEvent{PlanEvent::Kind::kAdvance, CheckpointStorage::kWork, "", advance_.first,
                               advance_.second, false});
    advance_ = {0, 0};
  }

  // A new checkpoint: the translation reads its state at every advance from it and at its delivery unless
  // its stage values are held then, except the first read after a store in the backward sweep (the state
  // is still at hand) and x_{N-1} kept by the forward sweep (its delivery is the forward run's last step).
  void store(std::int64_t position, bool record, bool forwardSweep) {
    const cams::Executor::AnchorUse use = executor_.lastStoredUse();
    const std::int64_t reads = forwardSweep && position == maxN_ - 1
                                   ? 0
                                   : use.advances + (use.filledAtDelivery ? 0 : 1) - (forwardSweep ? 0 : 1);
    if (reads > 0) usage_.loads[translator_.nextVersion()] = reads;
    translator_.feed(PlanEvent{record ? PlanEvent::Kind::kStoreRecord : PlanEvent::Kind::kStore,
                               CheckpointStorage::kRam, "at " + std::to_string(position), position, 0,
                               false});
  }

  // online: the placement's checkpoint `index`, stored in the forward run; its reads are counted when its
  // interval begins (the plan does not exist before), until then it is only known to be read (every
  // interval's anchor is: advanced from, or delivered by a load).
  void storeOnline(std::size_t index) {
    versions_[index] = translator_.nextVersion();
    usage_.loads[versions_[index]] = 1;
    translator_.feed(PlanEvent{PlanEvent::Kind::kStore, CheckpointStorage::kRam,
                               "at " + std::to_string(positions_[index]), positions_[index], 0, false});
  }
  void restoreOnline(std::int64_t e, Visitor& visitor) {
    if (e == maxN_ - 1) {  // the working state: the forward run's last step writes its adjoint data
      translator_.feed(PlanEvent{PlanEvent::Kind::kDeliver, CheckpointStorage::kWork, "", e, e, false});
      return;
    }
    if (!plan_) {
      const std::int64_t longest = internal::OnlinePlacement::longestInterval(positions_, maxN_);
      cams::onlineIntervalPlan(plan_, longest, memoryUnits_, recordUnits_);
      executor_.reserve(std::min(memoryUnits_, longest + 1));
    }
    if (e < interval_.start) {
      // As cams::simulateOnline: interval j's checkpoint in unit j, the units above it free.
      interval_ = internal::OnlinePlacement::intervalOf(positions_, maxN_, e, interval_.index);
      executor_.beginInterval(plan_.get(), interval_.start, interval_.index, interval_.length,
                              memoryUnits_ - interval_.index - 1);
      const cams::Executor::AnchorUse use = executor_.lastStoredUse();
      usage_.loads[versions_[static_cast<std::size_t>(interval_.index)]] =
          use.advances + (use.filledAtDelivery ? 0 : 1);
    }
    executor_.restoreStep(e, visitor);
  }

  bool feedNext() override {
    if (forward_ < maxN_ && online_) {
      // Straight to the next held position (the forward run is cut only where it writes).
      if (nextPosition_ < positions_.size()) {
        forward_ = positions_[nextPosition_];
        storeOnline(nextPosition_++);
        ++forward_;
      } else {
        forward_ = maxN_;
      }
    } else if (forward_ < maxN_) {
      bool record = false;
      if (executor_.recordForward(forward_, &record) >= 0) store(forward_, record, /*forwardSweep=*/true);
      ++forward_;
    } else if (restore_ >= 0 && online_) {
      Visitor visitor{*this};
      restoreOnline(restore_--, visitor);
      flushAdvance();
    } else if (restore_ >= 0) {
      Visitor visitor{*this};
      executor_.restoreStep(restore_--, visitor);
      flushAdvance();
    } else {
      return false;
    }
    return true;
  }

  bool online_ = false;
  std::vector<std::int64_t> positions_, versions_;  // online: the held positions, their checkpoints' versions
  std::size_t nextPosition_ = 0;
  std::int64_t memoryUnits_ = 0, recordUnits_ = 0;
  internal::OnlinePlacement::Interval interval_{static_cast<std::int64_t>(positions_.size()), maxN_, 0};
  std::unique_ptr<cams::Plan> plan_;
  cams::Executor executor_;
  std::pair<std::int64_t, std::int64_t> advance_{0, 0};  // consecutive advances, merged
  std::int64_t forward_ = 0, restore_ = maxN_ - 1;
};

}  // namespace

std::unique_ptr<CheckpointStream> openCamsPlanStream(std::int64_t steps, std::unique_ptr<cams::Plan> plan) {
  return std::make_unique<CamsPlanStream>(steps, std::move(plan));
}

std::unique_ptr<CheckpointStream> openCamsOnlineStreamAt(std::int64_t steps,
                                                         std::vector<std::int64_t> positions,
                                                         std::int64_t memoryUnits, std::int64_t recordUnits) {
  const std::int64_t longest = internal::OnlinePlacement::longestInterval(positions, steps);
  const std::int64_t planned = cams::onlineIntervalPlanSteps(longest, memoryUnits, recordUnits);
  if (longest > planned) {
    throw std::invalid_argument(
        "cams with online=1: the placement of " + std::to_string(steps) + " steps has an interval of " +
        std::to_string(longest) + " steps, beyond the " + std::to_string(planned) +
        " its plan reverses (longer ones are revolve's, which the action stream does not translate); "
        "raise cams.checkpoints/cams.budget or drop online=1");
  }
  return std::make_unique<CamsPlanStream>(steps, std::move(positions), memoryUnits, recordUnits);
}

std::unique_ptr<CheckpointStream> openCamsOnlineStream(std::int64_t steps, std::int64_t memoryUnits,
                                                       std::int64_t recordUnits) {
  if (steps > prediction::kMaxWalkedSteps) {
    throw std::invalid_argument(
        "cams with online=1 streams steps up to " + std::to_string(prediction::kMaxWalkedSteps) +
        " (2^24: its placement is walked step by step before the first action); steps = " +
        std::to_string(steps));
  }
  return openCamsOnlineStreamAt(steps,
                                internal::OnlinePlacement::simulate(steps, memoryUnits - 1, nullptr, nullptr),
                                memoryUnits, recordUnits);
}

std::vector<CheckpointAction> checkpointSchedule(const std::string& spec, std::int64_t steps,
                                                 std::int64_t stateBytes, int stages,
                                                 const ScheduleCosts* costs) {
  const std::unique_ptr<CheckpointStream> stream =
      openCheckpointStream(spec, steps, stateBytes, stages, costs);
  std::vector<CheckpointAction> actions;
  CheckpointAction action;
  while (stream->next(&action)) actions.push_back(action);
  return actions;
}

// The contract of docs/guides/checkpoint_schedule.md ("The contract"), as python/tests/stream_contract.py
// states it rule by rule: checkpoints are keyed by their step per storage and hold the step ranges of their
// restart data and adjoint data; WORK holds the same two sets.
void CheckpointStreamChecker::take(const CheckpointAction& a) {
  const auto empty = [](const Range& r) { return r.first >= r.second; };
  const auto fail = [&](const std::string& why) { throw std::logic_error(a.text() + ": " + why); };
  const auto checkpointStorage = [](CheckpointStorage s) {
    return s == CheckpointStorage::kRam || s == CheckpointStorage::kDisk;
  };
  if (reverseDone) fail("after EndReverse");
  switch (a.kind) {
    case CheckpointAction::Kind::kForward: {
      if (at != a.n0) fail("WORK holds x_" + std::to_string(at));
      if (a.n1 <= a.n0) fail("advances no step");
      if (a.n1 > steps - reversed)
        fail("advances past the adjoint at step " + std::to_string(steps - reversed));
      workIcs = workAdjDeps = Range{0, 0};
      // A state checkpoint (RestartData::kState) restarts every step from its own on.
      const Range ics = a.writeIcs ? Range{a.n0, states ? steps : a.n1} : Range{0, 0};
      const Range adjDeps = a.writeAdjDeps ? Range{a.n0, a.n1} : Range{0, 0};
      if (checkpointStorage(a.storage)) {
        if (empty(ics) && empty(adjDeps)) fail("writes nothing to a checkpoint storage");
        if (!held[a.storage].emplace(a.n0, Snapshot{ics, adjDeps}).second)
          fail("a checkpoint at " + std::to_string(a.n0) + " exists there");
        if (a.writeIcs)
          (a.storage == CheckpointStorage::kRam ? counts.ramIcsWrites : counts.diskIcsWrites) += 1;
      } else if (a.storage == CheckpointStorage::kWork) {
        workIcs = ics;
        workAdjDeps = adjDeps;
      }
      const std::int64_t length = a.n1 - a.n0;
      const bool rerun = a.writeAdjDeps && a.storage == CheckpointStorage::kWork && length == 1;
      if (!forwardDone) {
        counts.forwardSteps += length;
        if (rerun && a.n1 == steps) ++counts.adjointReruns;
      } else if (rerun) {
        ++counts.adjointReruns;
      } else {
        counts.recomputedSteps += length;
      }
      at = a.n1;
      break;
    }
    case CheckpointAction::Kind::kCopy:
    case CheckpointAction::Kind::kMove: {
      if (!checkpointStorage(a.from)) fail("copies from a storage that holds no checkpoints");
      if (states && a.kind == CheckpointAction::Kind::kMove && a.to == CheckpointStorage::kNone) {
        // The release of a state checkpoint: it touches neither WORK nor the adjoint.
        if (held[a.from].erase(a.n0) == 0) fail("no checkpoint at " + std::to_string(a.n0) + " there");
        break;
      }
      if (!checkpointStorage(a.to) && a.to != CheckpointStorage::kWork) fail("copies to no storage");
      if (!empty(workIcs) || !empty(workAdjDeps)) fail("WORK still holds data");
      const auto it = held[a.from].find(a.n0);
      if (it == held[a.from].end()) fail("no checkpoint at " + std::to_string(a.n0) + " there");
      const Snapshot snapshot = it->second;
      if (a.kind == CheckpointAction::Kind::kMove) held[a.from].erase(it);
      if (a.n0 >= steps - reversed) fail("the checkpoint is not before the adjoint");
      if (checkpointStorage(a.to)) {
        if (!held[a.to].emplace(a.n0, snapshot).second)
          fail("a checkpoint at " + std::to_string(a.n0) + " exists there");
        if (!empty(snapshot.ics))
          (a.to == CheckpointStorage::kRam ? counts.ramIcsWrites : counts.diskIcsWrites) += 1;
      } else {
        const bool restart = snapshot.ics.first <= a.n0 && a.n0 < snapshot.ics.second;
        at = restart ? a.n0 : -1;
        if (restart && snapshot.ics.second < steps - reversed)
          fail("its restart data does not reach the adjoint at step " + std::to_string(steps - reversed));
        workIcs = snapshot.ics;
        workAdjDeps = snapshot.adjDeps;
        if (std::min<std::int64_t>(1, workIcs.second - workIcs.first) +
                std::max<std::int64_t>(0, workAdjDeps.second - workAdjDeps.first) >
            1)
          fail("WORK would hold more than one unit");
      }
      break;
    }
    case CheckpointAction::Kind::kReverse:
      if (!forwardDone) fail("before EndForward");
      if (a.n1 != steps - reversed || a.n0 >= a.n1)
        fail("the adjoint is at step " + std::to_string(steps - reversed));
      if (workAdjDeps.first > a.n0 || workAdjDeps.second < a.n1) fail("its adjoint data is not in WORK");
      reversed += a.n1 - a.n0;
      if (a.clearAdjDeps) workAdjDeps = Range{0, 0};
      break;
    case CheckpointAction::Kind::kEndForward:
      if (forwardDone || at != steps) fail("the forward run is not at x_N");
      forwardDone = true;
      break;
    case CheckpointAction::Kind::kEndReverse:
      if (reversed != steps) fail(std::to_string(reversed) + " steps reversed");
      reverseDone = true;
      break;
  }
  std::int64_t restartRam = 0, restartDisk = 0;
  for (const auto& [step, snapshot] : held[CheckpointStorage::kRam]) restartRam += !empty(snapshot.ics);
  for (const auto& [step, snapshot] : held[CheckpointStorage::kDisk]) restartDisk += !empty(snapshot.ics);
  counts.peakRamCheckpoints = std::max(counts.peakRamCheckpoints, restartRam);
  counts.peakDiskCheckpoints = std::max(counts.peakDiskCheckpoints, restartDisk);
}

CheckpointStreamCounts CheckpointStreamChecker::finish() {
  if (!reverseDone) throw std::logic_error("the stream ends without EndReverse");
  if (!held[CheckpointStorage::kRam].empty() || !held[CheckpointStorage::kDisk].empty())
    throw std::logic_error("checkpoints are left when the stream ends");
  return counts;
}

CheckpointStreamCounts checkCheckpointStream(const std::vector<CheckpointAction>& actions, std::int64_t steps,
                                             RestartData restartData) {
  CheckpointStreamChecker checker(steps, restartData);
  for (const CheckpointAction& a : actions) checker.take(a);
  return checker.finish();
}

}  // namespace hindsight
