#include <hindsight/storage/multilevel_storage.h>

#include <hindsight/storage/chunked_state_file.h>

#include <algorithm>
#include <cstring>
#include <filesystem>

namespace hindsight {
namespace {
constexpr std::int64_t kSlotsPerBlock = 256;
}

bool MultilevelStorage::Options::IsValid(std::string* error) const {
  std::string message;
  if (ramBytes <= 0)
    message = "multilevel.ram = " + std::to_string(ramBytes) + " must be a positive byte count";
  else if (diskBytes < 0)
    message = "multilevel.disk = " + std::to_string(diskBytes) + " must not be negative";
  else if (compressionLevel < 1 || compressionLevel > 22)
    message = "multilevel.level = " + std::to_string(compressionLevel) + " must be in [1, 22]";
  if (error != nullptr) *error = message;
  return message.empty();
}

MultilevelStorage::MultilevelStorage(Options options)
    : TrajectoryStorage(std::max<std::int64_t>(1, options.ramBytes)), options_(std::move(options)) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument(error);
}

MultilevelStorage::~MultilevelStorage() { closeFile(); }

std::unique_ptr<TrajectoryStorage> MultilevelStorage::create(const StorageSpec& spec) {
  if (!spec.has("ram") || !spec.has("disk")) {
    throw std::invalid_argument("multilevel needs ram= and disk=, e.g. multilevel:ram=64MiB,disk=4GiB");
  }
  Options options;
  options.ramBytes = spec.bytes("ram", 0);
  options.diskBytes = spec.bytes("disk", 0);
  options.directory = spec.text("dir", "");
  options.compressionLevel = static_cast<int>(spec.integer("level", 3, 1, 22));
  options.keepFile = spec.text("keep", "false", {"true", "false"}) == "true";
  return std::make_unique<MultilevelStorage>(std::move(options));
}

std::string MultilevelStorage::spec() const {
  std::string text =
      "multilevel:ram=" + std::to_string(options_.ramBytes) + ",disk=" + std::to_string(options_.diskBytes);
  if (!options_.directory.empty()) text += ",dir=" + options_.directory;
  if (options_.compressionLevel != 3) text += ",level=" + std::to_string(options_.compressionLevel);
  if (options_.keepFile) text += ",keep=true";
  return text;
}

void MultilevelStorage::closeFile() {
  if (file_) {
    file_->close();
    file_.reset();
  }
}

void MultilevelStorage::doBegin() {
  closeFile();
  slotBlocks_.clear();
  slots_.clear();
  freeSlots_.clear();
  kept_.clear();
  scratch_.clear();
  slotsInUseByKept_ = 0;
  statesInRam_ = 0;
  diskRows_ = 0;
  diskBufferBytes_ = 0;
  cursor_ = -1;
  filePath_.clear();

  const int n = info().stateSize;
  const std::int64_t budget = budgetBytes();
  const std::int64_t steps = info().stepCount;
  const std::int64_t rowBytes = internal::ChunkedStateFile::bufferBytes(n, 1);
  diskCapacity_ = options_.diskBytes / rowBytes;
  const bool ramSuffices = steps >= 0 && steps <= budget / stateBytes();
  if (diskCapacity_ > 0 && !ramSuffices) {
    std::int64_t chunk = std::clamp<std::int64_t>((std::int64_t{1} << 20) / rowBytes, 1, 4096);
    chunk = std::min({chunk, std::max<std::int64_t>(1, budget / 8 / rowBytes), diskCapacity_});
    const std::int64_t buffers = 2 * internal::ChunkedStateFile::bufferBytes(n, chunk);
    if (buffers <= budget / 2) {
      chunkStates_ = chunk;
      diskBufferBytes_ = buffers;
      holdBytes(diskBufferBytes_);
    } else {
      diskCapacity_ = 0;  // RAM cannot even afford the I/O buffers
    }
  } else {
    diskCapacity_ = 0;
  }
  ramCapacity_ = (budget - diskBufferBytes_) / stateBytes();
  if (ramCapacity_ + diskCapacity_ < 1) {
    throw StorageError("storage '" + spec() + "' cannot hold a single state of " + formatBytes(stateBytes()) +
                       "; raise ram or disk");
  }

  stride_ = 1;
  ramKeptLimit_ = ramCapacity_;
  if (steps > ramCapacity_ + diskCapacity_) {
    // Smallest stride k whose ceil(N/k) kept states and k - 1 scratch states fit.
    bool found = false;
    for (std::int64_t k = 2; k - 1 < ramCapacity_ && !found; ++k) {
      const std::int64_t keptStates = (steps + k - 1) / k;
      if (keptStates <= ramCapacity_ - (k - 1) + diskCapacity_) {
        stride_ = k;
        ramKeptLimit_ = ramCapacity_ - (k - 1);
        found = true;
      }
    }
    if (!found) stride_ = (steps + ramCapacity_ + diskCapacity_ - 1) / (ramCapacity_ + diskCapacity_);
  }
}

