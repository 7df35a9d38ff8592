#include <hindsight/storage/checkpoint_actions.h>

#include <hindsight/engine/storage_spec.h>

#include <algorithm>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

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

// The translation, run twice: the first pass learns which stored states are loaded later (and which
// load is a state's last), the second emits the stream with that knowledge.
class Translator {
 public:
  struct Usage {
    std::map<std::int64_t, std::int64_t> loads;  // version -> number of loads
    std::map<std::int64_t, std::int64_t> seen;   // version -> loads emitted so far (second pass)
    std::set<std::int64_t> adjDepsUsed;          // steps whose record's adjoint data a Reverse uses
  };

  Translator(std::int64_t steps, Usage& usage, bool emit) : steps_(steps), usage_(usage), emit_(emit) {}

  std::vector<CheckpointAction> run(const std::vector<PlanEvent>& events) {
    std::size_t i = 0;
    std::int64_t recorded = 0;
    // Forward sweep: records and stores, up to the first restore, load or advance. The forward run goes
    // on uninterrupted; it is cut into Forwards only where it writes something. (cams names the position
    // of each store and prints no records.)
    for (; i < events.size(); ++i) {
      const PlanEvent& ev = events[i];
      if (ev.kind == PlanEvent::Kind::kRecord) {
        recorded = ev.a;
      } else if (ev.kind == PlanEvent::Kind::kStore || ev.kind == PlanEvent::Kind::kStoreRecord) {
        forwardTo(ev.a >= 0 ? ev.a : recorded);
        if (ev.kind == PlanEvent::Kind::kStore)
          store(ev);
        else
          storeRecord(ev);
      } else {
        break;
      }
    }
    // x_{N-1}: when the plan holds it (a working state, loaded without recomputation), the forward run's
    // last step writes its adjoint data (to RAM for a record, else WORK) and that delivery is skipped;
    // when the plan replays it from a checkpoint, the replay is translated like every other restore.
    std::size_t lastDelivery = i;
    bool replays = false;  // anything but loads
    for (; lastDelivery < events.size() && events[lastDelivery].kind != PlanEvent::Kind::kDeliver;
         ++lastDelivery) {
      const PlanEvent::Kind kind = events[lastDelivery].kind;
      replays = replays || (kind != PlanEvent::Kind::kLoad && kind != PlanEvent::Kind::kBeginRestore);
    }
    if (lastDelivery == events.size() || events[lastDelivery].a != steps_ - 1) {
      throw std::logic_error("checkpointSchedule: the first restore is not x_{N-1}");
    }
    forwardTo(steps_, /*last=*/!replays);
    out(Kind::kEndForward);
    std::int64_t expected = steps_ - 1;
    if (!replays) {
      i = lastDelivery + 1;
      reverse(steps_ - 1);
      expected = steps_ - 2;
    }
    current_ = -1;
    for (; i < events.size(); ++i) {
      const PlanEvent& ev = events[i];
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
          if (ev.a != expected) throw std::logic_error("checkpointSchedule: restores out of order");
          deliver(ev.a, ev.withStages);
          --expected;
          break;
        case PlanEvent::Kind::kBeginRestore:
          break;
        case PlanEvent::Kind::kRecord:
          throw std::logic_error("checkpointSchedule: a forward record in the backward sweep");
      }
    }
    if (expected != -1) throw std::logic_error("checkpointSchedule: the plan does not restore every state");
    out(Kind::kEndReverse);
    return std::move(actions_);
  }

 private:
  using Kind = CheckpointAction::Kind;
  struct Content {
    std::int64_t version = -1, position = -1;
    CheckpointStorage level = CheckpointStorage::kRam;
  };

  void out(Kind kind, std::int64_t n0 = 0, std::int64_t n1 = 0) {
    CheckpointAction a;
    a.kind = kind;
    a.n0 = n0;
    a.n1 = n1;
    actions_.push_back(a);
  }

  bool used(std::int64_t version) const {
    const auto it = usage_.loads.find(version);
    return !emit_ || (it != usage_.loads.end() && it->second > 0);
  }

  // Checkpoint writes of the state at hand wait for the Forward that leaves it (writeIcs) or, when the
  // state is not advanced, become a Copy from WORK.
  void store(const PlanEvent& ev) {
    const std::int64_t position = ev.key.rfind("at ", 0) == 0 ? ev.a : current_;
    if (position != current_) throw std::logic_error("checkpointSchedule: a store of a state not at hand");
    const Content c{nextVersion_++, position, ev.level};
    slots_[key(ev.level, ev.key)] = c;
    if (used(c.version)) pendingIcs_.push_back(ev.level);
  }
  void storeRecord(const PlanEvent& ev) {
    // A record of step k: its state (a restart point) and the stage values captured by the next Forward
    // over step k (at once in the forward sweep; after an upgrade, when its interval is entered).
    const std::string k = key(CheckpointStorage::kRam, "at " + std::to_string(ev.a));
    const auto existing = slots_.find(k);
    if (existing == slots_.end() || existing->second.position != ev.a) {
      if (ev.a != current_) throw std::logic_error("checkpointSchedule: a record of a state not at hand");
      const Content c{nextVersion_++, ev.a, CheckpointStorage::kRam};
      slots_[k] = c;
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

  void flushIcs() {
    for (CheckpointStorage level : pendingIcs_) {
      CheckpointAction a;
      a.kind = Kind::kCopy;
      a.n0 = a.n1 = current_;
      a.from = CheckpointStorage::kWork;
      a.to = level;
      actions_.push_back(a);
    }
    pendingIcs_.clear();
  }

  void load(const Content& c) {
    flushIcs();
    CheckpointAction a;
    std::int64_t& seen = usage_.seen[c.version];
    ++seen;
    if (!emit_) ++usage_.loads[c.version];
    const bool last = emit_ && seen == usage_.loads[c.version];
    a.kind = last ? Kind::kMove : Kind::kCopy;
    a.n0 = a.n1 = c.position;
    a.from = c.level;
    a.to = CheckpointStorage::kWork;
    actions_.push_back(a);
    current_ = c.position;
  }

  // x_n in WORK: as it is, or loaded from a checkpoint holding it (cams names no loads).
  void need(std::int64_t n) {
    if (current_ == n) return;
    const Content* best = nullptr;
    for (const auto& [name, c] : slots_) {
      if (c.position == n &&
          (best == nullptr || (c.level == CheckpointStorage::kRam && best->level != c.level)))
        best = &c;
    }
    if (best == nullptr)
      throw std::logic_error("checkpointSchedule: x_" + std::to_string(n) + " is neither at hand nor stored");
    load(*best);
  }

  // Advance the WORK state to x_to in Forwards that write the pending checkpoints (first) and the adjoint
  // data of the record steps on the way, each in a Forward of its own step. last: the forward run's final
  // step, whose adjoint data goes to WORK unless it is a record's.
  void forwardTo(std::int64_t to, bool last = false) {
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
      if (!pendingIcs_.empty()) {
        // writeIcs goes with the Forward's own storage when it writes adjoint data; else to the
        // checkpoint's level; further levels are copies from WORK first.
        auto it = std::find(pendingIcs_.begin(), pendingIcs_.end(),
                            a.writeAdjDeps ? a.storage : pendingIcs_.front());
        if (it != pendingIcs_.end()) {
          a.writeIcs = true;
          a.storage = *it;
          pendingIcs_.erase(it);
        }
        flushIcs();
      }
      if (adj) {
        wantAdjDeps_.erase(current_);
        heldAdjDeps_.insert(current_);
      }
      actions_.push_back(a);
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

  void deliver(std::int64_t e, bool withStages) {
    if (withStages || heldAdjDeps_.count(e) != 0) {
      if (heldAdjDeps_.count(e) == 0)
        throw std::logic_error("checkpointSchedule: a record delivered before it was filled");
      heldAdjDeps_.erase(e);
      flushIcs();
    } else {
      need(e);
      flushIcs();
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
  }

  std::int64_t steps_;
  Usage& usage_;
  bool emit_;
  std::vector<CheckpointAction> actions_;
  std::map<std::string, Content> slots_;
  std::vector<CheckpointStorage> pendingIcs_;
  std::set<std::int64_t> wantAdjDeps_, heldAdjDeps_;
  std::int64_t current_ = 0, nextVersion_ = 0;
};

}  // namespace

std::vector<CheckpointAction> checkpointSchedule(const std::string& spec, std::int64_t steps,
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
  Translator(steps, usage, false).run(events);
  usage.seen.clear();
  return Translator(steps, usage, true).run(events);
}

CheckpointStreamCounts checkCheckpointStream(const std::vector<CheckpointAction>& actions,
                                             std::int64_t steps) {
  CheckpointStreamCounts counts;
  std::int64_t work = 0;                                        // the step of the WORK state, -1 none
  std::map<CheckpointStorage, std::set<std::int64_t>> ics;      // restart states held per storage
  std::map<CheckpointStorage, std::set<std::int64_t>> adjDeps;  // steps whose adjoint data is held
  bool forwardDone = false, reverseDone = false;
  std::int64_t nextReverse = steps - 1;
  for (const CheckpointAction& a : actions) {
    const auto fail = [&](const std::string& why) { throw std::logic_error(a.text() + ": " + why); };
    if (reverseDone) fail("after EndReverse");
    switch (a.kind) {
      case CheckpointAction::Kind::kForward: {
        if (work != a.n0) fail("WORK holds x_" + std::to_string(work));
        if (a.n1 <= a.n0 || a.n1 > steps) fail("not a forward range within N = " + std::to_string(steps));
        if (a.writeIcs) {
          if (a.storage == CheckpointStorage::kWork || a.storage == CheckpointStorage::kNone)
            fail("ics to WORK");
          ics[a.storage].insert(a.n0);
          (a.storage == CheckpointStorage::kRam ? counts.ramIcsWrites : counts.diskIcsWrites) += 1;
        }
        if (a.writeAdjDeps) {
          for (std::int64_t n = a.n0; n < a.n1; ++n) adjDeps[a.storage].insert(n);
        }
        const std::int64_t length = a.n1 - a.n0;
        if (!forwardDone) {
          counts.forwardSteps += length;
          if (a.writeAdjDeps && a.storage == CheckpointStorage::kWork && a.n1 == steps && length == 1)
            ++counts.adjointReruns;
        } else if (a.writeAdjDeps && a.storage == CheckpointStorage::kWork && length == 1) {
          ++counts.adjointReruns;
        } else {
          counts.recomputedSteps += length;
        }
        work = a.n1;
        break;
      }
      case CheckpointAction::Kind::kCopy:
      case CheckpointAction::Kind::kMove:
        if (a.from == CheckpointStorage::kWork) {
          if (work != a.n0) fail("WORK holds x_" + std::to_string(work));
          if (a.kind == CheckpointAction::Kind::kMove) work = -1;
        } else {
          if (ics[a.from].count(a.n0) == 0) fail("x_" + std::to_string(a.n0) + " is not held there");
          if (a.kind == CheckpointAction::Kind::kMove) ics[a.from].erase(a.n0);
        }
        if (a.to == CheckpointStorage::kWork) {
          work = a.n0;
        } else if (a.to != CheckpointStorage::kNone) {
          ics[a.to].insert(a.n0);
          (a.to == CheckpointStorage::kRam ? counts.ramIcsWrites : counts.diskIcsWrites) += 1;
        }
        break;
      case CheckpointAction::Kind::kReverse: {
        if (!forwardDone) fail("before EndForward");
        if (a.n1 != nextReverse + 1 || a.n0 >= a.n1)
          fail("the adjoint is at step " + std::to_string(nextReverse));
        for (std::int64_t n = a.n1 - 1; n >= a.n0; --n) {
          bool found = false;
          for (auto& [storage, held] : adjDeps) {
            if (held.count(n) != 0) {
              found = true;
              if (a.clearAdjDeps) held.erase(n);
              break;
            }
          }
          if (!found) fail("no adjoint data of step " + std::to_string(n));
        }
        nextReverse = a.n0 - 1;
        if (a.n0 <= work) work = -1;
        break;
      }
      case CheckpointAction::Kind::kEndForward:
        if (forwardDone || work != steps) fail("the forward run is not at x_N");
        forwardDone = true;
        break;
      case CheckpointAction::Kind::kEndReverse:
        if (nextReverse != -1) fail("step " + std::to_string(nextReverse) + " is not reversed");
        reverseDone = true;
        break;
    }
    counts.peakRamCheckpoints = std::max<std::int64_t>(
        counts.peakRamCheckpoints, static_cast<std::int64_t>(ics[CheckpointStorage::kRam].size()));
    counts.peakDiskCheckpoints = std::max<std::int64_t>(
        counts.peakDiskCheckpoints, static_cast<std::int64_t>(ics[CheckpointStorage::kDisk].size()));
  }
  if (!reverseDone) throw std::logic_error("the stream ends without EndReverse");
  return counts;
}

}  // namespace hindsight
