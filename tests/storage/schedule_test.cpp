// Schedules as data (storage/schedule.h): the two-level plan against a brute-force search over every
// schedule of the game, free disk against revolve, closed-form counts against the schedule run without
// states, predictions against real runs counter by counter, and N = 1e9.
#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/interrupt.h>
#include <hindsight/engine/online_checkpointing.h>
#include <hindsight/engine/recomputed_stages.h>
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_factory.h>
#include "support/storage_fixtures.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <queue>
#include <sstream>
#include <tuple>
#include <unordered_map>

namespace hindsight {
namespace {

using testing::bitwiseEqual;
using testing::fixedStepRk4;
using testing::fullReference;
using testing::pendulumParameters;
using testing::ScratchDirectory;

// The least cost R uf + W wd + Q rd over ALL schedules of the game of storage/schedule.h (Dijkstra
// over: the positions' levels (none, RAM, disk), the next state to produce, the state at hand).
double bruteForceOptimum(int steps, int ramSlots, int diskSlots, const ScheduleCosts& c) {
  struct State {
    std::uint32_t levels;  // base 3 digit per position: 0 none, 1 RAM, 2 disk
    int next;              // forward sweep: steps; backward: the next position to produce
    int at;                // position at hand, -1 none
    std::uint64_t key(int n) const {
      return (static_cast<std::uint64_t>(levels) * static_cast<std::uint64_t>(n + 2) +
              static_cast<std::uint64_t>(next + 1)) *
                 static_cast<std::uint64_t>(n + 2) +
             static_cast<std::uint64_t>(at + 1);
    }
  };
  std::vector<std::uint32_t> power(static_cast<std::size_t>(steps) + 1, 1);
  for (int i = 1; i <= steps; ++i)
    power[static_cast<std::size_t>(i)] = power[static_cast<std::size_t>(i) - 1] * 3;
  const auto level = [&](std::uint32_t levels, int p) {
    return (levels / power[static_cast<std::size_t>(p)]) % 3;
  };
  using Entry = std::pair<double, std::uint64_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  std::unordered_map<std::uint64_t, double> best;
  std::unordered_map<std::uint64_t, State> states;
  const auto push = [&](const State& s, double cost) {
    const std::uint64_t key = s.key(steps);
    auto it = best.find(key);
    if (it != best.end() && it->second <= cost) return;
    best[key] = cost;
    states[key] = s;
    queue.push({cost, key});
  };
  push(State{0, steps, 0}, 0.0);  // forward sweep at position 0
  while (!queue.empty()) {
    const auto [cost, key] = queue.top();
    queue.pop();
    if (best[key] < cost) continue;
    const State s = states[key];
    const bool forward = s.next == steps;
    if (!forward && s.next < 0) return cost;
    int ram = 0, disk = 0;
    for (int p = 0; p < steps; ++p) {
      ram += level(s.levels, p) == 1;
      disk += level(s.levels, p) == 2;
    }
    // Store the state at hand.
    if (s.at >= 0 && level(s.levels, s.at) == 0) {
      if (ram < ramSlots) push(State{s.levels + power[static_cast<std::size_t>(s.at)], s.next, s.at}, cost);
      if (disk < diskSlots)
        push(State{s.levels + 2 * power[static_cast<std::size_t>(s.at)], s.next, s.at}, cost + c.diskWrite);
    }
    // Discard a checkpoint.
    for (int p = 0; p < steps; ++p) {
      const std::uint32_t l = level(s.levels, p);
      if (l != 0) push(State{s.levels - l * power[static_cast<std::size_t>(p)], s.next, s.at}, cost);
    }
    if (forward) {
      if (s.at < steps - 1)
        push(State{s.levels, steps, s.at + 1}, cost);  // free: the forward sweep
      else
        push(State{s.levels, steps - 1, -1}, cost);  // x_{N-1} must be in a slot now
      continue;
    }
    if (s.at == s.next) {
      // Produce x_next; checkpoints after it are of no further use.
      std::uint32_t levels = s.levels;
      for (int p = s.next; p < steps; ++p) levels -= level(levels, p) * power[static_cast<std::size_t>(p)];
      push(State{levels, s.next - 1, -1}, cost);
      continue;
    }
    if (s.at >= 0 && s.at < s.next) push(State{s.levels, s.next, s.at + 1}, cost + c.forwardStep);
    for (int p = 0; p <= s.next; ++p) {
      const std::uint32_t l = level(s.levels, p);
      if (l != 0 && p != s.at) push(State{s.levels, s.next, p}, cost + (l == 2 ? c.diskRead : 0.0));
    }
  }
  return -1.0;
}

TEST(TwoLevelPlan, FreeDiskIsRevolveWithAllSlotsAndTheOptimumOfTheGame) {
  for (int steps = 1; steps <= 7; ++steps) {
    for (int ram = 1; ram <= 3; ++ram) {
      for (int disk = 0; disk <= 2; ++disk) {
        if (steps >= 2 && ram + disk < 2) continue;
        SCOPED_TRACE("N " + std::to_string(steps) + " ram " + std::to_string(ram) + " disk " +
                     std::to_string(disk));
        const ScheduleCosts free{1.0, 1.0, 0.0, 0.0};
        const TwoLevelPlan plan = TwoLevelPlan::choose(steps, ram, disk, free);
        const double optimum = bruteForceOptimum(steps, ram, disk, free);
        EXPECT_EQ(plan.counts().cost(free), optimum);
        // Free disk: as if every slot were RAM, at least as good as revolve (binomial) with all of them.
        const TwoLevelPlan allRam = TwoLevelPlan::choose(steps, ram + disk, 0, ScheduleCosts{1, 1, 7, 7});
        EXPECT_EQ(plan.counts().recomputedSteps, allRam.counts().recomputedSteps);
        const std::int64_t checkpoints = std::min<std::int64_t>(ram + disk - 1, std::max(1, steps - 1));
        if (steps >= 2 && ram + disk >= 2) {
          EXPECT_LE(
              plan.counts().recomputedSteps,
              static_cast<std::int64_t>(revolve::optimalForwardSteps(steps, checkpoints)) - (steps - 1));
          // The game's optimum with ram + disk slots (this search and the one of
          // binomial_checkpointing_test.cpp are independent): T(N + 1, S) - N, what binomial attains.
          EXPECT_EQ(optimum, static_cast<double>(revolve::optimalRecomputedSteps(steps, ram + disk)));
        }
      }
    }
  }
}

TEST(TwoLevelPlan, EqualsTheBruteForceOptimumOverAllSchedules) {
  // Costs in units of a forward step; the plan is never better than the optimum (it is a schedule of
  // the game) and equal to it in each case below (RecordProperty lists the gaps of the others).
  const ScheduleCosts costs[] = {{1, 1, 0, 0}, {1, 1, 0.5, 0.5}, {1, 1, 1, 1},
                                 {1, 1, 2, 3}, {1, 1, 10, 10},   {1, 1, 0.2, 3}};
  int compared = 0, equal = 0;
  std::ostringstream gaps;
  for (const ScheduleCosts& c : costs) {
    for (int steps = 2; steps <= 7; ++steps) {
      for (int ram = 2; ram <= 3; ++ram) {
        for (int disk = 0; disk <= 3; ++disk) {
          const TwoLevelPlan plan = TwoLevelPlan::choose(steps, ram, disk, c);
          const double optimum = bruteForceOptimum(steps, ram, disk, c);
          const double planned = plan.counts().cost(c);
          EXPECT_GE(planned, optimum - 1e-12);
          ++compared;
          if (planned <= optimum + 1e-12) {
            ++equal;
          } else {
            gaps << "N=" << steps << " ram=" << ram << " disk=" << disk << " costs=" << c.text() << ": plan "
                 << planned << " optimum " << optimum << "; ";
          }
        }
      }
    }
  }
  ::testing::Test::RecordProperty("equal", std::to_string(equal) + " of " + std::to_string(compared));
  ::testing::Test::RecordProperty("gaps", gaps.str());
  EXPECT_EQ(equal, compared) << gaps.str();
}

TEST(TwoLevelPlan, ClosedFormCountsEqualTheScheduleRunWithoutStates) {
  struct Counter {
    TwoLevelPlan::Counts counts;
    std::int64_t forwardStores = 0;
    bool forward = true;
    void store(StorageLevel level, std::int64_t) {
      ++(level == StorageLevel::kRam ? counts.ramWrites : counts.diskWrites);
      if (forward) ++forwardStores;
    }
    void load(StorageLevel level, std::int64_t) {
      ++(level == StorageLevel::kRam ? counts.ramReads : counts.diskReads);
    }
    void advance(std::int64_t from, std::int64_t to) { counts.recomputedSteps += to - from; }
  };
  for (std::int64_t steps : {1, 2, 3, 7, 30, 101, 1000}) {
    for (std::int64_t ram : {2, 3, 5, 40}) {
      for (std::int64_t leaves : {1, 2, 3, 7, 64}) {
        for (bool replay : {false, true}) {
          if (leaves > steps) continue;
          const std::int64_t last =
              leaves == 1 ? steps : std::max<std::int64_t>(1, steps / leaves + (replay ? 1 : -1));
          if (steps - last < leaves - 1) continue;
          SCOPED_TRACE("N " + std::to_string(steps) + " ram " + std::to_string(ram) + " K " +
                       std::to_string(leaves) + (replay ? " replay" : ""));
          TwoLevelPlan plan = TwoLevelPlan::leaves(steps, ram, leaves, last, replay);
          Counter counter;
          std::vector<std::int64_t> produced;
          for (std::int64_t n = 0; n < steps; ++n) plan.recordForward(n, counter);
          counter.forward = false;
          for (std::int64_t e = steps - 1; e >= 0; --e) plan.restoreStep(e, counter);
          EXPECT_EQ(counter.counts.recomputedSteps, plan.counts().recomputedSteps);
          EXPECT_EQ(counter.counts.diskWrites, plan.counts().diskWrites);
          EXPECT_EQ(counter.counts.diskReads, plan.counts().diskReads);
          EXPECT_EQ(counter.counts.ramReads, plan.counts().ramReads);
          EXPECT_EQ(counter.forwardStores, plan.counts().statesStored);
        }
      }
    }
  }
}

// Every restore must produce exactly x_e: run the plan on integers (state = position).
TEST(TwoLevelPlan, EveryActionStreamProducesEachStateInTurnWithinItsSlots) {
  struct Replay {
    std::int64_t ramSlots, diskSlots;
    std::vector<std::int64_t> ram, disk;
    std::int64_t current = -1;
    bool ok = true;
    void store(StorageLevel level, std::int64_t slot) {
      auto& v = level == StorageLevel::kRam ? ram : disk;
      const std::int64_t limit = level == StorageLevel::kRam ? ramSlots : diskSlots;
      if (slot < 0 || slot >= limit)
        ok = false;
      else
        v[static_cast<std::size_t>(slot)] = current;
    }
    void load(StorageLevel level, std::int64_t slot) {
      const auto& v = level == StorageLevel::kRam ? ram : disk;
      current = v.at(static_cast<std::size_t>(slot));
    }
    void advance(std::int64_t from, std::int64_t to) {
      if (current != from) ok = false;
      current = to;
    }
  };
  for (std::int64_t steps : {1, 2, 5, 33, 400}) {
    for (std::int64_t ram : {1, 2, 4, 17}) {
      for (std::int64_t disk : {0, 1, 3, 50}) {
        for (const ScheduleCosts& c :
             {ScheduleCosts{1, 1, 0, 0}, ScheduleCosts{1, 1, 0.5, 0.5}, ScheduleCosts{1, 1, 50, 50}}) {
          if (steps >= 2 && ram + disk < 2) continue;
          SCOPED_TRACE("N " + std::to_string(steps) + " ram " + std::to_string(ram) + " disk " +
                       std::to_string(disk) + " costs " + c.text());
          TwoLevelPlan plan = TwoLevelPlan::choose(steps, ram, disk, c);
          ASSERT_LE(plan.ramSlotsUsed(), ram);
          ASSERT_LE(plan.diskSlotsUsed(), disk);
          Replay replay{plan.ramSlotsUsed(), plan.diskSlotsUsed(),
                        std::vector<std::int64_t>(static_cast<std::size_t>(plan.ramSlotsUsed()), -1),
                        std::vector<std::int64_t>(static_cast<std::size_t>(plan.diskSlotsUsed()), -1)};
          for (std::int64_t n = 0; n < steps; ++n) {
            replay.current = n;
            plan.recordForward(n, replay);
          }
          for (std::int64_t e = steps - 1; e >= 0; --e) {
            replay.current = -1;
            plan.restoreStep(e, replay);
            ASSERT_EQ(replay.current, e);
          }
          EXPECT_TRUE(replay.ok);
        }
      }
    }
  }
}

// The stack schedules' optimum by an independent top-down recursion (memoised), read from the game:
// a segment [p, e] with its first state held at `level` (RAM or disk), m RAM and d disk slots free
// besides it, and whether that state is at hand; the forward sweep at an unstored state. Each choice
// is enumerated directly (advance to e and produce it, or to p + j and keep that state at a level, or
// move the held state to the other level), unlike the bottom-up tables of TwoLevelPlan::dynamic.
class StackOptimum {
 public:
  StackOptimum(std::int64_t ram, std::int64_t disk, const ScheduleCosts& c) : ram_(ram), disk_(disk), c_(c) {}
  double game(std::int64_t steps) { return forward(steps, ram_, disk_); }