std::int64_t MultilevelStorage::availableSlots() const {
  const std::int64_t unallocated = ramCapacity_ - static_cast<std::int64_t>(slots_.size());
  const std::int64_t affordable = (budgetBytes() - counters().bytesInMemory) / stateBytes();
  return static_cast<std::int64_t>(freeSlots_.size()) +
         std::max<std::int64_t>(0, std::min(unallocated, affordable));
}

std::int64_t MultilevelStorage::acquireSlot(std::int64_t wanted) {
  if (freeSlots_.empty()) {
    // A new block of slots: as many as wanted (at least one), within capacity and budget.
    std::int64_t count = std::min({kSlotsPerBlock, std::max<std::int64_t>(1, wanted),
                                   ramCapacity_ - static_cast<std::int64_t>(slots_.size()),
                                   (budgetBytes() - counters().bytesInMemory) / stateBytes()});
    count = std::max<std::int64_t>(1, count);
    holdBytes(count * stateBytes());
    const int n = info().stateSize;
    slotBlocks_.emplace_back(new double[static_cast<std::size_t>(count * n)]);
    for (std::int64_t i = count - 1; i >= 0; --i) {
      freeSlots_.push_back(static_cast<std::int64_t>(slots_.size() + static_cast<std::size_t>(i)));
    }
    for (std::int64_t i = 0; i < count; ++i) slots_.push_back(slotBlocks_.back().get() + i * n);
  }
  const std::int64_t slot = freeSlots_.back();
  freeSlots_.pop_back();
  return slot;
}

void MultilevelStorage::openFile() {
  internal::StateFileOptions fileOptions;
  fileOptions.directory =
      options_.directory.empty() ? std::filesystem::temp_directory_path().string() : options_.directory;
  fileOptions.filePrefix = "hindsight-multilevel";
  fileOptions.compressionLevel = options_.compressionLevel;
  fileOptions.chunkStates = chunkStates_;
  fileOptions.bufferCount = 2;
  fileOptions.keepFile = options_.keepFile;
  fileOptions.failWriteAfterChunks = options_.failWriteAfterChunks;
  file_ = std::make_unique<internal::ChunkedStateFile>(fileOptions, info());
  filePath_ = file_->path();
}

