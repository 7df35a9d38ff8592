// `hindsight schedule --storage SPEC --steps N --state-bytes B [--stages S] [--stage-bytes D]
// [--costs uf:ub:wd:rd] [--json] [--actions]`: what a storage strategy will do for N fixed steps, without
// running a model (storage/schedule.h: the same plan code the strategies execute). Prints forward and
// recomputed steps, right-hand-side evaluations, reads and writes per level, peak bytes per level and the
// predicted cost; --actions prints the action stream instead (one action per line). Exit 2 for bad
// input, naming the flag and its allowed range.
#include <hindsight/problems/app/config.h>
#include <hindsight/storage/schedule.h>
#include <hindsight/storage/storage_factory.h>
#include "commands.h"

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace hindsight::cli {
namespace {

std::string formatCost(double value) {
  std::ostringstream text;
  text << std::setprecision(6) << value;
  return text.str();
}

struct ScheduleArgs {
  std::string storage;
  std::string steps;
  std::string stateBytes;
  std::string stages = "4";
  std::string stageBytes = "0";
  std::string costs;
  bool json = false;
  bool actions = false;
  bool bound = false;
};

std::string count(std::int64_t value) {
  return value < 0 ? std::string("not counted") : std::to_string(value);
}

int runSchedule(const ScheduleArgs& args) {
  const std::int64_t steps = parseScheduleInteger(args.steps, "--steps", 1, kMaxScheduleSteps);
  const std::int64_t stateBytes = parseBytes(args.stateBytes, "--state-bytes");
  const int stages = static_cast<int>(parseScheduleInteger(args.stages, "--stages", 1, kMaxScheduleStages));
  const std::int64_t stageBytes =
      parseScheduleInteger(args.stageBytes, "--stage-bytes", 0, kMaxScheduleStateBytes);  // a multiple of 8
  std::unique_ptr<ScheduleCosts> costs;
  if (!args.costs.empty())
    costs = std::make_unique<ScheduleCosts>(ScheduleCosts::parse(args.costs, "--costs"));
  if (args.bound && args.actions) throw std::invalid_argument("--bound and --actions: give one of them");
  if (args.actions) {
    writeScheduleActions(args.storage, steps, stateBytes, stages, costs.get(), std::cout,
                         stageBytes);  // validates first
    return 0;
  }
  const SchedulePrediction p =
      predictSchedule(args.storage, steps, stateBytes, stages, costs.get(), stageBytes, args.bound);
  if (args.json) {
    const nlohmann::json out = scheduleToJson(p, stateBytes);
    std::cout << out.dump(2) << '\n';
    return 0;
  }
  std::cout << "storage:           " << p.strategy << "\nplan:              " << p.plan
            << "\nsteps:             " << p.steps << " (" << p.stages << " rhs per step, states of "
            << formatBytes(stateBytes) << ")\nforward steps:     " << p.forwardSteps
            << "\nrecomputed steps:  " << p.recomputedSteps << "\nrhs evaluations:   " << p.rhsEvaluations
            << (p.stepDataStored > 0
                    ? "\nstage values:      " + std::to_string(p.stepDataStored) + " step records stored, " +
                          std::to_string(p.stepDataRestored) + " adjoint steps served (no rhs)"
                    : std::string())
            << "\nstates stored:     " << p.statesStored << "\nram:               writes "
            << count(p.ramWrites) << ", reads " << count(p.ramReads) << ", peak "
            << formatBytes(p.peakRamBytes) << "\ndisk:              writes " << p.diskWrites << ", reads "
            << p.diskReads << ", peak " << formatBytes(p.peakDiskBytes) << " (uncompressed)\n";
  for (const LevelTraffic& level : p.levels) {  // three or more levels: the disk line sums these
    std::cout << "  " << std::left << std::setw(17) << (level.name + ":") << std::right << "writes "
              << level.writes << ", reads " << level.reads << ", peak " << formatBytes(level.peakBytes)
              << " (costs " << level.write << ":" << level.read << ")\n";
  }
  std::cout << "predicted cost:    " << std::setprecision(6) << p.totalCost << " (schedule " << p.scheduleCost
            << " = recomputation + disk I/O"
            << (p.hiddenIoCost > 0.0 ? " - " + formatCost(p.hiddenIoCost) + " hidden by overlapped disk I/O"
                                     : std::string())
            << ")\n";
  if (p.lowerBound >= 0.0) {
    // The bound is on the synchronous schedule part; overlapped I/O is a saving on top of any schedule.
    const double synchronous = p.scheduleCost + p.hiddenIoCost;
    char gap[64];
    std::snprintf(gap, sizeof gap, "%.3f %%", 100.0 * std::abs(synchronous - p.lowerBound) / p.lowerBound);
    // Below it only where the plan is not of that family: the exact programme over every stack schedule,
    // which can beat it where a slower level is cheaper to write or read than a faster one.
    const std::string where =
        synchronous >= p.lowerBound
            ? std::string(gap) + " above it"
            : std::string(gap) + " below it: the plan is the exact programme's, not of that family";
    std::cout << "lower bound:       " << std::setprecision(10) << p.lowerBound
              << " (no schedule of H-Revolve's family on these levels has a smaller schedule part; this "
                 "plan's, "
              << synchronous << " without overlapped I/O, is " << where << ")\n";
  }
  if (!p.warning.empty()) std::cout << "warning:           " << p.warning << '\n';
  return 0;
}

}  // namespace

void registerSchedule(CLI::App& app) {
  auto args = std::make_shared<ScheduleArgs>();
  CLI::App* command = app.add_subcommand(
      "schedule",
      "What a storage strategy will do for N fixed steps, without running a model: recomputed "
      "steps, rhs evaluations, reads/writes and peak bytes per level, predicted cost");
  // The strategies it predicts, from the registry's rows (storage/storage_factory.h).
  std::string predicted;
  for (const StorageStrategyRow& row : storageStrategies()) {
    if (row.predict != nullptr) predicted += (predicted.empty() ? "" : ", ") + row.name();
  }
  command
      ->add_option("--storage", args->storage,
                   "storage spec NAME[:key=value,...], e.g. binomial:checkpoints=50; predicted: " + predicted)
      ->required();
  command
      ->add_option("--steps", args->steps,
                   "number of fixed steps N, an integer in [1, 4e18] (1e9 style accepted)")
      ->required();
  command
      ->add_option("--state-bytes", args->stateBytes,
                   "bytes of one state, a multiple of 8 in [8, 16 GiB - 8] (e.g. 8000, 64KiB)")
      ->required();
  command
      ->add_option("--stages", args->stages,
                   "right-hand sides per step of the integrator, an integer in [1, 64] (rk4: 4)")
      ->capture_default_str();
  command
      ->add_option("--stage-bytes", args->stageBytes,
                   "bytes of rhs data the problem keeps per stage with the stage values (storages with "
                   "stages=1, cams), a multiple of 8 in [0, 16 GiB - 8]; a SecondOrderProblem of f "
                   "coordinates: 8 (f + f (f + 1) / 2), the rod's 10 modes: 520; cams keeps none")
      ->capture_default_str();
  command->add_option(
      "--costs", args->costs,
      "cost model uf:ub:wd:rd: seconds of a forward step, an adjoint step, a disk write and a "
      "disk read of one state (default 1:1:0:0; multilevel plans by it unless its spec has costs=, as a "
      "run plans by costs= or, without it, by the costs it measures)");
  command->add_flag("--json", args->json, "machine-readable output");
  command->add_flag("--bound", args->bound,
                    "multilevel plans: also compute a lower bound on the optimum of H-Revolve's family of "
                    "schedules on these levels and the plan's distance to it (seconds at N = 10^6; "
                    "docs/theory/storage.md)");
  command->add_flag("--actions", args->actions,
                    "print the action stream (record/restore/store/load/advance)");
  commands().push_back({command, [args] { return guarded([&] { return runSchedule(*args); }); }});
}

}  // namespace hindsight::cli