 private:
  double segment(std::int64_t l, int level, std::int64_t m, std::int64_t d, bool atHand,
                 bool allowMove = true) {
    const std::int64_t key =
        ((((l * 2 + level) * (ram_ + 1) + m) * (disk_ + 1) + d) * 2 + (atHand ? 1 : 0)) * 2 +
        (allowMove ? 1 : 0);
    if (auto it = memo_.find(key); it != memo_.end()) return it->second;
    double best = 0;
    if (!atHand) {
      best = (level == 1 ? c_.diskRead : 0.0) + segment(l, level, m, d, true);
    } else if (l >= 2) {
      best = (l - 1) * c_.forwardStep + segment(l - 1, level, m, d, false);
      for (std::int64_t j = 1; j + 1 < l; ++j) {
        const double after = j * c_.forwardStep + segment(j, level, m, d, false);
        if (m > 0) best = std::min(best, after + segment(l - j, 0, m - 1, d, true));
        if (d > 0) best = std::min(best, after + c_.diskWrite + segment(l - j, 1, m, d - 1, true));
      }
      // Moving the held state to the other level (moving it back would only add cost).
      if (allowMove) {
        if (level == 1 && m > 0) best = std::min(best, segment(l, 0, m - 1, d + 1, true, false));
        if (level == 0 && d > 0)
          best = std::min(best, c_.diskWrite + segment(l, 1, m + 1, d - 1, true, false));
      }
    }
    memo_[key] = best;
    return best;
  }
  double forward(std::int64_t l, std::int64_t m, std::int64_t d) {
    const std::int64_t key = -1 - ((l * (ram_ + 1) + m) * (disk_ + 1) + d);
    if (auto it = memo_.find(key); it != memo_.end()) return it->second;
    double best = std::numeric_limits<double>::infinity();
    for (int level = 0; level < 2; ++level) {
      const std::int64_t m2 = m - (level == 0), d2 = d - (level == 1);
      if (m2 < 0 || d2 < 0) continue;
      const double write = level == 1 ? c_.diskWrite : 0.0;
      best = std::min(best, write + segment(l, level, m2, d2, false));
      for (std::int64_t j = 1; j < l; ++j)
        best = std::min(best, write + forward(l - j, m2, d2) + segment(j, level, m2, d2, false));
    }
    memo_[key] = best;
    return best;
  }
  std::int64_t ram_, disk_;
  ScheduleCosts c_;
  std::map<std::int64_t, double> memo_;
};

TEST(TwoLevelPlan, DynamicProgrammeEqualsTheBruteForceOptimumOverAllSchedules) {
  // Every schedule of the game (not only stack schedules) for N <= 7: the dynamic programme is optimal.
  const ScheduleCosts costs[] = {{1, 1, 0, 0}, {1, 1, 0.5, 0.5}, {1, 1, 1, 1},
                                 {1, 1, 2, 3}, {1, 1, 0.2, 3},   {1, 1, 3, 0.2}};
  for (const ScheduleCosts& c : costs) {
    for (int steps = 1; steps <= 7; ++steps) {
      for (int ram = 1; ram <= 3; ++ram) {
        for (int disk = 0; disk <= 3; ++disk) {
          if (steps >= 2 && ram + disk < 2) continue;
          SCOPED_TRACE("N " + std::to_string(steps) + " ram " + std::to_string(ram) + " disk " +
                       std::to_string(disk) + " costs " + c.text());
          const TwoLevelPlan plan = TwoLevelPlan::dynamic(steps, ram, disk, c);
          const double optimum = bruteForceOptimum(steps, ram, disk, c);
          EXPECT_NEAR(plan.counts().cost(c), optimum, 1e-12);
          EXPECT_LE(TwoLevelPlan::lowerBound(steps, ram, disk, c), optimum + 1e-12);
          EXPECT_LE(plan.ramSlotsUsed(), ram);
          EXPECT_LE(plan.diskSlotsUsed(), disk);
        }
      }
    }
  }
}

TEST(TwoLevelPlan, DynamicProgrammeEqualsAnIndependentRecursionAndReusesDiskSlots) {
  for (const ScheduleCosts& c :
       {ScheduleCosts{1, 1, 0.5, 0.5}, ScheduleCosts{1, 1, 2, 1}, ScheduleCosts{1, 1, 0, 0}}) {
    for (std::int64_t steps : {20, 45, 80}) {
      for (const auto& [ram, disk] : {std::pair<std::int64_t, std::int64_t>{2, 1}, {3, 4}, {4, 2}, {1, 3}}) {
        SCOPED_TRACE("N " + std::to_string(steps) + " ram " + std::to_string(ram) + " disk " +
                     std::to_string(disk) + " costs " + c.text());
        StackOptimum reference(ram, disk, c);
        const TwoLevelPlan plan = TwoLevelPlan::dynamic(steps, ram, disk, c);
        // The simulated run costs what the recursion says is optimal.
        EXPECT_NEAR(plan.counts().cost(c), reference.game(steps), 1e-9);
        // choose() never returns a dearer plan.
        EXPECT_LE(TwoLevelPlan::choose(steps, ram, disk, c).counts().cost(c), plan.counts().cost(c) + 1e-9);
      }
    }
  }
  // Herrmann & Pallez's example size: N = 1000, 6 RAM and 20 disk states, uf : ub : wd : rd = 1:1:0.5:0.5.
  // Write-once disk checkpoints (the leaves) cost 2184; H-Revolve's optimum is 1843.
  const ScheduleCosts half{1, 1, 0.5, 0.5};
  const TwoLevelPlan plan = TwoLevelPlan::choose(1000, 6, 20, half);
  EXPECT_EQ(plan.kind(), TwoLevelPlan::Kind::kDynamic);
  EXPECT_LE(plan.counts().cost(half), 1843.0);
  EXPECT_GT(plan.counts().diskWrites, plan.diskSlotsUsed()) << "disk slots are reused";
  std::cout << "[ two-level ] N = 1000, 6 RAM, 20 disk, 1:1:0.5:0.5: cost " << plan.counts().cost(half)
            << " (" << plan.describe() << "), recomputed " << plan.counts().recomputedSteps
            << ", disk writes " << plan.counts().diskWrites << ", reads " << plan.counts().diskReads << '\n';
}

int interruptPolls = 0;
void interruptAfterTenPolls() {
  if (++interruptPolls > 10) throw std::runtime_error("interrupted");
}

TEST(TwoLevelPlan, PlanningPollsTheInterrupt) {
  // The dynamic programme polls once per segment length, the closed-form search per last-leaf length and
  // the stateless count every 2^16 steps: a poll that throws ends each of them.
  struct Restore {
    ~Restore() { setInterruptPoll(nullptr); }
  } restore;
  const ScheduleCosts half{1, 1, 0.5, 0.5};
  for (const auto& [steps, ram, disk] : {std::tuple<std::int64_t, std::int64_t, std::int64_t>{1000, 6, 20},
                                         {1'000'000, 10, 1000},
                                         {4'000'000, 1, 3}}) {
    SCOPED_TRACE("N " + std::to_string(steps));
    interruptPolls = 0;
    setInterruptPoll(&interruptAfterTenPolls);
    EXPECT_THROW(TwoLevelPlan::choose(steps, ram, disk, half), std::runtime_error);
    setInterruptPoll(nullptr);
    EXPECT_GT(interruptPolls, 10);
  }
}

TEST(TwoLevelPlan, ExpensiveDiskKeepsToRamAndCheapDiskIsUsed) {
  // 1000 steps, 10 RAM states, 1000 disk states: a disk as dear as 1000 forward steps is not worth it.
  const TwoLevelPlan dear = TwoLevelPlan::choose(1000, 10, 1000, ScheduleCosts{1, 1, 1000, 1000});
  EXPECT_EQ(dear.diskSlotsUsed(), 0);
  const TwoLevelPlan cheap = TwoLevelPlan::choose(1000, 10, 1000, ScheduleCosts{1, 1, 0.01, 0.01});
  EXPECT_GT(cheap.diskSlotsUsed(), 0);
  EXPECT_LT(cheap.counts().recomputedSteps, dear.counts().recomputedSteps);
}

TEST(SchedulePrediction, HandlesABillionStepsInClosedForm) {
  const ScheduleCosts costs{1e-4, 2e-4, 1e-5, 1e-5};
  const std::int64_t n = 1'000'000'000;
  const SchedulePrediction binomial = predictSchedule("binomial:checkpoints=100", n, 8000, 4, nullptr);
  EXPECT_EQ(binomial.recomputedSteps,
            static_cast<std::int64_t>(revolve::workingStateRecomputedSteps(n, 101)));
  EXPECT_EQ(binomial.rhsEvaluations, 4 * (2 * n + binomial.recomputedSteps));
  const SchedulePrediction multilevel = predictSchedule("multilevel:ram=64MiB,disk=1TiB", n, 8000, 4, &costs);
  EXPECT_GT(multilevel.diskWrites, 0);
  EXPECT_GT(multilevel.recomputedSteps, 0);
  EXPECT_LE(multilevel.peakRamBytes, std::int64_t{64} << 20);
  const SchedulePrediction disk = predictSchedule("disk:dir=/tmp", n, 8000, 4, nullptr);
  EXPECT_EQ(disk.diskWrites, n + 1);
}

TEST(SchedulePrediction, BadInputNamesTheFlagOrField) {
  const ScheduleCosts costs;
  const auto message = [&](const std::string& spec, std::int64_t steps, std::int64_t bytes, int stages) {
    try {
      predictSchedule(spec, steps, bytes, stages, &costs);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("full", 0, 16, 4).find("--steps"), std::string::npos);
  EXPECT_NE(message("full", 10, 12, 4).find("--state-bytes"), std::string::npos);
  EXPECT_NE(message("full", 10, 16, 0).find("--stages"), std::string::npos);
  EXPECT_NE(message("hermite:every=4", 10, 16, 4).find("not predicted"), std::string::npos);
  EXPECT_NE(message("online:checkpoints=5,budget=40", 10, 16, 4).find("online.budget"), std::string::npos);
  EXPECT_NE(message("binomial", 10, 16, 4).find("binomial.checkpoints"), std::string::npos);
  // The stride is predicted by walking it, up to 2^24 steps.
  EXPECT_EQ(message("multilevel:ram=1MiB,disk=1MiB,schedule=stride", 10, 16, 4), "no error");
  EXPECT_NE(message("multilevel:ram=1MiB,disk=1MiB,schedule=stride", (std::int64_t{1} << 24) + 1, 16, 4)
                .find("multilevel.schedule = stride is predicted up to --steps"),
            std::string::npos);
  EXPECT_THROW(ScheduleCosts::parse("1:2:3", "--costs"), std::invalid_argument);
  EXPECT_THROW(ScheduleCosts::parse("1:2:3:-4", "--costs"), std::invalid_argument);
  EXPECT_THROW(ScheduleCosts::parse("0:2:3:4", "--costs"), std::invalid_argument);
  EXPECT_THROW(ScheduleCosts::parse("1:2:3:4:5", "--costs"), std::invalid_argument);
  EXPECT_THROW(ScheduleCosts::parse("1:x:3:4", "--costs"), std::invalid_argument);
  const ScheduleCosts parsed = ScheduleCosts::parse("1e-4:2e-4:3e-5:0", "--costs");
  EXPECT_EQ(parsed.forwardStep, 1e-4);
  EXPECT_EQ(parsed.diskRead, 0.0);
  EXPECT_THROW(createStorage("multilevel:ram=1MiB,disk=1MiB,schedule=fast"), std::invalid_argument);
  EXPECT_THROW(createStorage("multilevel:ram=1MiB,disk=1MiB,costs=1:2"), std::invalid_argument);
}

// Runs `spec` on the pendulum (rk4, fixed steps, 16-byte states, 16 bytes of rhs data per stage: the
// acceleration and the 1 x 1 Cholesky factor of a SecondOrderProblem), checks its gradient against
// `reference` bit for bit and every counter a prediction shares with a run against the run's; returns the
// prediction and the storage for the checks of one strategy.
struct PredictedRun {
  SchedulePrediction prediction;
  std::unique_ptr<TrajectoryStorage> storage;
};
PredictedRun expectPredictionEqualsRun(const std::string& spec, const IntegratorOptions& options,
                                       const GradientResult& reference, const ScheduleCosts& costs) {
  Pendulum problem;
  auto storage = createStorage(spec);
  storage->setVerifyRestores(true);  // states and restored stage values hash-verified
  const GradientResult result = computeGradient(problem, pendulumParameters(), options, *storage);
  EXPECT_TRUE(bitwiseEqual(result, reference));
  const SchedulePrediction p =
      predictSchedule(spec, reference.summary.steps, 16, 4, &costs, 8 * problem.rhsDataSize());
  EXPECT_EQ(p.recomputedSteps, result.summary.recomputedSteps) << p.plan;
  EXPECT_EQ(p.statesStored, storage->counters().statesStored) << p.plan;
  EXPECT_EQ(p.peakRamBytes, storage->counters().peakBytesInMemory) << p.plan;
  EXPECT_EQ(p.rhsEvaluations, result.summary.rhsEvaluations) << p.plan;
  EXPECT_EQ(p.stepDataStored, storage->counters().stepDataStored) << p.plan;
  EXPECT_EQ(p.stepDataRestored, storage->counters().stepDataRestored) << p.plan;
  return {p, std::move(storage)};
}

// expectPredictionEqualsRun for a multilevel spec whose plan is H-Revolve's hierarchical one: the disk's
// writes and reads and the plan's cost against the run's as well. `storage` is the run's multilevel
// storage (null, with the failure recorded, if the spec made none).
struct HierarchicalRun {
  PredictedRun run;
  const MultilevelStorage* storage;
};
HierarchicalRun expectHierarchicalPredictionEqualsRun(const std::string& spec,
                                                      const IntegratorOptions& options,
                                                      const GradientResult& reference,
                                                      const ScheduleCosts& costs) {
  PredictedRun run = expectPredictionEqualsRun(spec, options, reference, costs);
  const auto* multilevel = dynamic_cast<const MultilevelStorage*>(run.storage.get());
  EXPECT_NE(multilevel, nullptr) << spec;
  if (multilevel != nullptr) {
    const SchedulePrediction& p = run.prediction;
    EXPECT_EQ(multilevel->plan().kind(), TwoLevelPlan::Kind::kHierarchical) << p.plan;
    EXPECT_EQ(p.diskWrites, multilevel->diskWrites());
    EXPECT_EQ(p.diskReads, multilevel->diskReads());
    EXPECT_DOUBLE_EQ(p.scheduleCost, multilevel->predictedSeconds());
  }
  return {std::move(run), multilevel};
}

// expectHierarchicalPredictionEqualsRun on the pendulum at 2000 * stepDivisor rk4 steps (fixedStepRk4's step
// divided; 4: 8000 steps, beyond the graded grid's exact lengths), `spec` in a scratch folder that the run
// leaves empty; the plan's description names `planNote`.
HierarchicalRun expectLongPendulumRunEqualsPrediction(const std::string& spec, const ScheduleCosts& costs,
                                                      const std::string& planNote, int stepDivisor = 4) {
  Pendulum problem;
  IntegratorOptions options = fixedStepRk4();
  options.step /= stepDivisor;
  const GradientResult reference = fullReference(problem, pendulumParameters(), options);
  EXPECT_EQ(reference.summary.steps, 2000 * stepDivisor);
  ScratchDirectory dir;
  HierarchicalRun run =
      expectHierarchicalPredictionEqualsRun(spec + ",dir=" + dir.path(), options, reference, costs);
  EXPECT_NE(run.run.prediction.plan.find(planNote), std::string::npos) << run.run.prediction.plan;
  EXPECT_EQ(dir.entryCount(), 0u);
  return run;
}

// The prediction against a real run of the pendulum (rk4, N = 2000 fixed steps, 16-byte states).
TEST(SchedulePrediction, AgreesExactlyWithRealRuns) {
  Pendulum problem;
  const IntegratorOptions options = fixedStepRk4();
  const GradientResult reference = fullReference(problem, pendulumParameters(), options);
  const std::int64_t steps = reference.summary.steps;
  ASSERT_EQ(steps, 2000);
  ScratchDirectory dir;
  const ScheduleCosts costs{1.0, 1.0, 0.5, 0.5};
  const std::vector<std::string> specs = {
      "full",
      "binomial:checkpoints=10",
      "binomial:checkpoints=3000",
      "disk:dir=" + dir.path(),
      "multilevel:ram=400,disk=1MiB,costs=1:1:0.5:0.5,dir=" + dir.path(),  // 25 RAM states, cheap disk
      "multilevel:ram=400,disk=1MiB,costs=1:1:0:0,dir=" + dir.path(),      // free disk: revolve over all
      "multilevel:ram=400,disk=320,costs=1:1:0:0,dir=" + dir.path(),       // 25 + 20 slots
      "multilevel:ram=800,disk=1MiB,costs=1:1:100:100,dir=" + dir.path(),  // dear disk: RAM only
      "multilevel:ram=64KiB,disk=1MiB,costs=1:1:1:1,dir=" + dir.path(),    // everything fits in RAM
      "cams:checkpoints=10",                                               // states and rk4 step records
      "cams:budget=640",                                                   // 40 state units
      "cams:checkpoints=10,online=1",                                      // online placement
      "full:stages=1",                                                     // every step's stages
      "disk:dir=" + dir.path() + ",chunk=64,stages=1",
      "disk:dir=" + dir.path() + ",stages=1",
  };
  for (const std::string& spec : specs) {
    SCOPED_TRACE(spec);
    const auto [p, storage] = expectPredictionEqualsRun(spec, options, reference, costs);
    if (spec.rfind("disk", 0) == 0) EXPECT_EQ(p.peakDiskBytes, storage->counters().uncompressedBytes);
    if (auto* multilevel = dynamic_cast<MultilevelStorage*>(storage.get())) {
      EXPECT_TRUE(multilevel->usesPlan());
      EXPECT_EQ(p.diskWrites, multilevel->diskWrites()) << p.plan;
      EXPECT_EQ(p.diskReads, multilevel->diskReads()) << p.plan;
      EXPECT_EQ(p.peakDiskBytes, multilevel->plan().diskSlotsUsed() * 16);
      EXPECT_DOUBLE_EQ(p.scheduleCost, multilevel->predictedSeconds());
      ::testing::Test::RecordProperty(spec, p.plan);
    }
  }
}

// multilevel's stride, predicted by running its own placement and scratch rounds in counting mode, against
// real runs: kept states in RAM and on disk, and RAM alone with scratch rounds.
TEST(SchedulePrediction, MultilevelStrideAgreesExactlyWithRealRuns) {
  Pendulum problem;
  const IntegratorOptions options = fixedStepRk4();
  const GradientResult reference = fullReference(problem, pendulumParameters(), options);
  ASSERT_EQ(reference.summary.steps, 2000);
  ScratchDirectory dir;
  const ScheduleCosts costs{1.0, 1.0, 0.5, 0.5};
  bool onDisk = false, rounds = false;
  for (const std::string& spec : {
           "multilevel:ram=1KiB,disk=4KiB,schedule=stride,dir=" + dir.path(),
           "multilevel:ram=160,disk=1MiB,schedule=stride,dir=" + dir.path(),
           "multilevel:ram=96,disk=16,schedule=stride,dir=" + dir.path(),
       }) {
    SCOPED_TRACE(spec);
    const auto [p, storage] = expectPredictionEqualsRun(spec, options, reference, costs);
    auto* multilevel = dynamic_cast<MultilevelStorage*>(storage.get());
    ASSERT_NE(multilevel, nullptr);
    EXPECT_FALSE(multilevel->usesPlan());
    EXPECT_EQ(p.diskWrites, multilevel->diskWrites()) << p.plan;
    EXPECT_EQ(p.diskReads, multilevel->diskReads()) << p.plan;
    EXPECT_EQ(p.peakDiskBytes, storage->counters().uncompressedBytes) << p.plan;
    EXPECT_EQ(p.diskWrites, multilevel->statesOnDisk()) << p.plan;
    onDisk = onDisk || multilevel->statesOnDisk() > 0;
    // Rounds: more recomputed steps than one pass over each segment between kept states.
    rounds = rounds || p.recomputedSteps > reference.summary.steps;
  }
  EXPECT_TRUE(onDisk);
  EXPECT_TRUE(rounds);
}

// Beyond the dynamic programme's limit (N^2 (R + 1)(D + 1) > 2^28) the hierarchical programme plans: the
// issue-size case of 4 RAM and 40 disk states at N = 3000 and costs 1:1:0.5:0.5 costs 5 762 (the closed-form
// families 7 351; H-Revolve 5 806), and on the pendulum (N = 2000) its prediction equals the run counter by
// counter with a bitwise gradient.
TEST(SchedulePrediction, HierarchicalPlanBeyondTheDynamicProgrammeEqualsItsRun) {
  const ScheduleCosts half{1, 1, 0.5, 0.5};
  ASSERT_FALSE(TwoLevelPlan::dynamicAffordable(3000, 4, 40));
  const TwoLevelPlan large = TwoLevelPlan::choose(3000, 4, 40, half);
  EXPECT_EQ(large.kind(), TwoLevelPlan::Kind::kHierarchical);
  EXPECT_DOUBLE_EQ(large.counts().cost(half), 5762.0);
  const TwoLevelPlan families = TwoLevelPlan::allSlots(3000, 4, 40, true);
  EXPECT_DOUBLE_EQ(families.counts().cost(half), 7351.0);
  Pendulum problem;
  const IntegratorOptions options = fixedStepRk4();
  const GradientResult reference = fullReference(problem, pendulumParameters(), options);
  ASSERT_FALSE(TwoLevelPlan::dynamicAffordable(reference.summary.steps, 4, 40));
  ScratchDirectory dir;
  const HierarchicalRun run = expectHierarchicalPredictionEqualsRun(
      "multilevel:ram=64,disk=640,costs=1:1:0.5:0.5,dir=" + dir.path(), options, reference, half);
  ASSERT_NE(run.storage, nullptr);
  EXPECT_LE(run.storage->plan().diskSlotsUsed(), 40);
  EXPECT_EQ(dir.entryCount(), 0u);
}

// Where the disk holds a state per leaf of RAM's length, leaves reach the game's lower bound: optimal, and
// choose() stops there (the action stream's spec: 20 RAM and 131 072 disk states at N = 10^6 costs
// N - 20); the bound is below every schedule's cost (the brute force above).
TEST(TwoLevelPlan, LeavesAtTheLowerBoundAreOptimalAndEndTheSearch) {
  const ScheduleCosts half{1, 1, 0.5, 0.5};
  const TwoLevelPlan plan = TwoLevelPlan::choose(1000000, 20, 131072, half);
  EXPECT_EQ(plan.kind(), TwoLevelPlan::Kind::kLeaves) << plan.describe();
  EXPECT_DOUBLE_EQ(plan.counts().cost(half), 999980.0);
  EXPECT_DOUBLE_EQ(TwoLevelPlan::lowerBound(1000000, 20, 131072, half), 999980.0);
  // Dear disk: the bound is revolve's N - R, reached by nothing once N exceeds the slots.
  const ScheduleCosts dear{1, 1, 2, 2};
  EXPECT_DOUBLE_EQ(TwoLevelPlan::lowerBound(100, 4, 50, dear), 96.0);
  EXPECT_GT(TwoLevelPlan::choose(100, 4, 50, dear).counts().cost(dear), 96.0);
}

// Beyond the old limits of the exact tables (N (R + D + 2) > 2^20) the two-level plan is KLevelPlan's
// graded programme: the rod's 6000 steps with 2 RAM and 204 disk states at 1:1:2:2 cost 16 352 (12 308
// recomputed steps) where the families cost 25 568 (24 752), equal to the hierarchical programme over every
// length (the reference, 1 s); at N = 10^5 and 10^6 with 8 RAM and 40 disk states at 1:1:0.5:0.5 never
// above the families either (289 814 and 3 836 760 against 334 259 and 4 177 889.5; the windowed
// reference at 10^5, 6 min, also 289 814: docs/theory/storage.md). On the pendulum (N = 8000, beyond the
// grid's 4096 exact lengths) the prediction equals the run counter by counter with a bitwise gradient.
TEST(SchedulePrediction, GradedTwoLevelPlanBeyondTheTablesIsWithinOnePercentAndEqualsItsRun) {
  const ScheduleCosts rod{1, 1, 2, 2};
  const TwoLevelPlan plan = TwoLevelPlan::choose(6000, 2, 204, rod);
  EXPECT_EQ(plan.kind(), TwoLevelPlan::Kind::kHierarchical) << plan.describe();
  EXPECT_NE(plan.describe().find("geometric grid"), std::string::npos) << plan.describe();
  const double reference =
      KLevelPlan::hierarchical(6000, 2, {StorageLevelCosts{204, 2, 2}}, 1.0, KLevelPlan::kGradedWindow)
          .counts()
          .cost;
  EXPECT_LE(plan.counts().cost(rod), 1.01 * reference);
  const TwoLevelPlan families = TwoLevelPlan::families(6000, 2, 204, rod);
  EXPECT_DOUBLE_EQ(families.counts().cost(rod), 25568.0);
  EXPECT_LT(plan.counts().cost(rod), 0.7 * families.counts().cost(rod));
  const ScheduleCosts half{1, 1, 0.5, 0.5};
  for (std::int64_t steps : {100000, 1000000}) {
    const TwoLevelPlan large = TwoLevelPlan::choose(steps, 8, 40, half);
    EXPECT_EQ(large.kind(), TwoLevelPlan::Kind::kHierarchical) << large.describe();
    EXPECT_LT(large.counts().cost(half),
              0.95 * TwoLevelPlan::families(steps, 8, 40, half).counts().cost(half));
    EXPECT_LE(large.ramSlotsUsed(), 8);
    EXPECT_LE(large.diskSlotsUsed(), 40);
  }
  expectLongPendulumRunEqualsPrediction("multilevel:ram=64,disk=640,costs=1:1:0.5:0.5", half,
                                        "geometric grid");
}

// Disks of many slots (R + D + 2 > 256, the families' case before): the graded plan with every slot, at
// N = 10^4 with 2 RAM and 300 disk states at 1:1:2:2 27 584 against the families' 45 888, at N = 10^6 with
// 8 RAM and 1000 disk states 2 311 158 (the segments; the coarse grid 2 312 908) against 4 287 004 (planned
// in 4 s; docs/theory/storage.md, "Large disks"); on the pendulum (N = 8000, 2 RAM and 600 disk states: a
// coarser grid of lengths holds every slot) the prediction equals the run counter by counter with a bitwise
// gradient.
TEST(SchedulePrediction, LargeDisksPlanWithEverySlotAndEqualTheirRun) {
  const ScheduleCosts dear{1, 1, 2, 2};
  const TwoLevelPlan plan = TwoLevelPlan::choose(10000, 2, 300, dear);
  EXPECT_EQ(plan.kind(), TwoLevelPlan::Kind::kHierarchical) << plan.describe();
  EXPECT_EQ(plan.diskSlotsUsed(), 300);
  EXPECT_LT(plan.counts().cost(dear), 0.65 * TwoLevelPlan::families(10000, 2, 300, dear).counts().cost(dear));
  const TwoLevelPlan large = TwoLevelPlan::choose(1000000, 8, 1000, dear);
  EXPECT_EQ(large.kind(), TwoLevelPlan::Kind::kHierarchical) << large.describe();
  EXPECT_EQ(large.diskSlotsUsed(), 1000);
  EXPECT_LT(large.counts().cost(dear),
            0.6 * TwoLevelPlan::families(1000000, 8, 1000, dear).counts().cost(dear));
  const HierarchicalRun run = expectLongPendulumRunEqualsPrediction(
      "multilevel:ram=32,disk=9600,costs=1:1:2:2", dear, "lengths beyond 1024");
  ASSERT_NE(run.storage, nullptr);
  EXPECT_EQ(run.storage->plan().diskSlotsUsed(), 600) << run.run.prediction.plan;
  // The plan's synchronous part (scheduleCost is net of the overlapped I/O): the graded plan on the finest
  // grid with every slot costs the same.
  EXPECT_DOUBLE_EQ(run.storage->plan().counts().cost(dear), 19184.0);
}

// A disk of more slots than any grid's tables hold (N = 500 000, 2 RAM and 80 000 disk states of 16 bytes at
// 1:1:2:2; the coarsest grid holds 56 676 disk slots at this N): the segmented plan (79 546 forward stores
// 6-7 steps apart, each segment reversed with both RAM slots while its first state stays on disk, and a tail
// of 4095 steps) costs 1 019 076 where the families' leaves cost 1 019 984 and the grid with its slots capped
// 1 091 607 (what KLevelPlan::choose returned before; docs/theory/storage.md, "Large disks"); on the pendulum
// the prediction equals the run counter by counter with a bitwise gradient.
TEST(SchedulePrediction, SegmentedPlanOnAHugeDiskEqualsItsRun) {
  const ScheduleCosts dear{1, 1, 2, 2};
  EXPECT_DOUBLE_EQ(TwoLevelPlan::families(500000, 2, 80000, dear).counts().cost(dear), 1019984.0);
  const HierarchicalRun run = expectLongPendulumRunEqualsPrediction(
      "multilevel:ram=32,disk=1280000,costs=1:1:2:2", dear, "segmented", 250);
  ASSERT_NE(run.storage, nullptr);
  EXPECT_DOUBLE_EQ(run.storage->plan().counts().cost(dear), 1019076.0) << run.run.prediction.plan;
  EXPECT_EQ(run.storage->plan().diskSlotsUsed(), 80000) << run.run.prediction.plan;
}

// Three levels from the spec's levels= (the RAM 3, SSD 10, HDD 200 states with 16-byte states, and a
// dearer hierarchy): the prediction equals the run on the pendulum (N = 2000) counter by counter, each
// level's writes and reads too, with a bitwise gradient; with measured costs the run is exact too; the
// level subfolders the runs make are removed.
TEST(SchedulePrediction, ThreeLevelPlanEqualsItsRun) {
  Pendulum problem;
  const IntegratorOptions options = fixedStepRk4();
  const GradientResult reference = fullReference(problem, pendulumParameters(), options);
  ScratchDirectory dir;
  const ScheduleCosts costs{1, 1, 0, 0};
  for (const std::string& levels : std::vector<std::string>{
           "ssd:160@1:1;hdd:3200@2:2", "ssd:48@0.5:1;hdd:640:" + dir.path() + "/h@3:3"}) {
    const std::string spec = "multilevel:ram=48,levels=" + levels + ",costs=1:1,dir=" + dir.path();
    SCOPED_TRACE(spec);
    const auto [p, storage] = expectPredictionEqualsRun(spec, options, reference, costs);
    auto* multilevel = dynamic_cast<MultilevelStorage*>(storage.get());
    ASSERT_NE(multilevel, nullptr);
    ASSERT_NE(multilevel->levelPlan(), nullptr);
    ASSERT_EQ(p.levels.size(), 2u);
    for (std::size_t k = 0; k < 2; ++k) {
      EXPECT_EQ(p.levels[k].writes, multilevel->levelWrites()[k]) << p.plan;
      EXPECT_EQ(p.levels[k].reads, multilevel->levelReads()[k]) << p.plan;
      EXPECT_GT(p.levels[k].writes, 0) << p.plan;
    }
    EXPECT_EQ(p.diskWrites, multilevel->diskWrites());
    EXPECT_EQ(p.diskReads, multilevel->diskReads());
    EXPECT_DOUBLE_EQ(p.scheduleCost, multilevel->predictedSeconds());
    EXPECT_DOUBLE_EQ(p.scheduleCost, multilevel->levelPlan()->optimum());
    ::testing::Test::RecordProperty(spec, p.plan);
  }
  {
    auto storage = createStorage("multilevel:ram=48,levels=ssd:160;hdd:3200,dir=" + dir.path());
    const GradientResult result = computeGradient(problem, pendulumParameters(), options, *storage);
    EXPECT_TRUE(bitwiseEqual(result, reference));
    auto* multilevel = dynamic_cast<MultilevelStorage*>(storage.get());
    ASSERT_NE(multilevel->levelPlan(), nullptr);
    EXPECT_GT(multilevel->costs().forwardStep, 0.0);
  }
  std::filesystem::remove(dir.path() + "/h");  // the given directory stays; the default subfolders do not
  EXPECT_EQ(dir.entryCount(), 0u);
}

// levels= with one level is the two-level form: the same plan and counts as disk= with its costs.
TEST(SchedulePrediction, OneLevelBelowRamIsTheTwoLevelForm) {
  for (std::int64_t steps : {10, 500, 3000}) {
    const SchedulePrediction levels =
        predictSchedule("multilevel:ram=64,levels=disk:640@0.5:0.5,costs=1:1", steps, 16, 4, nullptr);
    const SchedulePrediction disk =
        predictSchedule("multilevel:ram=64,disk=640,costs=1:1:0.5:0.5", steps, 16, 4, nullptr);
    EXPECT_EQ(levels.plan, disk.plan);
    EXPECT_EQ(levels.recomputedSteps, disk.recomputedSteps);
    EXPECT_EQ(levels.diskWrites, disk.diskWrites);
    EXPECT_EQ(levels.diskReads, disk.diskReads);
    EXPECT_EQ(levels.scheduleCost, disk.scheduleCost);
    EXPECT_TRUE(levels.levels.empty());
  }
}

TEST(SchedulePrediction, LevelsSpecRoundTripsAndBadLevelsNameTheField) {
  EXPECT_EQ(
      createStorage("multilevel:ram=1KiB,levels=ssd:1MiB@1:1;hdd:1GiB:/mnt/h@2:2.5,costs=1:0.5")->spec(),
      "multilevel:ram=1024,levels=ssd:1048576@1:1;hdd:1073741824:/mnt/h@2:2.5,costs=1:0.5");
  EXPECT_EQ(createStorage("multilevel:ram=1KiB,levels=ssd:1MiB;hdd:1GiB,dir=/tmp/x")->spec(),
            "multilevel:ram=1024,levels=ssd:1048576;hdd:1073741824,dir=/tmp/x");
  const auto message = [](const std::string& spec) {
    try {
      createStorage(spec);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("multilevel:ram=1KiB,levels=ssd:1MiB,disk=1MiB").find("not both"), std::string::npos);
  EXPECT_NE(message("multilevel:levels=ssd:1MiB").find("ram="), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=ssd").find("NAME:BYTES"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=ram:1MiB").find("not 'ram'"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1MiB;a:2MiB").find("twice"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:0;b:2MiB").find("multilevel.levels.a"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1x").find("multilevel.levels.a"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1MiB@1").find("WRITE:READ"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1MiB@1:-2,costs=1:1").find("WRITE:READ"),
            std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1MiB@1:1;b:1MiB,costs=1:1").find("1 of 2"),
            std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1MiB@1:1").find("costs= is missing"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1MiB@1:1,costs=1:1:1:1").find("uf:ub"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1MiB@1:1,costs=0:1").find("uf > 0"), std::string::npos);
  EXPECT_NE(message("multilevel:ram=1KiB,levels=a:1MiB;b:1MiB,costs=1:1").find("@WRITE:READ"),
            std::string::npos);
  // A prediction of measured K-level costs cannot take --costs (four numbers, two levels); --actions is
  // refused.
  const ScheduleCosts costs{1, 1, 1, 1};
  const auto predicted = [&](const std::string& spec, std::int64_t steps) {
    try {
      predictSchedule(spec, steps, 16, 4, &costs);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(predicted("multilevel:ram=48,levels=a:160;b:320", 100).find("costs=uf:ub"), std::string::npos);
  EXPECT_NE(predicted("multilevel:ram=8,levels=a:8@1:1;b:8@1:1,costs=1:1", 100).find("multilevel.levels"),
            std::string::npos);
  EXPECT_NE(predicted("multilevel:ram=48,levels=a:160@1:1;b:320@2:2,costs=1:1", 100'000'000).find("2^24"),
            std::string::npos);
  std::ostringstream out;
  EXPECT_THROW(
      writeScheduleActions("multilevel:ram=48,levels=a:160@1:1;b:320@2:2,costs=1:1", 10, 16, 4, nullptr, out),
      std::invalid_argument);
}

// The trap that was: a RAM of fewer than 3 states without costs= used to take the stride, and the
// prediction with --costs counted that stride while costs= in the spec counted the plan (187 250 against
// 3 897 recomputed steps for the numbers of docs/theory/storage.md, "No silent trap"). Now --costs stands
// for the costs a run measures, and with either the same plan is counted.
TEST(SchedulePrediction, CostsFlagMeansWhatCostsInTheSpecMeans) {
  const ScheduleCosts costs{1, 1, 2, 2};
  for (const std::int64_t ram : {16, 32, 48, 400}) {
    for (const std::int64_t steps : {2, 50, 3000}) {
      SCOPED_TRACE("ram " + std::to_string(ram) + ", N " + std::to_string(steps));
      const std::string levels = "multilevel:ram=" + std::to_string(ram) + ",disk=64KiB";
      const SchedulePrediction flag = predictSchedule(levels, steps, 16, 4, &costs);
      const SchedulePrediction spec = predictSchedule(levels + ",costs=1:1:2:2", steps, 16, 4, nullptr);
      EXPECT_EQ(flag.plan, spec.plan);
      EXPECT_EQ(flag.recomputedSteps, spec.recomputedSteps);
      EXPECT_EQ(flag.diskWrites, spec.diskWrites);
      EXPECT_EQ(flag.diskReads, spec.diskReads);
      EXPECT_EQ(flag.scheduleCost, spec.scheduleCost);
      EXPECT_TRUE(flag.warning.empty()) << flag.warning;
    }
  }
}

// With nothing to choose (one step, or a disk smaller than one state) a run plans by 1:1:0:0 and needs no
// costs; its action stream did not either, and dereferenced the missing --costs.
TEST(SchedulePrediction, ActionsWithNothingToChooseNeedNoCosts) {
  for (const auto& [spec, steps] : {std::pair<std::string, std::int64_t>{"multilevel:ram=512,disk=4KiB", 1},
                                    std::pair<std::string, std::int64_t>{"multilevel:ram=512,disk=4", 10}}) {
    SCOPED_TRACE(spec);
    std::ostringstream out;
    writeScheduleActions(spec, steps, 8, 4, nullptr, out);
    EXPECT_NE(out.str().find("restore 0\n"), std::string::npos) << out.str();
    EXPECT_EQ(out.str().find("disk"), std::string::npos) << out.str();
  }
  std::ostringstream out;
  EXPECT_THROW(writeScheduleActions("multilevel:ram=512,disk=4KiB", 10, 8, 4, nullptr, out),
               std::invalid_argument);
  EXPECT_TRUE(out.str().empty());
}

// A stride more than twice as dear as the plan the same levels allow says so and names the plan; a stride
// within the factor does not.
TEST(SchedulePrediction, StrideFarAboveThePlanWarnsAndNamesIt) {
  const ScheduleCosts costs{1, 1, 2, 2};
  const SchedulePrediction trap =
      predictSchedule("multilevel:ram=32,disk=64KiB,schedule=stride", 3000, 16, 4, &costs);
  const SchedulePrediction plan = predictSchedule("multilevel:ram=32,disk=64KiB", 3000, 16, 4, &costs);
  ASSERT_GT(trap.scheduleCost, MultilevelStorage::kTrapFactor * plan.scheduleCost);
  EXPECT_NE(trap.warning.find("schedule=optimal"), std::string::npos) << trap.warning;
  EXPECT_NE(trap.warning.find(std::to_string(plan.recomputedSteps) + " recomputed steps"), std::string::npos)
      << trap.warning;
  // Everything in RAM: the stride is k = 1, nothing recomputed, nothing to warn about.
  const SchedulePrediction fits =
      predictSchedule("multilevel:ram=64KiB,disk=64KiB,schedule=stride", 3000, 16, 4, &costs);
  EXPECT_EQ(fits.recomputedSteps, 0);
  EXPECT_TRUE(fits.warning.empty()) << fits.warning;
}

// revolve's checkpoint writes in closed form (binomial's ram_writes, and with stages=1 the adjoint steps
// that find their stages) against the schedule run step by step without states.
TEST(SchedulePrediction, BinomialWritesInClosedFormEqualTheScheduleRun) {
  const auto check = [](std::int64_t steps, std::int64_t c) {
    const SchedulePrediction p =
        predictSchedule("binomial:checkpoints=" + std::to_string(c), steps, 16, 4, nullptr);
    // A run of computeGradient: revolve with slotsFor(N, C, true) slots over positions 0..N-1, x_{N-1}
    // the working state.
    const std::int64_t slots = BinomialCheckpointing::slotsFor(steps, c, true);
    const ScheduleCounts counts = revolve::simulateSchedule(steps, slots);
    EXPECT_EQ(p.ramWrites, counts.checkpointWrites) << "N " << steps << " c " << c;
    EXPECT_EQ(revolve::toString(counts.recomputedSteps), std::to_string(p.recomputedSteps))
        << "N " << steps << " c " << c;
    BinomialSchedule schedule;  // the first sweep's pushes (statesStored, and stepDataStored with stages=1)
    schedule.reset(steps, slots, true);
    std::int64_t pushes = 0;
    for (std::int64_t n = 1; n < steps; ++n) pushes += schedule.recordForward(n) >= 0 ? 1 : 0;
    EXPECT_EQ(p.statesStored, 1 + pushes) << "N " << steps << " c " << c;
  };
  for (std::int64_t steps = 1; steps <= 300; ++steps)
    for (std::int64_t c = 1; c <= 14; ++c) check(steps, c);
  for (std::int64_t steps : {1000, 4097, 30000, 100003, 1000000})
    for (std::int64_t c : {1, 2, 3, 7, 10, 50, 999, 5000}) check(steps, c);
}

// binomial:stages=1 without a model: the strategy's own rule (internal::RecomputedStages, as
// BinomialCheckpointing drives it) over the schedule it runs, with one-double "stage values".
struct StageCounts {
  std::int64_t stored = 0, restored = 0;
};
StageCounts binomialStagesByRule(std::int64_t steps, std::int64_t c) {
  const std::int64_t slots = BinomialCheckpointing::slotsFor(steps, c, true);
  BinomialSchedule schedule;
  schedule.reset(steps, slots, true);  // positions 0..N-1, x_{N-1} the working state
  internal::RecomputedStages stages;
  stages.reset(1);
  StageCounts counts;
  Vector data(1);
  data(0) = 0.0;
  for (std::int64_t n = 1; n < steps; ++n) schedule.recordForward(n);
  stages.recordLast(steps - 1, data);  // doRecordStepData keeps the last forward step's stages
  ++counts.stored;
  struct Visitor {
    internal::RecomputedStages& stages;
    StageCounts& counts;
    void loadWorking() {}
    void load(std::int64_t) {}
    void store(std::int64_t) {}
    void advance(std::int64_t from, std::int64_t to) {
      if (to > from) {
        stages.pending(to - 1);
        ++counts.stored;
      }
    }
  } visitor{stages, counts};
  for (std::int64_t e = steps - 1; e >= 0; --e) {
    stages.beginRestore(e);
    schedule.restoreStep(e, visitor);
    if (stages.restore(e, data)) ++counts.restored;  // (the release at step 0 comes after restoreStepData(0))
  }
  return counts;
}

TEST(SchedulePrediction, BinomialStagesEqualTheStrategysRuleRunWithoutStates) {
  const auto check = [](std::int64_t steps, std::int64_t c) {
    const std::string spec = "binomial:checkpoints=" + std::to_string(c) + ",stages=1";
    const SchedulePrediction p = predictSchedule(spec, steps, 16, 4, nullptr);
    const SchedulePrediction plain =
        predictSchedule("binomial:checkpoints=" + std::to_string(c), steps, 16, 4, nullptr);
    const StageCounts rule = binomialStagesByRule(steps, c);
    SCOPED_TRACE("N " + std::to_string(steps) + " c " + std::to_string(c));
    EXPECT_EQ(p.stepDataStored, rule.stored);
    EXPECT_EQ(p.stepDataRestored, rule.restored);
    EXPECT_EQ(p.recomputedSteps, plain.recomputedSteps);  // the schedule is revolve's as without stages
    EXPECT_EQ(p.rhsEvaluations, plain.rhsEvaluations - 4 * rule.restored);
    EXPECT_EQ(p.peakRamBytes, plain.peakRamBytes + 2 * 3 * 16);  // two rk4 step records of 3 stage states
    // One stage (explicit Euler): no step data, nothing kept, as without stages=1.
    const SchedulePrediction euler = predictSchedule(spec, steps, 16, 1, nullptr);
    EXPECT_EQ(euler.stepDataRestored, 0);
    EXPECT_EQ(
        euler.rhsEvaluations,
        predictSchedule("binomial:checkpoints=" + std::to_string(c), steps, 16, 1, nullptr).rhsEvaluations);
  };
  for (std::int64_t steps = 1; steps <= 200; ++steps)
    for (std::int64_t c = 1; c <= 12; ++c) check(steps, c);
  for (std::int64_t steps : {1000, 30000, 100003})
    for (std::int64_t c : {1, 2, 10, 50, 5000}) check(steps, c);
}

TEST(SchedulePrediction, BinomialStagesHandleABillionSteps) {
  const std::int64_t n = 1'000'000'000;
  const SchedulePrediction plain = predictSchedule("binomial:checkpoints=10", n, 160, 4, nullptr);
  const SchedulePrediction p = predictSchedule("binomial:checkpoints=10,stages=1", n, 160, 4, nullptr);
  EXPECT_GT(plain.ramWrites, 0);  // counted in closed form beyond the 2^24 steps a simulation would take
  EXPECT_EQ(p.stepDataRestored, n - plain.ramWrites);
  EXPECT_GT(p.stepDataRestored, n / 2);
  EXPECT_EQ(p.rhsEvaluations, 4 * (2 * n + p.recomputedSteps - p.stepDataRestored));
  // As many slots as steps: no recomputation, every state but the working state's x_{N-1} a checkpoint (no
  // restore recomputes), only the last adjoint step served (by the forward sweep's record); counted
  // without a walk.
  const SchedulePrediction all =
      predictSchedule("binomial:checkpoints=1000000000,budget=1000GiB,stages=1", n, 160, 4, nullptr);
  EXPECT_EQ(all.recomputedSteps, 0);
  EXPECT_EQ(all.statesStored, n - 1);
  EXPECT_EQ(all.stepDataRestored, 1);
  EXPECT_EQ(all.rhsEvaluations, 4 * (2 * n - 1));
}

// binomial:stages=1 against real pendulum runs (rk4): N from 1 to 2000 fixed steps, few and many
// checkpoints (N < C + 2 included), counter by counter, the gradient bitwise equal to `full`.
TEST(SchedulePrediction, BinomialStagesAgreeExactlyWithRealRuns) {
  Pendulum problem;
  const ScheduleCosts costs;
  for (int wanted : {1, 2, 3, 4, 5, 12, 37, 2000}) {
    IntegratorOptions options = fixedStepRk4();
    options.t1 = 2e-3 * wanted;
    const GradientResult reference = fullReference(problem, pendulumParameters(), options);
    const std::int64_t steps = reference.summary.steps;
    ASSERT_GE(steps, 1);
    for (int c : {1, 2, 3, 10, 50, 3000}) {
      for (const std::string keep : {",stages=1", ""}) {
        const std::string spec = "binomial:checkpoints=" + std::to_string(c) + keep;
        SCOPED_TRACE(spec + " N " + std::to_string(steps));
        const SchedulePrediction p = expectPredictionEqualsRun(spec, options, reference, costs).prediction;
        if (!keep.empty() && steps >= 2) EXPECT_GT(p.stepDataRestored, 0);
      }
    }
  }
}

TEST(SchedulePrediction, OnlineAgreesExactlyWithRealRuns) {
  // online (fixed steps here, so the run can be compared; the strategy does not use N while recording),
  // with and without stages=1, by checkpoints and by budget: every counter the prediction reports.
  Pendulum problem;
  const ScheduleCosts costs;
  for (int wanted : {1, 2, 3, 4, 5, 12, 37, 2000}) {
    IntegratorOptions options = fixedStepRk4();
    options.t1 = 2e-3 * wanted;
    const GradientResult reference = fullReference(problem, pendulumParameters(), options);
    const std::int64_t steps = reference.summary.steps;
    for (const std::string base : {"online:checkpoints=1", "online:checkpoints=2", "online:checkpoints=3",
                                   "online:checkpoints=10", "online:checkpoints=50", "online:budget=400"}) {
      for (const std::string keep : {",stages=1", ""}) {
        const std::string spec = base + keep;
        SCOPED_TRACE(spec + " N " + std::to_string(steps));
        expectPredictionEqualsRun(spec, options, reference, costs);
      }
    }
  }
  // The placement is simulated step by step: N = 10^6 is predicted, N = 10^9 refused with the limit.
  const SchedulePrediction big = predictSchedule("online:checkpoints=100", 1'000'000, 16, 4, &costs);
  EXPECT_EQ(big.recomputedSteps + 999'999,
            static_cast<std::int64_t>(OnlineCheckpointing::predictedForwardSteps(1'000'000, 100, true)));
  EXPECT_THROW(predictSchedule("online:checkpoints=100", 1'000'000'000, 16, 4, &costs),
               std::invalid_argument);
  EXPECT_THROW(predictSchedule("online:checkpoints=100,stages=1", 1'000'000'000, 16, 4, &costs),
               std::invalid_argument);
  EXPECT_THROW(writeScheduleActions("online:checkpoints=3", 10, 16, 4, nullptr, std::cout),
               std::invalid_argument);
}

TEST(SchedulePrediction, BinomialStagesRefuseABudgetWithoutRoomForTheRecords) {
  // 11 states of 16 bytes fit 176 bytes; with stages=1 the two rk4 records (2 x 48 bytes) do not.
  EXPECT_NO_THROW(predictSchedule("binomial:checkpoints=10,budget=176", 100, 16, 4, nullptr));
  try {
    predictSchedule("binomial:checkpoints=10,budget=176,stages=1", 100, 16, 4, nullptr);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("binomial.budget"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(predictSchedule("binomial:checkpoints=10,budget=272,stages=1", 100, 16, 4, nullptr));
  // The pendulum's records also hold 4 stages' rhs data of 16 bytes: 2 x (48 + 64) bytes.
  EXPECT_THROW(predictSchedule("binomial:checkpoints=10,budget=399,stages=1", 100, 16, 4, nullptr, 16),
               std::invalid_argument);
  EXPECT_NO_THROW(predictSchedule("binomial:checkpoints=10,budget=400,stages=1", 100, 16, 4, nullptr, 16));
  // A real run refuses the same budget.
  Pendulum problem;
  ASSERT_EQ(8 * problem.rhsDataSize(), 16);
  IntegratorOptions options = fixedStepRk4();
  options.t1 = 0.2;  // 100 steps
  auto tight = createStorage("binomial:checkpoints=10,budget=399,stages=1");
  EXPECT_THROW(computeGradient(problem, pendulumParameters(), options, *tight), std::invalid_argument);
  auto fits = createStorage("binomial:checkpoints=10,budget=400,stages=1");
  EXPECT_NO_THROW(computeGradient(problem, pendulumParameters(), options, *fits));
  EXPECT_EQ(fits->counters().peakBytesInMemory, 400);
}

TEST(SchedulePrediction, ActionStreamsListEveryRecordAndRestore) {
  const ScheduleCosts costs{1, 1, 0.5, 0.5};
  for (const std::string spec :
       {"full", "binomial:checkpoints=3", "multilevel:ram=64,disk=64", "disk:dir=/tmp"}) {
    std::ostringstream out;
    writeScheduleActions(spec, 12, 16, 4, &costs, out);
    const std::string text = out.str();
    std::size_t records = 0, restores = 0, advances = 0;
    std::istringstream lines(text);
    std::string word, rest;
    std::int64_t advanced = 0;
    while (lines >> word) {
      if (word == "record") ++records;
      if (word == "restore") ++restores;
      if (word == "advance") {
        std::int64_t from = 0, to = 0;
        lines >> from >> to;
        advanced += to - from;
        ++advances;
      }
      std::getline(lines, rest);
    }
    EXPECT_EQ(records, 12u) << spec;
    EXPECT_EQ(restores, 12u) << spec;
    EXPECT_EQ(advanced, predictSchedule(spec, 12, 16, 1, &costs).recomputedSteps) << spec;
  }
}

// --actions for cams follows the stages it is given: without records (one stage) no step record is stored,
// with records of two units some are, as many as the prediction counts.
TEST(SchedulePrediction, CamsActionsFollowTheStages) {
  for (int stages : {1, 2, 4}) {
    std::ostringstream out;
    writeScheduleActions("cams:checkpoints=6", 60, 16, stages, nullptr, out);
    const SchedulePrediction p = predictSchedule("cams:checkpoints=6", 60, 16, stages, nullptr);
    std::istringstream lines(out.str());
    std::string line;
    std::int64_t records = 0, advanced = 0;
    while (std::getline(lines, line)) {
      if (line.rfind("store ram record", 0) == 0) ++records;
      if (line.rfind("advance ", 0) == 0) {
        std::istringstream words(line.substr(8));
        std::int64_t from = 0, to = 0;
        words >> from >> to;
        advanced += to - from;
      }
    }
    SCOPED_TRACE("stages " + std::to_string(stages));
    EXPECT_EQ(records, p.stepDataStored);
    EXPECT_GT(advanced, 0);
    if (stages == 1) EXPECT_EQ(records, 0);
    if (stages == 2) EXPECT_GT(records, 0);
  }
}

TEST(ScheduleInput, IntegersAreReadCompletelyAndExactly) {
  const std::int64_t max = kMaxScheduleSteps;
  EXPECT_EQ(parseScheduleInteger("30000", "--steps", 1, max), 30000);
  EXPECT_EQ(parseScheduleInteger("1e17", "--steps", 1, max), 100'000'000'000'000'000);
  EXPECT_EQ(parseScheduleInteger("9.5e15", "--steps", 1, max), 9'500'000'000'000'000);
  EXPECT_EQ(parseScheduleInteger("4e18", "--steps", 1, max), 4'000'000'000'000'000'000);
  EXPECT_EQ(parseScheduleInteger("1E+9", "--steps", 1, max), 1'000'000'000);
  EXPECT_EQ(parseScheduleInteger("2.50e1", "--steps", 1, max), 25);
  EXPECT_EQ(parseScheduleInteger("3999999999999999999", "--steps", 1, max), 3'999'999'999'999'999'999);
  for (const std::string bad : {"",
                                "0",
                                "-1",
                                "1.5",
                                "2.9",
                                "1e17x",
                                "1e",
                                "e5",
                                ".",
                                "4.1e18",
                                "4000000000000000001",
                                "99999999999999999999999999999999999",
                                "1e40",
                                "1e400",
                                "nan",
                                "inf",
                                "0x10",
                                " 5",
                                "5 ",
                                "1e-1",
                                "+5",
                                "1,000"}) {
    try {
      parseScheduleInteger(bad, "--steps", 1, max);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("--steps"), std::string::npos) << message;
      EXPECT_NE(message.find("[1, 4000000000000000000]"), std::string::npos) << message;
    }
  }
}

// Property: for extreme N, state sizes, stages and budgets every strategy either refuses with
// std::invalid_argument or returns counts that are what they claim: non-negative (-1 only for "not
// counted" RAM traffic), peak bytes within the bytes the spec allows, rhs evaluations S (N + R + A).
// Never a wrapped-around count, never a division by zero.
TEST(ScheduleInput, ExtremeArgumentsGiveSoundCountsOrAClearRefusal) {
  const std::vector<std::int64_t> stepsList = {1,
                                               2,
                                               3,
                                               1000,
                                               std::int64_t{1} << 31,
                                               9'000'000'000'000'000,
                                               100'000'000'000'000'000,
                                               kMaxScheduleSteps};
  const std::vector<std::int64_t> bytesList = {
      8, 8000, 65536, 65544, std::int64_t{1} << 32, kMaxScheduleStateBytes};
  const std::vector<std::string> specs = {"full",
                                          "full:budget=1000000GiB",
                                          "full:stages=1,budget=9000000000000000000",
                                          "binomial:checkpoints=1",
                                          "binomial:checkpoints=2",
                                          "binomial:checkpoints=1000,budget=9000000000000000000",
                                          "binomial:checkpoints=50,stages=1,budget=9000000000000000000",
                                          "online:checkpoints=10",
                                          "online:budget=64KiB",
                                          "cams:checkpoints=10",
                                          "disk:dir=/tmp",
                                          "disk:dir=/tmp,chunk=1073741824",
                                          "disk:dir=/tmp,stages=1,budget=9000000000000000000"};
  const std::int64_t maxCount = std::numeric_limits<std::int64_t>::max();
  int sound = 0, refused = 0;
  for (const std::string& spec : specs) {
    for (std::int64_t steps : stepsList) {
      for (std::int64_t bytes : bytesList) {
        for (int stages : {1, 4, 64}) {
          SCOPED_TRACE(spec + " N " + std::to_string(steps) + " bytes " + std::to_string(bytes) + " S " +
                       std::to_string(stages));
          SchedulePrediction p;
          try {
            p = predictSchedule(spec, steps, bytes, stages, nullptr);
          } catch (const std::invalid_argument& e) {
            EXPECT_GT(std::string(e.what()).size(), 20u);
            ++refused;
            continue;
          }
          ++sound;
          EXPECT_EQ(p.steps, steps);
          EXPECT_GE(p.recomputedSteps, 0);
          EXPECT_GE(p.statesStored, 0);
          EXPECT_GE(p.ramWrites, -1);
          EXPECT_GE(p.ramReads, 0);
          EXPECT_GE(p.diskWrites, 0);
          EXPECT_GE(p.diskReads, 0);
          EXPECT_GT(p.peakRamBytes + p.peakDiskBytes, 0);
          EXPECT_GE(p.peakDiskBytes, 0);
          EXPECT_LE(p.peakRamBytes, createStorage(spec)->budgetBytes());
          const UnsignedInt128 rhs =
              static_cast<UnsignedInt128>(stages) *
              (static_cast<UnsignedInt128>(steps) + static_cast<UnsignedInt128>(p.recomputedSteps) +
               static_cast<UnsignedInt128>(spec.rfind("cams", 0) == 0 ? p.adjointRecomputations
                                                                      : steps - p.stepDataRestored));
          EXPECT_LE(rhs, static_cast<UnsignedInt128>(maxCount));
          EXPECT_EQ(static_cast<UnsignedInt128>(p.rhsEvaluations), rhs);
          EXPECT_TRUE(std::isfinite(p.totalCost));
          if (spec.rfind("binomial", 0) == 0) {
            const std::int64_t c = dynamic_cast<BinomialCheckpointing&>(*createStorage(spec)).checkpoints();
            EXPECT_EQ(
                static_cast<UnsignedInt128>(p.recomputedSteps),
                revolve::workingStateRecomputedSteps(steps, BinomialCheckpointing::slotsFor(steps, c, true)));
          }
        }
      }
    }
  }
  // Both outcomes occur (the grid reaches the limits and stays inside them).
  EXPECT_GT(sound, 100);
  EXPECT_GT(refused, 100);
  // Beyond the limits: refused by name.
  const auto message = [](std::int64_t steps, std::int64_t bytes, int stages) {
    try {
      predictSchedule("full", steps, bytes, stages, nullptr);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(kMaxScheduleSteps + 1, 8, 4).find("--steps"), std::string::npos);
  EXPECT_NE(message(0, 8, 4).find("--steps"), std::string::npos);
  EXPECT_NE(message(10, kMaxScheduleStateBytes + 8, 4).find("--state-bytes"), std::string::npos);
  EXPECT_NE(message(10, std::int64_t{1} << 60, 4).find("--state-bytes"), std::string::npos);
  EXPECT_NE(message(10, 12, 4).find("--state-bytes"), std::string::npos);
  EXPECT_NE(message(10, 8, 65).find("--stages"), std::string::npos);
  // A full store of 4 GiB states (once an int of doubles overflowing to a division by zero).
  EXPECT_NE(message(10, std::int64_t{4} << 30, 4).find("full.budget"), std::string::npos);
  // Costs: at most 1e30 seconds each, so N (uf + ub) stays finite; 1e308 is refused by name.
  EXPECT_THROW(ScheduleCosts::parse("1e308:1:0:0", "--costs"), std::invalid_argument);
  const ScheduleCosts huge = ScheduleCosts::parse("1e30:1e30:1e30:1e30", "--costs");
  const SchedulePrediction p = predictSchedule("binomial:checkpoints=2", 1000, 8, 4, &huge);
  EXPECT_TRUE(std::isfinite(p.totalCost));
  EXPECT_GT(p.totalCost, 0.0);
}

}  // namespace
}  // namespace hindsight
