#include <hindsight/storage/overlapped_io.h>

#include <hindsight/engine/interrupt.h>

#include <algorithm>
#include <cstring>
#include <deque>
#include <stdexcept>
#include <string>

namespace hindsight::internal {

OverlappedSlotIo::OverlappedSlotIo(std::int64_t values, int queueDepth, Writer writer, Reader reader)
    : values_(values), writer_(std::move(writer)), reader_(std::move(reader)) {
  if (queueDepth < 1) throw std::invalid_argument("OverlappedSlotIo: queueDepth must be at least 1");
  // Every buffer allocated here, once: the sweeps' writes and reads allocate nothing.
  for (int i = 0; i < queueDepth; ++i) {
    writeBuffers_.emplace_back(static_cast<std::size_t>(values));
    freeBuffers_.push_back(queueDepth - 1 - i);
  }
  readBuffer_.assign(static_cast<std::size_t>(values), 0.0);
  ring_.resize(static_cast<std::size_t>(queueDepth) + 1);
  worker_ = std::thread([this] { run(); });
}

OverlappedSlotIo::~OverlappedSlotIo() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    queued_ = 0;
  }
  changed_.notify_all();
  worker_.join();
}

void OverlappedSlotIo::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    changed_.wait(lock, [this] { return stop_ || (queued_ > 0 && !failure_); });
    if (stop_) return;
    const Job job = ring_[head_];
    head_ = (head_ + 1) % ring_.size();
    --queued_;
    busy_ = true;
    lock.unlock();
    std::exception_ptr error;
    try {
      if (job.read)
        reader_(job.slot, readBuffer_.data());
      else
        writer_(job.slot, writeBuffers_[static_cast<std::size_t>(job.buffer)].data());
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    busy_ = false;
    if (error && !failure_) failure_ = error;  // the thread stops taking jobs: the caller gets it next
    if (job.read)
      prefetchDone_ = true;
    else
      freeBuffers_.push_back(job.buffer);
    changed_.notify_all();
  }
}

void OverlappedSlotIo::push(const Job& job) {
  // At most one job per write buffer and one for the read-ahead buffer are queued: the ring never fills.
  ring_[(head_ + queued_) % ring_.size()] = job;
  ++queued_;
}

void OverlappedSlotIo::rethrowLocked() {
  if (failure_) std::rethrow_exception(failure_);
}

void OverlappedSlotIo::write(std::int64_t slot, const double* z) {
  std::unique_lock<std::mutex> lock(mutex_);
  rethrowLocked();
  if (slot == prefetchSlot_) {
    // A prefetch of the slot being rewritten would be stale: wait for it and drop it (the lookahead rule
    // never asks for this; it keeps the class correct on its own).
    changed_.wait(lock, [this] { return prefetchDone_ || failure_; });
    rethrowLocked();
    prefetchSlot_ = -1;
    prefetchDone_ = false;
  }
  changed_.wait(lock, [this] { return !freeBuffers_.empty() || failure_; });
  rethrowLocked();
  const int buffer = freeBuffers_.back();
  freeBuffers_.pop_back();
  lock.unlock();  // the buffer is this thread's until queued
  std::memcpy(writeBuffers_[static_cast<std::size_t>(buffer)].data(), z,
              static_cast<std::size_t>(values_) * 8);
  lock.lock();
  push(Job{false, slot, buffer});
  changed_.notify_all();
}

void OverlappedSlotIo::prefetch(std::int64_t slot) {
  std::unique_lock<std::mutex> lock(mutex_);
  rethrowLocked();
  if (slot == prefetchSlot_) return;
  if (prefetchSlot_ >= 0) {  // another slot's prefetch, not read: the buffer is free once it is done
    changed_.wait(lock, [this] { return prefetchDone_ || failure_; });
    rethrowLocked();
  }
  prefetchSlot_ = slot;
  prefetchDone_ = false;
  push(Job{true, slot, -1});
  changed_.notify_all();
}

void OverlappedSlotIo::read(std::int64_t slot, double* z) {
  std::unique_lock<std::mutex> lock(mutex_);
  rethrowLocked();
  if (slot == prefetchSlot_) {
    ++prefetchedReads_;
  } else {
    lock.unlock();
    prefetch(slot);  // queued behind every write, as a synchronous read would follow them
    lock.lock();
  }
  changed_.wait(lock, [this] { return prefetchDone_ || failure_; });
  rethrowLocked();
  std::memcpy(z, readBuffer_.data(), static_cast<std::size_t>(values_) * 8);
  prefetchSlot_ = -1;
  prefetchDone_ = false;
}

void OverlappedSlotIo::drain() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] { return (queued_ == 0 && !busy_) || failure_; });
  rethrowLocked();
}

namespace {

// Collects a plan's disk events (the RAM ones are free and not events).
struct EventCollector {
  std::vector<DiskEvent>& events;
  void store(StorageLevel level, std::int64_t slot) {
    if (level == StorageLevel::kDisk) events.push_back(DiskEvent{false, slot});
  }
  void load(StorageLevel level, std::int64_t slot) {
    if (level == StorageLevel::kDisk) events.push_back(DiskEvent{true, slot});
  }
  void advance(std::int64_t, std::int64_t) {}
};

}  // namespace