void MultilevelStorage::doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef) {
  const std::size_t bytes = static_cast<std::size_t>(info().stateSize) * 8;
  while (step % stride_ == 0) {
    if (slotsInUseByKept_ < ramKeptLimit_ && availableSlots() > 0) {
      // A known trajectory needs ceil(N / stride) kept states; an unknown one gets blocks.
      const std::int64_t wanted = info().stepCount >= 0
                                      ? (info().stepCount + stride_ - 1) / stride_ - slotsInUseByKept_
                                      : kSlotsPerBlock;
      const std::int64_t slot = acquireSlot(std::min(wanted, ramKeptLimit_ - slotsInUseByKept_));
      std::memcpy(slots_[static_cast<std::size_t>(slot)], z.data(), bytes);
      kept_.push_back(Kept{step, slot, -1});
      ++slotsInUseByKept_;
      return;
    }
    if (diskRows_ < diskCapacity_) {
      if (!file_) openFile();
      file_->append(t, z.data());
      kept_.push_back(Kept{step, -1, diskRows_++});
      return;
    }
    // Both levels full: double the stride and drop the RAM states that are no longer on it.
    stride_ *= 2;
    const std::int64_t stride = stride_;
    kept_.erase(std::remove_if(kept_.begin(), kept_.end(),
                               [&](const Kept& k) {
                                 if (k.slot < 0 || k.step % stride == 0) return false;
                                 releaseSlot(k.slot);
                                 --slotsInUseByKept_;
                                 return true;
                               }),
                kept_.end());
  }
}

void MultilevelStorage::doFinish(double, ConstVectorRef, ConstVectorRef) {
  StorageCounters& c = mutableCounters();
  c.statesStored = static_cast<std::int64_t>(kept_.size());
  statesInRam_ = slotsInUseByKept_;
  cursor_ = static_cast<std::int64_t>(kept_.size()) - 1;
  if (file_) {
    file_->finishWriting(stepCount());
    c.bytesOnDisk = file_->fileBytes();
    c.uncompressedBytes = diskRows_ * stateBytes();
    c.compressedBytes = file_->storedStateBytes();
    c.ioSeconds = file_->ioSeconds();
    file_->startReading(diskRows_ - 1);
  }
}

void MultilevelStorage::loadKept(std::size_t index, VectorRef z) {
  const Kept& k = kept_[index];
  if (k.slot >= 0) {
    std::memcpy(z.data(), slots_[static_cast<std::size_t>(k.slot)],
                static_cast<std::size_t>(info().stateSize) * 8);
  } else {
    file_->read(k.row, z.data());
  }
}

void MultilevelStorage::releaseScratch() {
  for (std::int64_t slot : scratch_) releaseSlot(slot);
  scratch_.clear();
}

void MultilevelStorage::doRestore(std::int64_t step, VectorRef z) {
  const std::size_t bytes = static_cast<std::size_t>(info().stateSize) * 8;
  while (kept_[static_cast<std::size_t>(cursor_)].step > step) --cursor_;
  const Kept& checkpoint = kept_[static_cast<std::size_t>(cursor_)];
  if (checkpoint.step == step) {
    loadKept(static_cast<std::size_t>(cursor_), z);
    if (checkpoint.slot >= 0) {  // its last use: the slot serves as scratch from now on
      releaseSlot(checkpoint.slot);
      --slotsInUseByKept_;
    }
    releaseScratch();
  } else if (!scratch_.empty() && step == scratchFirst_ + static_cast<std::int64_t>(scratch_.size()) - 1) {
    std::memcpy(z.data(), slots_[static_cast<std::size_t>(scratch_.back())], bytes);
    releaseSlot(scratch_.back());
    scratch_.pop_back();
  } else {
    // Recompute from the checkpoint to `step`, keeping the states just below `step` that fit.
    releaseScratch();
    const std::int64_t count = std::min(step - checkpoint.step - 1, availableSlots());
    scratchFirst_ = step - count;
    for (std::int64_t i = 0; i < count; ++i) scratch_.push_back(acquireSlot(count - i));
    loadKept(static_cast<std::size_t>(cursor_), z);
    for (std::int64_t i = checkpoint.step; i < step; ++i) {
      recompute(i, z);
      if (i + 1 >= scratchFirst_ && i + 1 < step) {
        std::memcpy(
            slots_[static_cast<std::size_t>(scratch_[static_cast<std::size_t>(i + 1 - scratchFirst_)])],
            z.data(), bytes);
      }
    }
  }
  if (step == 0 && file_) {
    mutableCounters().ioSeconds = file_->ioSeconds();
    closeFile();
  }
}

}  // namespace hindsight
