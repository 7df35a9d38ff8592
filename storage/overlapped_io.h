// Overlapped disk I/O for the disk level of a plan (multilevel's slot file, storage/multilevel_storage.h):
// writes go behind on a second thread while the sweep goes on, and the backward sweep's next disk read is
// started as soon as the plan allows, so that it is done when the state is needed. Not a strategy itself.
//
// OverlappedSlotIo: one I/O thread runs the jobs (write slot, read slot) in the order they were queued,
// through the caller's own write and read functions (the slot file's pwrite/pread with their checksums).
// FIFO order is what keeps every bit: a read queued after a write of the same slot reads what that write
// wrote, exactly as the synchronous file does. A write copies the state into one of `queueDepth` buffers
// and returns; it blocks only while every buffer waits for the disk. One read-ahead buffer takes a
// prefetch; read() of that slot waits for it (or queues the read itself when nothing was prefetched). The
// first failure of a job (full disk, corrupted slot) stops the thread's work and is rethrown, as the same
// exception, by the caller's next call; the destructor discards what is queued and joins the thread.
// Waits are bounded by the jobs ahead (a few disk operations), so an interrupt (engine/interrupt.h) is
// seen at the caller's next poll as without overlap.
//
// DiskEventLookahead: the disk events of a plan in the order a run issues them, from a copy of the plan
// run ahead without states (the same plan code, so it cannot disagree with the run). The rule both the
// run and the cost model follow: right after a disk event (and when the forward sweep has ended), if the
// next disk event is a read, that read is started. Nothing is written between the two, so the prefetched
// state is the one the plan loads.
//
// The cost model (hiddenDiskSeconds): the plan walked with a clock, the main thread's and the I/O
// thread's. The main thread spends uf per forward or recomputed step and ub per adjoint step; a disk job
// starts when it is queued and the I/O thread is free and lasts wd or rd; the main thread waits for a
// write buffer when queueDepth writes are unfinished, for every write at the end of the forward sweep
// (the file is complete there, storage/multilevel_storage.h), and for a read until it is done. The run
// then costs N uf + N ub + R uf + W wd + Q rd - hidden, where hidden is what the model returns
// (docs/theory/storage.md, "Overlapped disk I/O").
#pragma once

#include <hindsight/storage/schedule.h>

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace hindsight::internal {

class OverlappedSlotIo {
 public:
  using Writer = std::function<void(std::int64_t slot, const double* z)>;
  using Reader = std::function<void(std::int64_t slot, double* z)>;
  static constexpr int kDefaultQueueDepth = 2;

  /// Buffers of `values` doubles: queueDepth >= 1 for writes, one for the read-ahead; starts the thread.
  OverlappedSlotIo(std::int64_t values, int queueDepth, Writer writer, Reader reader);
  /// Discards the queued jobs and joins the thread. Never throws.
  ~OverlappedSlotIo();
  OverlappedSlotIo(const OverlappedSlotIo&) = delete;
  OverlappedSlotIo& operator=(const OverlappedSlotIo&) = delete;

  /// Queues a copy of z for `slot`; blocks while queueDepth writes are unfinished.
  void write(std::int64_t slot, const double* z);
  /// Queues a read of `slot` into the read-ahead buffer (after every queued write). No effect when that
  /// slot is already prefetched; a prefetch of another slot not yet read is waited for and dropped.
  void prefetch(std::int64_t slot);
  /// z <- the state of `slot`: the prefetched one when it is that slot, else read now (queued, waited for).
  void read(std::int64_t slot, double* z);
  /// Waits until every queued job is done.
  void drain();
  /// Reads served by a prefetch (the run's counter of the rule above).
  std::int64_t prefetchedReads() const { return prefetchedReads_; }
  // Every call rethrows the first failure of a job.

 private:
  struct Job {
    bool read;
    std::int64_t slot;
    int buffer;  // write buffer index; -1 for the read-ahead buffer
  };
  void run();
  void push(const Job& job);  // with mutex_ held
  void rethrowLocked();       // with mutex_ held
  void waitIdleLocked(std::unique_lock<std::mutex>& lock);

  std::int64_t values_;
  Writer writer_;
  Reader reader_;
  std::vector<std::vector<double>> writeBuffers_;
  std::vector<int> freeBuffers_;
  std::vector<double> readBuffer_;
  std::mutex mutex_;
  std::condition_variable changed_;
  // The queue: a ring of queueDepth + 1 jobs (every write buffer and the read-ahead), allocated once.
  std::vector<Job> ring_;
  std::size_t head_ = 0, queued_ = 0;
  bool busy_ = false;  // the thread runs a job
  bool stop_ = false;
  std::exception_ptr failure_;
  std::int64_t prefetchSlot_ = -1;  // slot in (or on its way to) the read-ahead buffer
  bool prefetchDone_ = false;
  std::int64_t prefetchedReads_ = 0;
  std::thread worker_;
};

struct DiskEvent {
  bool read = false;
  std::int64_t slot = 0;
};

class DiskEventLookahead {
 public:
  /// A rewound copy of `plan`, to be run ahead of the run that executes `plan` from its start.
  explicit DiskEventLookahead(const TwoLevelPlan& plan);
  /// The next disk event not yet popped, or nullptr when the plan has none left.
  const DiskEvent* peek();
  /// Takes the next event; throws std::logic_error unless it is `expected` (the run and its copy diverged).
  void pop(const DiskEvent& expected);

 private:
  TwoLevelPlan plan_;
  std::int64_t nextRecord_ = 0, nextRestore_ = 0;
  // Events found and not yet popped: events_[head_..]; cleared (capacity kept) once all are popped.
  std::vector<DiskEvent> events_;
  std::size_t head_ = 0;
};

/// Seconds of disk I/O that write-behind with `queueDepth` buffers and the read-ahead hide in one run of
/// `plan` under `costs` (the model above); 0 when the plan has no disk traffic, the disk is free, or N
/// exceeds TwoLevelPlan::kMaxSimulatedSteps (not walked: the prediction then shows no overlap). Polls the
/// interrupt every 2^16 steps.
double hiddenDiskSeconds(const TwoLevelPlan& plan, const ScheduleCosts& costs, int queueDepth);

}  // namespace hindsight::internal
