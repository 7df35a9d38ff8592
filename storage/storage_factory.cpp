#include <hindsight/storage/storage_factory.h>

#include <hindsight/engine/memory_storage_factory.h>
#include <hindsight/storage/disk_storage.h>
#include <hindsight/storage/hermite_storage.h>
#include <hindsight/storage/lossy_storage.h>
#include <hindsight/storage/mixed_plan.h>
#include <hindsight/storage/multilevel_storage.h>

#include <stdexcept>

namespace hindsight {
namespace {

const char* const kBudget =
    "bytes the strategy may hold in memory, e.g. 512MiB (default 4 GiB); exceeding it is a "
    "StorageError";

}  // namespace

const std::vector<StorageStrategyRow>& storageStrategies() {
  // The engine's in-memory rows (engine/memory_storage_factory.h) and then this component's; each
  // strategy has its row in one of the two lists only. Texts condensed from the header comment of each
  // strategy (storage/*.h).
  static const std::vector<StorageStrategyRow> rows = [] {
    std::vector<StorageStrategyRow> all = memoryStorageStrategies();
    all.insert(
        all.end(),
        {
            {{"hermite",
              "(z, z') at every M-th grid point, states in between from cubic Hermite interpolation; the "
              "gradient "
              "error shrinks like (M h)^4",
              false,
              "hermite:every=4",
              {{"every", "keep every M-th grid point, M in [1, 1e9] (default 10)"},
               {"budget", kBudget},
               {"tolerance",
                "the largest relative interpolation error accepted, measured mid-interval in the forward "
                "sweep (the run is refused beyond it; gradient_error_estimate = 10 x that error), in "
                "[1e-14, 1] (default 0.01)"}}},
             &HermiteStorage::create,
             nullptr,
             "it keeps (z, z') at every M-th grid point, but whether a run is accepted depends on the "
             "interpolation error it measures",
             nullptr,
             "it keeps no checkpoints to plan: every M-th grid point, interpolated in between"},
            {{"disk",
              "every step's state in an HDF5 file (chunked; lossless prediction along time, or shuffle + "
              "zstd), "
              "written "
              "and read by a background thread",
              true,
              "disk:dir=/tmp/hindsight",
              {{"dir", "directory of the file, created if missing (required)"},
               {"level", "zstd level in [1, 22] (default 3)"},
               {"chunk",
                "states per HDF5 chunk and I/O buffer, in [1, 2^30] (default: about 1 MiB of states, at most "
                "4096)"},
               {"budget", "bytes of the I/O buffers held in memory (default 64 MiB)"},
               {"keep", "true | false: keep the file after the backward sweep (default false)"},
               {"codec",
                "time (default): prediction along time, lossless residual coding | zstd: byte shuffle + zstd "
                "per "
                "chunk"},
               {"stages",
                "0 | 1: each row holds the state, the step's stage values and each stage's rhs data "
                "(default 0)"}}},
             &DiskStorage::create,
             &DiskStorage::predict,
             {},
             &DiskStorage::writeActions,
             {}},
            {{"lossy",
              "every step's state in memory, compressed with a bounded error (a gradient error target, or "
              "ZFP "
              "absolute, mantissa rounding or time-prediction relative bounds); the gradient error is "
              "O(tolerance)",
              false,
              "lossy:codec=zfp,tolerance=1e-10",
              {{"target",
                "the relative gradient error T accepted; chooses codec=time and its tolerance (give target "
                "or "
                "codec + tolerance)"},
               {"sensitivity",
                "with target: the problem's calibrated ratio S of relative gradient error to relative state "
                "error, in [0.001, 1000] (default 10, or the application's calibration); tolerance T / S"},
               {"codec",
                "zfp (absolute error bound) | round | time (relative error bounds, tolerance in (0, 0.5])"},
               {"tolerance", "the error bound T > 0, with codec"},
               {"budget", kBudget},
               {"block",
                "states compressed together, in [1, 2^30] (default: about 256 KiB of states, at most "
                "4096)"}}},
             &LossyStorage::create,
             nullptr,
             "its bytes depend on how well the states compress",
             nullptr,
             "it keeps every state, compressed: no checkpoints to plan"},
            {{"mixed",
              "checkpoint_schedules' Mixed plan (Maddison 2023) for action streams and predictions: C units, "
              "each a restart state or one step's adjoint data of a state's size; runs of the engine are "
              "refused (cams is the engine's equivalent, records sized by the stage data)",
              true,
              "mixed:checkpoints=11",
              {{"checkpoints", "units C in [1, 1e6], each a state or one step's adjoint data (required)"}}},
             &MixedPlanStorage::create,
             &MixedPlanStorage::predict,
             {},
             nullptr,
             "its units hold one step's adjoint data, which --actions' state vocabulary does not express; "
             "hindsight.checkpoint_schedule('mixed:checkpoints=C', N) hands out its checkpoint_schedules "
             "stream"},
            {{"multilevel",
              "states in RAM and in a file on disk (or on K - 1 slower levels, levels=) up to a budget "
              "each, reversed by the plan cheapest under a cost model (fixed steps) or by a uniform stride "
              "with recomputation of the states between (schedule=stride, adaptive steps)",
              true,
              "multilevel:ram=64MiB,disk=1GiB",
              {{"ram", "bytes held in memory (required)"},
               {"disk",
                "bytes of states written to the file, counted uncompressed (required without levels=, "
                "positive: disk=0 is refused, binomial or cams hold states in RAM alone)"},
               {"levels",
                "instead of disk=, the levels below RAM fastest first, NAME:BYTES[:PATH][@WRITE:READ] "
                "separated "
                "by ';', e.g. ssd:4GiB@1e-4:1e-4;hdd:64GiB@1e-3:1e-3 (each level's directory PATH, default "
                "the subfolder NAME of dir=; its write and read seconds of one state, given for every level "
                "with costs=uf:ub or measured by the run); fixed steps up to 2^24 planned on all levels"},
               {"dir",
                "directory of the file (default: the system temp directory); with levels=, of the "
                "levels' subfolders"},
               {"level", "zstd level in [1, 22] (default 3)"},
               {"keep", "true | false: keep the file after the backward sweep (default false)"},
               {"costs",
                "uf:ub:wd:rd, seconds of a forward step, an adjoint step, a disk write and a read (default: "
                "measured at the start of the run; storage/schedule.h); with levels=, uf:ub"},
               {"schedule", "optimal (default, fixed steps) | stride"},
               {"overlap",
                "1 (default) | 0: schedule=optimal's disk writes behind and reads ahead on a second thread "
                "(the same bits; the prediction subtracts the hidden I/O); one level below RAM only, with "
                "three or more levels every write and read waits"},
               {"sync",
                "0 (default) | 1: schedule=optimal's disk writes reach the device before they return "
                "(O_DSYNC)"}}},
             &MultilevelStorage::create,
             &MultilevelStorage::predict,
             {},
             &MultilevelStorage::writeActions,
             {}},
            {{"packed",
              "every step's state in memory, coded losslessly along time in blocks (prediction + "
              "bit-difference "
              "residuals + shuffle + zstd, the codec of disk); every bit restored",
              true,
              "packed",
              {{"budget",
                "bytes of coded blocks held in memory, e.g. 512MiB (default 4 GiB); exceeding it is a "
                "StorageError"},
               {"block",
                "states coded together, in [1, 2^30] (default: about 256 KiB of states, at least 16, at most "
                "4096)"}}},
             &LossyStorage::createPacked,
             nullptr,
             "its bytes depend on how well the states compress",
             nullptr,
             "it keeps every state, coded: no checkpoints to plan"},
        });
    return all;
  }();
  return rows;
}

std::unique_ptr<TrajectoryStorage> createStorage(const std::string& text) {
  return createFromRows(storageStrategies(), text);
}

std::vector<std::string> storageStrategyKeys(const std::string& name) {
  const StorageStrategyRow* row = findStorageStrategy(storageStrategies(), name);
  if (row == nullptr) {
    throw std::invalid_argument("unknown storage strategy '" + name + "'; known: " + [] {
      std::string names;
      for (const auto& n : storageStrategyNames()) names += (names.empty() ? "" : ", ") + n;
      return names;
    }());
  }
  return row->keys();
}

std::vector<std::string> storageStrategyNames() {
  std::vector<std::string> names;
  for (const StorageStrategyRow& row : storageStrategies()) names.push_back(row.name());
  return names;
}

}  // namespace hindsight