DiskEventLookahead::DiskEventLookahead(const TwoLevelPlan& plan) : plan_(plan) {
  plan_.rewind();
  nextRestore_ = plan_.steps() - 1;
}

const DiskEvent* DiskEventLookahead::peek() {
  EventCollector collector{events_};
  std::int64_t walked = 0;
  if (head_ == events_.size()) {  // all popped: start over, keeping the capacity
    events_.clear();
    head_ = 0;
  }
  while (events_.empty()) {
    if ((++walked & 0xffff) == 0) pollInterrupt();
    if (nextRecord_ < plan_.steps())
      plan_.recordForward(nextRecord_++, collector);
    else if (nextRestore_ >= 0)
      plan_.restoreStep(nextRestore_--, collector);
    else
      return nullptr;
  }
  return &events_[head_];
}

void DiskEventLookahead::pop(const DiskEvent& expected) {
  const DiskEvent* next = peek();
  if (next == nullptr || next->read != expected.read || next->slot != expected.slot) {
    throw std::logic_error("multilevel: the lookahead copy of the plan disagrees with the run at a disk " +
                           std::string(expected.read ? "read" : "write") + " of slot " +
                           std::to_string(expected.slot));
  }
  ++head_;
}

namespace {

// The model's clock (overlapped_io.h): the main thread's time, the I/O thread's, the writes not yet done.
struct OverlapClock {
  OverlapClock(const ScheduleCosts& c, DiskEventLookahead& a, std::size_t d) : costs(c), ahead(a), depth(d) {}
  const ScheduleCosts& costs;
  DiskEventLookahead& ahead;
  std::size_t depth;
  double main = 0.0, io = 0.0;
  std::int64_t writes = 0, reads = 0, recomputed = 0;
  std::deque<double> writesDone;
  bool backward = false, prefetched = false;
  std::int64_t prefetchSlot = -1;
  double prefetchReady = 0.0;

  void startNextRead() {
    const DiskEvent* next = ahead.peek();
    if (next == nullptr || !next->read || (prefetched && prefetchSlot == next->slot)) return;
    io = std::max(io, main) + costs.diskRead;
    prefetched = true;
    prefetchSlot = next->slot;
    prefetchReady = io;
  }
  void store(StorageLevel level, std::int64_t slot) {
    if (level != StorageLevel::kDisk) return;
    ahead.pop(DiskEvent{false, slot});
    ++writes;
    while (!writesDone.empty() && writesDone.front() <= main) writesDone.pop_front();
    if (writesDone.size() >= depth) {  // every buffer busy: wait for the oldest write
      main = std::max(main, writesDone.front());
      writesDone.pop_front();
    }
    io = std::max(io, main) + costs.diskWrite;
    writesDone.push_back(io);
    if (backward) startNextRead();
  }
  void load(StorageLevel level, std::int64_t slot) {
    if (level != StorageLevel::kDisk) return;
    ahead.pop(DiskEvent{true, slot});
    ++reads;
    if (prefetched && prefetchSlot == slot) {
      main = std::max(main, prefetchReady);
    } else {
      io = std::max(io, main) + costs.diskRead;
      main = io;
    }
    prefetched = false;
    startNextRead();
  }
  void advance(std::int64_t from, std::int64_t to) {
    main += static_cast<double>(to - from) * costs.forwardStep;
    recomputed += to - from;
  }
};

}  // namespace

double hiddenDiskSeconds(const TwoLevelPlan& plan, const ScheduleCosts& costs, int queueDepth) {
  const TwoLevelPlan::Counts& counts = plan.counts();
  if (plan.steps() > TwoLevelPlan::kMaxSimulatedSteps || plan.diskSlotsUsed() == 0 ||
      (counts.diskWrites == 0 && counts.diskReads == 0) || (costs.diskWrite == 0.0 && costs.diskRead == 0.0))
    return 0.0;
  TwoLevelPlan run = plan;
  run.rewind();
  DiskEventLookahead ahead(plan);
  OverlapClock clock(costs, ahead, static_cast<std::size_t>(std::max(1, queueDepth)));
  const std::int64_t steps = plan.steps();
  for (std::int64_t n = 0; n < steps; ++n) {
    if ((n & 0xffff) == 0) pollInterrupt();
    run.recordForward(n, clock);
    clock.main += costs.forwardStep;  // the step from x_n to x_{n+1}
  }
  clock.main = std::max(clock.main, clock.io);  // the forward sweep ends with the file complete
  clock.backward = true;
  clock.startNextRead();
  for (std::int64_t e = steps - 1; e >= 0; --e) {
    if ((e & 0xffff) == 0) pollInterrupt();
    run.restoreStep(e, clock);
    clock.main += costs.adjointStep;
  }
  clock.main = std::max(clock.main, clock.io);
  // What the synchronous run takes minus what the overlapped one does; at most the disk part, which is
  // written as the prediction writes it (R uf + W wd + Q rd), so that all of it hidden leaves R uf exactly.
  const double disk =
      static_cast<double>(clock.writes) * costs.diskWrite + static_cast<double>(clock.reads) * costs.diskRead;
  const double serial = static_cast<double>(steps) * (costs.forwardStep + costs.adjointStep) +
                        static_cast<double>(clock.recomputed) * costs.forwardStep + disk;
  return std::clamp(serial - clock.main, 0.0, disk);
}

}  // namespace hindsight::internal
