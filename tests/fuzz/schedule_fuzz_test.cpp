// Fuzzing `hindsight schedule` (cli/schedule_command.cpp, storage/schedule.h) in-process, through the
// same functions in the same order as the command: parseScheduleInteger for --steps and --stages,
// parseBytes for --state-bytes, ScheduleCosts::parse for --costs, then predictSchedule or
// writeScheduleActions. Whatever the texts, the result is a prediction whose numbers are what they
// claim (non-negative counts that fit in int64, N forward steps, rhs evaluations S (N + R + A), peak
// RAM within the spec's budget, a finite cost of at least N (uf + ub)), or std::invalid_argument whose
// message names the flag or the storage setting it refused -- which the command turns into exit 2.
// A handful of real processes check that last step: exit 0 or 2, never another code or a signal.
#include "fuzz/fuzz_support.h"
#include "support/run_cli.h"

#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/storage/multilevel_storage.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_factory.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

namespace hindsight {
namespace {

struct Arguments {
  std::string storage, steps, stateBytes, stages = "4", costs;
  bool actions = false;

  std::string commandLine() const {
    std::string line = "schedule --storage '" + storage + "' --steps '" + steps + "' --state-bytes '" +
                       stateBytes + "' --stages '" + stages + "'";
    if (!costs.empty()) line += " --costs '" + costs + "'";
    return line + (actions ? " --actions" : " --json");
  }
};

struct Outcome {
  std::optional<SchedulePrediction> prediction;
  std::string actions;  // the action stream, with --actions
  std::string message;  // of the refusal
  std::int64_t steps = 0, stateBytes = 0;
  int stages = 0;
  ScheduleCosts costs;
};

// The command's steps (runSchedule in cli/schedule_command.cpp), with the prediction kept for the checks.
Outcome run(const Arguments& a) {
  Outcome o;
  o.steps = parseScheduleInteger(a.steps, "--steps", 1, kMaxScheduleSteps);
  o.stateBytes = parseBytes(a.stateBytes, "--state-bytes");
  o.stages = static_cast<int>(parseScheduleInteger(a.stages, "--stages", 1, kMaxScheduleStages));
  std::unique_ptr<ScheduleCosts> costs;
  if (!a.costs.empty()) costs = std::make_unique<ScheduleCosts>(ScheduleCosts::parse(a.costs, "--costs"));
  if (costs) o.costs = *costs;
  if (a.actions) {
    std::ostringstream out;
    writeScheduleActions(a.storage, o.steps, o.stateBytes, o.stages, costs.get(), out);
    o.actions = out.str();
    return o;
  }
  o.prediction = predictSchedule(a.storage, o.steps, o.stateBytes, o.stages, costs.get());
  return o;
}

// Names a refusal may carry: the command's flags and the storage strategies' names (a setting of the
// spec is named "binomial.checkpoints = ...", an unknown strategy "unknown storage strategy").
bool namesTheInput(const std::string& message) {
  for (const char* flag : {"--steps", "--state-bytes", "--stages", "--costs", "storage"}) {
    if (message.find(flag) != std::string::npos) return true;
  }
  for (const std::string& name : storageStrategyNames()) {
    if (message.find(name) != std::string::npos) return true;
  }
  return false;
}

void expectSound(const Arguments& a, const Outcome& o) {
  const std::string input = fuzz::printable(a.commandLine());
  if (!o.prediction) {
    // The action stream: one action a line, and each "advance from to" inside 0..N-1.
    std::istringstream lines(o.actions);
    for (std::string line; std::getline(lines, line);) {
      std::int64_t from = 0, to = 0;
      if (std::sscanf(line.c_str(), "advance %ld %ld", &from, &to) == 2) {
        ASSERT_TRUE(0 <= from && from < to && to < o.steps) << line << "\n" << input;
      }
    }
    return;
  }
  const SchedulePrediction& p = *o.prediction;
  EXPECT_EQ(p.steps, o.steps) << input;
  EXPECT_EQ(p.stages, o.stages) << input;
  EXPECT_EQ(p.forwardSteps, o.steps) << input;
  for (const std::int64_t count :
       {p.recomputedSteps, p.rhsEvaluations, p.adjointRecomputations, p.stepDataStored, p.stepDataRestored,
        p.statesStored, p.diskWrites, p.diskReads, p.peakRamBytes, p.peakDiskBytes}) {
    EXPECT_GE(count, 0) << input;
  }
  // -1: not counted (engine/storage_registry.h; the stride's RAM traffic).
  EXPECT_GE(p.ramWrites, -1) << input;
  EXPECT_GE(p.ramReads, -1) << input;
  // mixed's one step (N = 1) is reversed from WORK alone (storage/mixed_plan.h): it holds no unit.
  if (!(a.storage.rfind("mixed", 0) == 0 && o.steps == 1))
    EXPECT_GT(p.peakRamBytes + p.peakDiskBytes, 0) << input;
  EXPECT_LE(p.peakRamBytes, createStorage(a.storage)->budgetBytes()) << input;
  const bool cams = a.storage.rfind("cams", 0) == 0;
  const UnsignedInt128 rhs =
      static_cast<UnsignedInt128>(o.stages) *
      (static_cast<UnsignedInt128>(o.steps) + static_cast<UnsignedInt128>(p.recomputedSteps) +
       static_cast<UnsignedInt128>(cams ? p.adjointRecomputations : o.steps - p.stepDataRestored));
  EXPECT_TRUE(static_cast<UnsignedInt128>(p.rhsEvaluations) == rhs) << input;
  EXPECT_TRUE(std::isfinite(p.scheduleCost) && p.scheduleCost >= 0.0) << p.scheduleCost << " " << input;
  EXPECT_TRUE(std::isfinite(p.totalCost)) << input;
  // Relative: N (uf + ub) and the schedule's part are each rounded once. multilevel with costs= in its
  // spec plans and reports by those (--costs is then not used).
  ScheduleCosts costs = o.costs;
  const std::size_t specCosts = a.storage.find("costs=");
  if (a.storage.rfind("multilevel", 0) == 0 && specCosts != std::string::npos) {
    const std::size_t end = a.storage.find(',', specCosts);
    costs = ScheduleCosts::parse(
        a.storage.substr(specCosts + 6, end == std::string::npos ? end : end - specCosts - 6), "costs");
  }
  const double fixed = static_cast<double>(o.steps) * (costs.forwardStep + costs.adjointStep);
  EXPECT_GE(p.totalCost, fixed * (1 - 1e-12)) << input;
  if (a.storage.rfind("binomial", 0) == 0) {
    const std::int64_t c = dynamic_cast<BinomialCheckpointing&>(*createStorage(a.storage)).checkpoints();
    // Revolve with C + 1 snapshots, x_{N-1} the engine's working state (engine/binomial_checkpointing.h).
    EXPECT_TRUE(
        static_cast<UnsignedInt128>(p.recomputedSteps) ==
        revolve::workingStateRecomputedSteps(o.steps, BinomialCheckpointing::slotsFor(o.steps, c, true)))
        << input;
  }
}

// Passes when the arguments give a sound prediction or std::invalid_argument naming the input.
bool expectPredictionOrInvalidArgument(const Arguments& a) {
  try {
    expectSound(a, run(a));
    return true;
  } catch (const std::invalid_argument& e) {
    EXPECT_TRUE(namesTheInput(e.what())) << "'" << e.what() << "' names no flag for\n"
                                         << fuzz::printable(a.commandLine());
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw " << typeid(e).name() << " (" << e.what()
                  << ") instead of std::invalid_argument for\n"
                  << fuzz::printable(a.commandLine());
  }
  return false;
}

const std::vector<std::string> kStepSeeds = {
    "1", "2", "7", "1000", "30000", "1e6", "2.5e6", "16777216", "1e9", "4e18", "3999999999999999999", "1E+5"};
const std::vector<std::string> kByteSeeds = {"8",    "64",   "8000",        "64KiB",
                                             "1MiB", "4GiB", "17179869176", "10MB"};
const std::vector<std::string> kStageSeeds = {"1", "2", "4", "7", "64"};
const std::vector<std::string> kCostSeeds = {
    "", "1:1:0:0", "1e-4:2e-4:1e-5:1e-5", "1:1:0.2:0.2", "1e30:1e30:1e30:1e30", "0.5:0:100:100"};

std::vector<std::string> dictionary() {
  return {"0",
          "1",
          "-1",
          "e",
          "E",
          "e+",
          "e-",
          ".",
          "+",
          "-",
          "x",
          " ",
          "\t",
          ":",
          "::",
          "9",
          "1e17",
          "1e18",
          "4.1e18",
          "1e400",
          "nan",
          "inf",
          "0x10",
          "KiB",
          "MiB",
          "GiB",
          "TiB",
          "B",
          "kB",
          "18446744073709551616",
          "9223372036854775807",
          "4e18",
          "1e308",
          "1e-320",
          ",",
          "="};
}

// Plans whose time grows with N: online and cams simulate their placement step by step, multilevel
// evaluates O(sqrt N) leaf counts for each of up to 2048 last-leaf lengths (seconds at N = 1e10 with
// 2^34 disk slots). Small N for them keeps these tests fast; the closed forms get any N.
bool simulated(const std::string& spec) {
  for (const char* name : {"online", "cams", "multilevel"}) {
    if (spec.rfind(name, 0) == 0) return true;
  }
  return false;
}

// Arguments whose prediction takes long by design, skipped to keep the tests well under a second
// each: multilevel's dynamic programme beyond 2^20 of its N^2 (R + 1)(D + 1) work (it is solved up to
// 2^28, about a second), and revolve's walk over its repetitions for 2 or 3 slots at N > 1e9.
bool slow(const Arguments& a) {
  try {
    const std::int64_t steps = parseScheduleInteger(a.steps, "--steps", 1, kMaxScheduleSteps);
    const std::int64_t bytes = parseBytes(a.stateBytes, "--state-bytes");
    if (bytes <= 0) return false;
    auto storage = createStorage(a.storage);
    if (auto* multilevel = dynamic_cast<MultilevelStorage*>(storage.get())) {
      const double n = static_cast<double>(steps);
      const double r = std::min(n, static_cast<double>(multilevel->budgetBytes() / bytes));
      const double d = std::min(n, static_cast<double>(multilevel->options().diskBytes / bytes));
      return n * n * (r + 1) * (d + 1) > 1048576.0;
    }
    if (auto* binomial = dynamic_cast<BinomialCheckpointing*>(storage.get()))
      return binomial->checkpoints() <= 2 && steps > 1000000000;
  } catch (const std::exception&) {
  }
  return false;
}

// The storage seeds and a few specs the schedule tool is used with.
std::vector<std::string> specSeeds() {
  auto specs = fuzz::seedLines("storage_specs.txt");
  for (const char* extra : {"binomial:checkpoints=10,stages=1", "full:stages=1",
                            "cams:checkpoints=3,online=1", "multilevel:ram=1MiB,disk=1GiB",
                            "multilevel:ram=512,disk=1TiB,costs=1:1:1e-3:1e-3", "disk:dir=/tmp,stages=1"})
    specs.push_back(extra);
  // Predictions write nothing; a directory that exists keeps createStorage's checks the run's.
  for (std::string& spec : specs) {
    const std::size_t at = spec.find("dir=/tmp/run");
    if (at != std::string::npos) spec.replace(at, 12, "dir=/tmp");
  }
  return specs;
}

TEST(ScheduleFuzz, SeedsGiveSoundPredictions) {
  int sound = 0;
  for (const std::string& spec : specSeeds()) {
    Arguments a{spec, "1000", "64", "4", "1:1:0.1:0.1"};
    sound += expectPredictionOrInvalidArgument(a) ? 1 : 0;
  }
  EXPECT_GT(sound, 15);
}

// Each argument mutated as text, the others from the seeds.
TEST(ScheduleFuzz, MutatedArguments) {
  const auto specs = specSeeds();
  const auto words = dictionary();
  fuzz::Mutator mutator(fuzz::seed(31));
  int sound = 0;
  for (int k = 0; k < fuzz::cases(3000); ++k) {
    Arguments a;
    a.storage = mutator.pick(specs);
    a.steps = mutator.pick(kStepSeeds);
    a.stateBytes = mutator.pick(kByteSeeds);
    a.stages = mutator.pick(kStageSeeds);
    a.costs = mutator.pick(kCostSeeds);
    a.actions = mutator.chance(0.1);
    switch (mutator.below(5)) {
      case 0:
        a.steps = mutator.mutate(a.steps, words, 3);
        break;
      case 1:
        a.stateBytes = mutator.mutate(a.stateBytes, words, 3);
        break;
      case 2:
        a.stages = mutator.mutate(a.stages, words, 3);
        break;
      case 3:
        a.costs = mutator.mutate(a.costs, words, 3);
        break;
      default:
        a.storage = mutator.mutate(a.storage, words, 3);
    }
    // Keep it fast: the long simulated plans (online, the dynamic programme, action streams) only for
    // small N; the closed forms for any N.
    if (a.actions || simulated(a.storage)) {
      try {
        if (parseScheduleInteger(a.steps, "--steps", 1, kMaxScheduleSteps) > 10000) continue;
      } catch (const std::invalid_argument&) {
      }
    }
    if (slow(a)) continue;
    sound += expectPredictionOrInvalidArgument(a) ? 1 : 0;
    if (HasFailure()) return;  // the first failing input is the useful one
  }
  EXPECT_GT(sound, 50);
  ::testing::Test::RecordProperty("sound", sound);
}

// Valid texts of random values over the whole range: N log-uniform in [1, 4e18] (digits or
// scientific notation), state sizes from 8 bytes to beyond the limit, every stage count, costs from
// 0 to 1e30.
TEST(ScheduleFuzz, RandomValuesOverTheWholeRange) {
  const auto specs = specSeeds();
  fuzz::Mutator mutator(fuzz::seed(32));
  const auto logUniform = [&](double lo, double hi) {
    return std::exp(std::uniform_real_distribution<double>(std::log(lo), std::log(hi))(mutator.rng()));
  };
  int sound = 0, refused = 0;
  for (int k = 0; k < fuzz::cases(2000); ++k) {
    Arguments a;
    a.storage = mutator.pick(specs);
    const double n = std::floor(logUniform(1, simulated(a.storage) ? 1e4 : 4.2e18));
    if (mutator.chance(0.5)) {
      char text[64];
      std::snprintf(text, sizeof text, "%.17g", n);
      a.steps = text;
    } else {
      a.steps = std::to_string(static_cast<std::uint64_t>(n));
    }
    const std::int64_t entries = static_cast<std::int64_t>(logUniform(1, 4e9));
    a.stateBytes = std::to_string(8 * entries + (mutator.chance(0.05) ? 4 : 0));
    a.stages = std::to_string(1 + mutator.below(mutator.chance(0.05) ? 80 : 64));
    if (mutator.chance(0.7)) {
      a.costs.clear();
      for (int i = 0; i < 4; ++i) {
        char text[40];
        std::snprintf(text, sizeof text, "%.17g", mutator.chance(0.2) ? 0.0 : logUniform(1e-12, 1e30));
        a.costs += (i == 0 ? "" : ":") + std::string(text);
      }
    }
    if (slow(a)) continue;
    if (expectPredictionOrInvalidArgument(a))
      ++sound;
    else
      ++refused;
    if (HasFailure()) return;
  }
  EXPECT_GT(sound, 200);
  EXPECT_GT(refused, 200);
  ::testing::Test::RecordProperty("sound", sound);
}

// Inputs these tests found, kept: each refusal now names what to change.
TEST(ScheduleFuzz, FoundInputsAreRefusedByName) {
  const auto refusal = [](const Arguments& a) {
    try {
      run(a);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  // A multilevel RAM level that holds no state: the plan's own message named neither level nor size.
  for (const char* steps : {"1", "2", "1000"}) {
    const std::string message =
        refusal({"multilevel:ram=512,disk=4KiB,costs=1:1:0:0", steps, "3411280", "63"});
    EXPECT_NE(message.find("multilevel.ram = 512 B"), std::string::npos) << message;
    EXPECT_NE(message.find("--state-bytes"), std::string::npos) << message;
  }
  // A spec with a NUL (a JSON "\u0000"): the message ended at it, before the key and the valid keys.
  const std::string message = refusal({std::string("cams:budget=1KiB,onlin\0=1", 25), "1", "1MiB", "64"});
  EXPECT_NE(message.find("control character (byte 0x00) at position 22"), std::string::npos) << message;
}

#ifdef HINDSIGHT_CLI_PATH
// The command itself: exit 0 with the prediction's numbers, or exit 2 with the in-process message.
TEST(ScheduleFuzz, CommandExitsZeroOrTwo) {
  const auto specs = specSeeds();
  const auto words = dictionary();
  fuzz::Mutator mutator(fuzz::seed(33));
  for (int k = 0; k < 8; ++k) {
    Arguments a{mutator.pick(specs), mutator.pick(kStepSeeds), mutator.pick(kByteSeeds),
                mutator.pick(kStageSeeds), mutator.pick(kCostSeeds)};
    if (k % 2 == 1) a.steps = mutator.mutate(a.steps, words, 2);
    if (k % 4 == 3) a.stateBytes = mutator.mutate(a.stateBytes, words, 2);
    if (simulated(a.storage)) a.steps = "30";
    for (std::string* text : {&a.steps, &a.stateBytes, &a.storage}) {  // the shell quotes them
      text->erase(
          std::remove_if(text->begin(), text->end(), [](char c) { return c == '\'' || c < 32 || c > 126; }),
          text->end());
    }
    std::string message;
    std::optional<SchedulePrediction> prediction;
    try {
      prediction = run(a).prediction;
    } catch (const std::invalid_argument& e) {
      message = e.what();
    }
    const auto result = testing::runCli(a.commandLine());
    SCOPED_TRACE(a.commandLine() + "\n" + result.output);
    if (prediction) {
      ASSERT_EQ(result.exitCode, 0);
      const auto json = nlohmann::json::parse(result.output.substr(result.output.find('{')));
      EXPECT_EQ(json["recomputed_steps"].get<std::int64_t>(), prediction->recomputedSteps);
      EXPECT_EQ(json["peak_ram_bytes"].get<std::int64_t>(), prediction->peakRamBytes);
    } else {
      EXPECT_EQ(result.exitCode, 2);
      EXPECT_NE(result.output.find(message), std::string::npos) << message;
    }
  }
}
#endif

}  // namespace
}  // namespace hindsight
