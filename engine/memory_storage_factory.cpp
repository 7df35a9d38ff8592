#include <hindsight/engine/memory_storage_factory.h>

#include <hindsight/engine/binomial_checkpointing.h>
#include <hindsight/engine/cams_checkpointing.h>
#include <hindsight/engine/full_storage.h>
#include <hindsight/engine/online_checkpointing.h>

#include <stdexcept>

namespace hindsight {
namespace {

const char* const kBudget =
    "bytes the strategy may hold in memory, e.g. 512MiB (default 4 GiB); exceeding it is a "
    "StorageError";

}  // namespace

const std::vector<StorageStrategyRow>& memoryStorageStrategies() {
  // Texts condensed from the header comment of each strategy (engine/full_storage.h,
  // engine/*_checkpointing.h).
  static const std::vector<StorageStrategyRow> rows = {
      {{"full",
        "every step's state in memory; nothing is recomputed",
        true,
        "full",
        {{"budget", kBudget},
         {"stages",
          "0 | 1: keep each step's stage values too, with each stage's rhs data (a SecondOrderProblem: the "
          "acceleration and the Cholesky factor of M), so no adjoint step evaluates the right-hand side or "
          "factorises M (default 0)"}}},
       &FullStorage::create,
       &FullStorage::predict,
       {},
       &FullStorage::writeActions,
       {}},
      {{"binomial",
        "revolve-optimal offline checkpointing for a known number of steps (Griewank & Walther 2000); fixed "
        "steps only",
        true,
        "binomial:checkpoints=50",
        {{"checkpoints",
          "number of checkpoints C in [1, 1e9] (default 1); the strategy holds C + 1 states and "
          "reverses by revolve with all of them as snapshots, x_{N-1} being the engine's working state "
          "(T(N, C + 1) - (N - 1) recomputed steps)"},
         {"budget", kBudget},
         {"stages",
          "0 | 1: keep the stage values of the last recomputed step, so the adjoint step after a "
          "recomputation evaluates no right-hand side (default 0)"}}},
       &BinomialCheckpointing::create,
       &BinomialCheckpointing::predict,
       {},
       &BinomialCheckpointing::writeActions,
       {}},
      {{"online",
        "checkpointing while the number of steps is unknown (adaptive steps), re-planned with the binomial "
        "schedule once it is known",
        true,
        "online:checkpoints=50",
        {{"checkpoints", "number of checkpoints c in [1, 1e9] (default: as many as the budget holds)"},
         {"budget", kBudget},
         {"stages",
          "0 | 1: keep the stage values of the last recomputed step, so the adjoint step after a "
          "recomputation evaluates no right-hand side (default 0)"}}},
       &OnlineCheckpointing::create,
       &OnlineCheckpointing::predict,
       {},
       nullptr,
       "--actions prints offline plans; online thins its checkpoints during the forward sweep (print its "
       "counts without --actions)"},
      {{"cams",
        "optimal stage-aware checkpointing (after Zhang & Constantinescu, CAMS): checkpoints hold states or "
        "a "
        "step's stage values; fixed steps get the optimal plan, adaptive steps (or online=1) the online "
        "mode: "
        "checkpoints placed as online places them, each interval reversed by the optimal plan",
        true,
        "cams:checkpoints=10",
        {{"checkpoints",
          "C in [1, 1e6]: the byte budget of binomial:checkpoints=C (C + 1 states); exactly one of "
          "checkpoints, budget"},
         {"budget", "bytes for the checkpoints; exactly one of checkpoints, budget"},
         {"online",
          "0 or 1 (default 0): the online mode for fixed steps too (plans in seconds at N = 1e6; "
          "adaptive steps always use it)"}}},
       &CamsCheckpointing::create,
       &CamsCheckpointing::predict,
       {},
       &CamsCheckpointing::writeActions,
       {}},
  };
  return rows;
}

std::unique_ptr<TrajectoryStorage> createMemoryStorage(const std::string& text) {
  const StorageSpec spec = StorageSpec::parse(text);
  if (findStorageStrategy(memoryStorageStrategies(), spec.name()) == nullptr) {
    std::string names;
    for (const StorageStrategyRow& row : memoryStorageStrategies())
      names += (names.empty() ? "" : ", ") + row.name();
    for (const char* other : {"disk", "lossy", "packed", "hermite", "multilevel"}) {
      if (spec.name() == other) {
        throw std::invalid_argument(
            "storage strategy '" + spec.name() +
            "' is not in memory: it needs the storage component (hindsight::createStorage, "
            "<hindsight/storage/storage_factory.h>); in memory: " +
            names);
      }
    }
    throw std::invalid_argument("unknown storage strategy '" + spec.name() + "'; in memory: " + names);
  }
  return createFromRows(memoryStorageStrategies(), text);
}

}  // namespace hindsight
