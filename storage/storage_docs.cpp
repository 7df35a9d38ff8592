#include <hindsight/storage/storage_docs.h>

#include <hindsight/storage/storage_factory.h>

namespace hindsight {
namespace {

const char* const kBudget =
    "bytes the strategy may hold in memory, e.g. 512MiB (default 4 GiB); exceeding it is a "
    "StorageError";

}  // namespace

const std::vector<StorageStrategyDoc>& storageStrategyDocs() {
  // Texts condensed from the header comment of each strategy (storage/*.h, engine/full_storage.h,
  // engine/*_checkpointing.h).
  static const std::vector<StorageStrategyDoc> table = {
      {"full",
       "every step's state in memory; nothing is recomputed",
       true,
       "full",
       {{"budget", kBudget},
        {"stages",
         "0 | 1: keep each step's stage values too, so no adjoint step evaluates the right-hand side "
         "(default 0)"}}},
      {"hermite",
       "(z, z') at every M-th grid point, states in between from cubic Hermite interpolation; the gradient "
       "error shrinks like (M h)^4",
       false,
       "hermite:every=4",
       {{"every", "keep every M-th grid point, M in [1, 1e9] (default 10)"},
        {"budget", kBudget},
        {"tolerance",
         "the largest relative interpolation error accepted, measured mid-interval in the forward "
         "sweep (the run is refused beyond it; gradient_error_estimate = 10 x that error), in "
         "[1e-14, 1] (default 0.01)"}}},
      {"disk",
       "every step's state in an HDF5 file (chunked; lossless prediction along time, or shuffle + zstd), "
       "written "
       "and read by a background thread",
       true,
       "disk:dir=/tmp/hindsight",
       {{"dir", "directory of the file, created if missing (required)"},
        {"level", "zstd level in [1, 22] (default 3)"},
        {"chunk",
         "states per HDF5 chunk and I/O buffer, in [1, 2^30] (default: about 1 MiB of states, at most 4096)"},
        {"budget", "bytes of the I/O buffers held in memory (default 64 MiB)"},
        {"keep", "true | false: keep the file after the backward sweep (default false)"},
        {"codec",
         "time (default): prediction along time, lossless residual coding | zstd: byte shuffle + zstd per "
         "chunk"},
        {"stages", "0 | 1: each row holds the state and the step's stage values (default 0)"}}},
      {"lossy",
       "every step's state in memory, compressed with a bounded error (a gradient error target, or ZFP "
       "absolute, mantissa rounding or time-prediction relative bounds); the gradient error is O(tolerance)",
       false,
       "lossy:codec=zfp,tolerance=1e-10",
       {{"target",
         "the relative gradient error T accepted; chooses codec=time and its tolerance (give target or "
         "codec + tolerance)"},
        {"codec", "zfp (absolute error bound) | round | time (relative error bounds, tolerance in (0, 0.5])"},
        {"tolerance", "the error bound T > 0, with codec"},
        {"budget", kBudget},
        {"block",
         "states compressed together, in [1, 2^30] (default: about 256 KiB of states, at most 4096)"}}},
      {"multilevel",
       "states in memory up to a RAM budget, then in an HDF5 file up to a disk budget, then every k-th state "
       "with recomputation of the others",
       true,
       "multilevel:ram=64MiB,disk=1GiB",
       {{"ram", "bytes held in memory (required)"},
        {"disk", "bytes of states written to the file, counted uncompressed (required)"},
        {"dir", "directory of the file (default: the system temp directory)"},
        {"level", "zstd level in [1, 22] (default 3)"},
        {"keep", "true | false: keep the file after the backward sweep (default false)"},
        {"costs",
         "uf:ub:wd:rd, seconds of a forward step, an adjoint step, a disk write and a read (default: "
         "measured at the start of the run; storage/schedule.h)"},
        {"schedule", "optimal (default, fixed steps) | stride"}}},
      {"binomial",
       "revolve-optimal offline checkpointing for a known number of steps (Griewank & Walther 2000); fixed "
       "steps only",
       true,
       "binomial:checkpoints=50",
       {{"checkpoints",
         "number of checkpoints C in [1, 1e9] (default 1); the strategy holds C + 1 states and "
         "reverses by revolve over all of them (T(N + 1, C + 1) - N recomputed steps)"},
        {"budget", kBudget},
        {"stages",
         "0 | 1: keep the stage values of the last recomputed step, so the adjoint step after a "
         "recomputation evaluates no right-hand side (default 0)"}}},
      {"online",
       "checkpointing while the number of steps is unknown (adaptive steps), re-planned with the binomial "
       "schedule once it is known",
       true,
       "online:checkpoints=50",
       {{"checkpoints", "number of checkpoints c in [1, 1e9] (default: as many as the budget holds)"},
        {"budget", kBudget},
        {"stages",
         "0 | 1: keep the stage values of the last recomputed step, so the adjoint step after a "
         "recomputation evaluates no right-hand side (default 0)"}}},
      {"cams",
       "optimal stage-aware checkpointing (after Zhang & Constantinescu, CAMS): checkpoints hold states or a "
       "step's stage values; fixed steps get the optimal plan, adaptive steps (or online=1) the online mode: "
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
      {"packed",
       "every step's state in memory, coded losslessly along time in blocks (prediction + bit-difference "
       "residuals + shuffle + zstd, the codec of disk); every bit restored",
       true,
       "packed",
       {{"budget",
         "bytes of coded blocks held in memory, e.g. 512MiB (default 4 GiB); exceeding it is a "
         "StorageError"},
        {"block",
         "states coded together, in [1, 2^30] (default: about 256 KiB of states, at least 16, at most "
         "4096)"}}},
  };
  // In the factory's order (the engine's in-memory strategies first), which help texts follow.
  static const std::vector<StorageStrategyDoc> docs = [] {
    std::vector<StorageStrategyDoc> ordered;
    for (const std::string& name : storageStrategyNames()) {
      for (const StorageStrategyDoc& doc : table) {
        if (doc.name == name) ordered.push_back(doc);
      }
    }
    return ordered;
  }();
  return docs;
}

const StorageStrategyDoc* findStorageStrategyDoc(const std::string& name) {
  for (const StorageStrategyDoc& doc : storageStrategyDocs()) {
    if (doc.name == name) return &doc;
  }
  return nullptr;
}

}  // namespace hindsight
