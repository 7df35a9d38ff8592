// The registry of trajectory storage strategies: one row per strategy with its spec name, its documented
// keys, its factory and its prediction. Rows are plain data; the engine holds the rows of its in-memory
// strategies (engine/memory_storage_factory.h) and the storage component appends its own
// (storage/storage_factory.h, storageStrategies()), each by an explicit function that returns the whole
// list (no registration at static initialization, so no order between translation units matters).
// createStorage, `hindsight schedule`, the help texts, Python's hindsight.storage_specs() and the table
// of docs/guides/storage_strategies.md all read the rows, so a strategy is added in one place: its own
// files and its row.
//
// A prediction says what a strategy will do for N fixed steps without running a model. Each row's
// prediction lives with its strategy and drives the plan objects the strategy itself executes at run time
// (BinomialSchedule, the online placement, cams::Plan, the two-level plan, the stride) with an executor
// that counts instead of copying states and stepping; tests/storage/prediction_grid_test.cpp holds every
// predicting row equal to real runs counter by counter, and a row without a prediction says why.
// A row's action stream (`hindsight schedule --actions`, storage/checkpoint_actions.h) is the same plan
// written action by action, so no caller picks a plan by the strategy's name.
#pragma once

#include <hindsight/engine/storage_spec.h>
#include <hindsight/engine/trajectory_storage.h>

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace hindsight {

__extension__ typedef unsigned __int128 UnsignedInt128;

/// The four costs of the schedule cost model (storage/schedule.h), in seconds (any common unit works).
struct ScheduleCosts {
  double forwardStep = 1.0;
  double adjointStep = 1.0;
  double diskWrite = 0.0;
  double diskRead = 0.0;
  /// Parses "uf:ub:wd:rd" (four numbers in [0, 1e30], uf > 0); throws std::invalid_argument naming
  /// `field` and the expected form.
  static ScheduleCosts parse(const std::string& text, const std::string& field);
  std::string text() const;
};

enum class StorageLevel { kRam, kDisk };
const char* levelName(StorageLevel level);

/// One storage level below RAM in a prediction of more than two levels (multilevel's levels=).
struct LevelTraffic {
  std::string name;
  std::int64_t writes = 0, reads = 0;  ///< states
  std::int64_t peakBytes = 0;          ///< bytes of states held at the most
  double write = 0.0, read = 0.0;      ///< the cost model's write and read of one state
};

/// What a schedule does, counted (a prediction or, for a run, what happened).
struct SchedulePrediction {
  std::string strategy;    ///< the spec
  std::string plan;        ///< human-readable plan, e.g. "leaves K=12 (revolve in RAM per leaf)"
  std::int64_t steps = 0;  ///< N
  int stages = 0;          ///< right-hand sides per step of the integrator (explicit RK: its stages)
  std::int64_t forwardSteps = 0;
  std::int64_t recomputedSteps = 0;
  std::int64_t rhsEvaluations = 0;  ///< stages * (forward + recomputed + adjoint steps without stored stages)
  /// cams: adjoint steps that recompute their stages (no step record held); their forward-step cost is
  /// part of scheduleCost (for cams, ub is the adjoint step given its stage values). 0 otherwise.
  std::int64_t adjointRecomputations = 0;
  /// Step data (stage values, `stages=1` and cams' records): the strategy's stepDataStored counter (step
  /// records filled, any sweep) and stepDataRestored (adjoint steps served from them, evaluating no rhs).
  std::int64_t stepDataStored = 0, stepDataRestored = 0;
  std::int64_t statesStored = 0;  ///< the strategy's statesStored counter
  /// RAM and disk traffic in states; -1: not counted (ramWrites of plans that rewrite slots unseen).
  std::int64_t ramWrites = 0, ramReads = 0, diskWrites = 0, diskReads = 0;
  std::int64_t peakRamBytes = 0;   ///< the strategy's peakBytesInMemory
  std::int64_t peakDiskBytes = 0;  ///< uncompressed bytes of states on disk at the most
  /// Disk seconds the strategy hides behind computation (multilevel's write-behind and read-ahead,
  /// storage/overlapped_io.h); scheduleCost is net of them. 0: none.
  double hiddenIoCost = 0.0;
  double scheduleCost = 0.0;  ///< (R + adjoint recomputations) uf + W wd + Q rd - hiddenIoCost
  double totalCost = 0.0;     ///< N uf + N ub + scheduleCost
  ScheduleCosts costs;        ///< the cost model of the two costs (a spec's own costs= first)
  /// Three or more levels: each level below RAM, its traffic and its own costs (diskWrites, diskReads and
  /// peakDiskBytes are their sums; costs.diskWrite and diskRead are unused). Empty otherwise.
  std::vector<LevelTraffic> levels;
  /// Asked for (request.lowerBound; multilevel plans only): no schedule of H-Revolve's family on these levels
  /// has a schedule part (without overlapped I/O) below this (KLevelPlan::lowerBound). -1: not computed.
  double lowerBound = -1.0;
  /// Empty, or why this plan is a trap: its schedule cost exceeds a simple alternative's (named here, with
  /// its cost) by more than twice (docs/theory/storage.md, "No silent trap").
  std::string warning;
};

/// What a prediction is asked: N fixed steps of an integrator with `stages` right-hand sides per step
/// (an explicit Runge-Kutta method; its step data are stages - 1 states and, when the problem keeps rhs
/// data, `stages` records of `stageDataBytes` bytes), states of `stateBytes` bytes (a multiple of 8), and
/// the cost model given on the command line (nullptr: none given).
struct PredictionRequest {
  std::int64_t steps = 0;
  std::int64_t stateBytes = 0;
  int stages = 1;
  const ScheduleCosts* costs = nullptr;
  /// Problem::rhsDataSize() * 8 (a SecondOrderProblem with f coordinates: 8 (f + f (f + 1) / 2)); 0: none.
  std::int64_t stageDataBytes = 0;
  /// Also bound the family's optimum from below (SchedulePrediction::lowerBound; seconds at N = 10^6).
  bool lowerBound = false;
};

struct StorageKeyDoc {
  std::string key;
  std::string doc;  ///< meaning, allowed values and default
};

struct StorageStrategyDoc {
  std::string name;
  std::string summary;  ///< one or two sentences: what is kept, what is recomputed
  bool exact = true;    ///< restore() returns the recorded bits (gradient bitwise equal to "full")
  std::string example;  ///< a valid spec string
  std::vector<StorageKeyDoc> keys;
};

/// One strategy. `predict` fills the counts, the plan and the peaks of `p` for a storage made from `spec`
/// by `create` (its keys checked); `p` arrives with the spec, N, the stages and the request's cost model
/// (1:1:0:0 without one), which a row may replace by its spec's own (multilevel's costs=), and rhs
/// evaluations and costs are completed after it (predictFromRows). nullptr when the strategy's counters
/// depend on the run; `notPredicted` then says on what.
/// `actions` writes the action stream of the plan `predict` counts (prediction::ActionWriter's lines,
/// or cams' own), for a request `predict` has accepted and N <= prediction::kMaxWalkedSteps; it may
/// refuse a configuration without a fixed plan with std::invalid_argument. nullptr when the strategy has
/// none at all; `noActions` then says why.
struct StorageStrategyRow {
  StorageStrategyDoc doc;
  std::unique_ptr<TrajectoryStorage> (*create)(const StorageSpec& spec) = nullptr;
  void (*predict)(const TrajectoryStorage& storage, const StorageSpec& spec, const PredictionRequest& request,
                  SchedulePrediction& p) = nullptr;
  std::string notPredicted;
  void (*actions)(const TrajectoryStorage& storage, const StorageSpec& spec, const PredictionRequest& request,
                  std::ostream& out) = nullptr;
  std::string noActions;

  const std::string& name() const { return doc.name; }
  std::vector<std::string> keys() const;
};

/// The row of `name` in `rows`, or nullptr.
const StorageStrategyRow* findStorageStrategy(const std::vector<StorageStrategyRow>& rows,
                                              const std::string& name);

/// A strategy from "NAME[:key=value,...]" by the rows: the name looked up, the keys checked against the
/// row's documented keys, the row's factory called. Throws std::invalid_argument for an unknown name
/// (listing the rows' names, after `unknownHint` when the caller knows more), an unknown key (listing the
/// valid ones) or an out-of-range value.
std::unique_ptr<TrajectoryStorage> createFromRows(const std::vector<StorageStrategyRow>& rows,
                                                  const std::string& spec);

/// Makes the storage of `spec` by the rows (validating it as a run would), calls its row's prediction
/// (or refuses with "is not predicted" and the row's reason) and completes the counts every strategy
/// shares: rhs evaluations, the schedule's and the total cost. The request's sizes are the caller's to
/// validate (storage/schedule.h, predictSchedule, names the flags and their ranges).
SchedulePrediction predictFromRows(const std::vector<StorageStrategyRow>& rows, const std::string& spec,
                                   const PredictionRequest& request);

namespace prediction {

/// Counts and bytes of a prediction are int64; every product or sum that could leave that range is
/// computed in 128 bits and refused with std::invalid_argument naming `what` instead of wrapping around.
std::int64_t checkedCount(UnsignedInt128 value, const std::string& what);
std::int64_t checkedProduct(std::int64_t a, std::int64_t b, const std::string& what);

/// Step records of an explicit Runge-Kutta method of `stages` stages: stages - 1 states of stage values.
inline bool hasStageValues(int stages) { return stages > 1; }

/// Bytes of one step record of an explicit Runge-Kutta method (Integrator::stepDataSize() * 8): its S - 1
/// stage states and S rhs data of request.stageDataBytes. Throws std::invalid_argument naming `name`.stages
/// = 1 when the record exceeds a run's 2^31 - 1 doubles.
std::int64_t stepRecordBytes(const PredictionRequest& request, const std::string& name);

/// Doubles of one stored row of full and disk: the state, and with `stageRows` its step record
/// (stepRecordBytes) too. Throws std::invalid_argument naming `name`.stages = 1 when that exceeds a run's
/// 2^31 - 1.
std::int64_t stageRowDoubles(const PredictionRequest& request, bool stageRows, const std::string& name);

/// The largest N a prediction walks step by step (an online placement, a schedule run without states).
constexpr std::int64_t kMaxWalkedSteps = std::int64_t{1} << 24;

/// The lines of an action stream, written by the plans' own visitors (BinomialSchedule, TwoLevelPlan):
///   record k / restore e        the run records x_k / asks for x_e (written by the row's loop);
///   store LEVEL SLOT            copy the current state into a slot, e.g. "store ram 3", "store disk 0";
///   load LEVEL SLOT             copy a slot into the current state; "load ram working": the state is
///                               the working state;
///   advance a b                 recompute x_a -> x_b.
struct ActionWriter {
  std::ostream& out;
  void store(StorageLevel level, std::int64_t slot);
  void load(StorageLevel level, std::int64_t slot);
  void advance(std::int64_t from, std::int64_t to);
  void loadWorking();
  void load(std::int64_t slot) { load(StorageLevel::kRam, slot); }
  void store(std::int64_t slot) { store(StorageLevel::kRam, slot); }
};

/// The stream of a strategy that keeps every state in its own slot of `level` (full, disk).
void writeEveryStateActions(std::int64_t steps, StorageLevel level, std::ostream& out);

}  // namespace prediction

}  // namespace hindsight
