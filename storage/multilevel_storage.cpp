#include <hindsight/storage/multilevel_storage.h>

#include <hindsight/storage/chunked_state_file.h>
#include <hindsight/storage/overlapped_io.h>
#include <hindsight/storage/scratch_files.h>

#include <hindsight/engine/hash.h>
#include <hindsight/engine/interrupt.h>

#include <hindsight/engine/stopwatch.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <optional>
#include <ostream>
#include <sstream>

namespace hindsight {
namespace {
constexpr std::int64_t kSlotsPerBlock = 256;
// Forward steps timed (median) before the plan is chosen, when costs are measured.
constexpr std::int64_t kProbeSteps = 16;
}  // namespace

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

MultilevelStorage::~MultilevelStorage() {
  closeFile();
  removeLevelDirectories();
}

namespace {

// A cost of levels= or costs= (a number in [0, 1e30]); throws naming `field` and the expected form.
double parseCost(const std::string& text, const std::string& field, const std::string& expected) {
  std::size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !(value >= 0.0 && value <= 1e30))
    throw std::invalid_argument(field + " = '" + text + "' must be " + expected);
  return value;
}

// The shortest text that reads back to the same double (the spec round-trips), as ScheduleCosts::text.
std::string costText(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

// levels=NAME:BYTES[:PATH][@WRITE:READ];... (storage/multilevel_storage.h).
std::vector<MultilevelStorage::Options::Level> parseLevels(const std::string& text) {
  const std::string form =
      "NAME:BYTES[:PATH][@WRITE:READ] separated by ';', e.g. levels=ssd:80@1:1;hdd:1600@2:2";
  std::vector<MultilevelStorage::Options::Level> levels;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find(';', start), text.size());
    const std::string item = text.substr(start, end - start);
    start = end + 1;
    MultilevelStorage::Options::Level level;
    const std::size_t at = item.rfind('@');
    const std::string head = item.substr(0, at);
    const std::size_t colon = head.find(':');
    level.name = head.substr(0, colon);
    const std::string field = "multilevel.levels '" + item + "'";
    if (colon == std::string::npos || level.name.empty() ||
        level.name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") !=
            std::string::npos ||
        level.name == "ram") {
      throw std::invalid_argument(field + ": each level is " + form +
                                  " (a name of letters, digits, '_' or '-', not 'ram')");
    }
    for (const auto& other : levels) {
      if (other.name == level.name)
        throw std::invalid_argument("multilevel.levels: level '" + level.name + "' given twice");
    }
    const std::string rest = head.substr(colon + 1);
    const std::size_t pathColon = rest.find(':');
    level.bytes = parseBytes(rest.substr(0, pathColon), "multilevel.levels." + level.name);
    if (level.bytes <= 0) {
      throw std::invalid_argument("multilevel.levels." + level.name + " = " + std::to_string(level.bytes) +
                                  " bytes: a level must hold a positive byte count");
    }
    if (pathColon != std::string::npos) level.path = rest.substr(pathColon + 1);
    if (pathColon != std::string::npos && level.path.empty())
      throw std::invalid_argument(field + ": an empty directory after the bytes; " + form);
    if (at != std::string::npos) {
      const std::string costs = item.substr(at + 1);
      const std::size_t split = costs.find(':');
      const std::string expected = "two costs WRITE:READ in [0, 1e30] (seconds of a write and a read)";
      if (split == std::string::npos)
        throw std::invalid_argument(field + " costs = '" + costs + "' must be " + expected);
      level.write = parseCost(costs.substr(0, split), field + " write", expected);
      level.read = parseCost(costs.substr(split + 1), field + " read", expected);
      level.costed = true;
    }
    levels.push_back(level);
  }
  return levels;
}

}  // namespace

std::unique_ptr<TrajectoryStorage> MultilevelStorage::create(const StorageSpec& spec) {
  if (spec.has("levels")) return createLevels(spec);
  if (!spec.has("ram") || !spec.has("disk")) {
    throw std::invalid_argument(
        "multilevel needs ram= and disk=, e.g. multilevel:ram=64MiB,disk=4GiB, or ram= and levels=, e.g. "
        "multilevel:ram=64MiB,levels=ssd:4GiB;hdd:64GiB");
  }
  Options options;
  options.ramBytes = spec.bytes("ram", 0);
  const std::string disk = spec.text("disk", "");
  if (disk.find_first_of("123456789") == std::string::npos && disk.find('0') != std::string::npos) {
    // "0", "0B", "0KiB": no disk level. Refused with a pointer to the strategies for RAM alone.
    throw std::invalid_argument(
        "multilevel.disk = '" + disk +
        "': multilevel needs a disk level (a positive byte count, e.g. disk=4GiB); for "
        "RAM alone use binomial:checkpoints=C or cams:budget=BYTES");
  }
  options.diskBytes = spec.bytes("disk", 0);
  options.directory = spec.text("dir", "");
  options.compressionLevel = static_cast<int>(spec.integer("level", 3, 1, 22));
  options.keepFile = spec.text("keep", "false", {"true", "false"}) == "true";
  options.stride = spec.text("schedule", "optimal", {"optimal", "stride"}) == "stride";
  if (spec.has("costs")) options.costs = ScheduleCosts::parse(spec.text("costs", ""), "multilevel.costs");
  options.overlap = spec.integer("overlap", 1, 0, 1) == 1;
  options.syncWrites = spec.integer("sync", 0, 0, 1) == 1;
  return std::make_unique<MultilevelStorage>(std::move(options));
}

std::unique_ptr<TrajectoryStorage> MultilevelStorage::createLevels(const StorageSpec& spec) {
  if (spec.has("disk")) {
    throw std::invalid_argument(
        "multilevel: give disk= (two levels) or levels= (K levels), not both; disk=BYTES is "
        "levels=disk:BYTES");
  }
  if (!spec.has("ram"))
    throw std::invalid_argument(
        "multilevel needs ram= with levels=, e.g. multilevel:ram=64MiB,levels=ssd:4GiB");
  Options options;
  options.ramBytes = spec.bytes("ram", 0);
  options.levels = parseLevels(spec.text("levels", ""));
  options.directory = spec.text("dir", "");
  options.compressionLevel = static_cast<int>(spec.integer("level", 3, 1, 22));
  options.keepFile = spec.text("keep", "false", {"true", "false"}) == "true";
  options.stride = spec.text("schedule", "optimal", {"optimal", "stride"}) == "stride";
  std::size_t costed = 0;
  for (const auto& level : options.levels) costed += level.costed ? 1 : 0;
  if (costed != 0 && (costed != options.levels.size() || !spec.has("costs"))) {
    throw std::invalid_argument(
        "multilevel.levels: costs are given completely (every level's @WRITE:READ and costs=uf:ub) or not at "
        "all (measured by the run); " +
        std::to_string(costed) + " of " + std::to_string(options.levels.size()) + " levels have theirs" +
        (spec.has("costs") ? "" : " and costs= is missing"));
  }
  if (spec.has("costs")) {
    const std::string text = spec.text("costs", "");
    const std::string expected =
        "two numbers uf:ub in [0, 1e30] (seconds of a forward and an adjoint step; "
        "each level's write and read follow its size: levels=NAME:BYTES@WRITE:READ), uf > 0";
    const std::size_t split = text.find(':');
    if (split == std::string::npos)
      throw std::invalid_argument("multilevel.costs = '" + text + "' must be " + expected);
    const double uf = parseCost(text.substr(0, split), "multilevel.costs", expected);
    const double ub = parseCost(text.substr(split + 1), "multilevel.costs", expected);
    if (!(uf > 0.0)) throw std::invalid_argument("multilevel.costs = '" + text + "' must be " + expected);
    if (costed == 0) {
      throw std::invalid_argument(
          "multilevel.costs with levels=: give each level's @WRITE:READ too, e.g. "
          "levels=ssd:80@1:1;hdd:1600@2:2,costs=1:1");
    }
    options.costs = ScheduleCosts{uf, ub, options.levels[0].write, options.levels[0].read};
  }
  // The first level is the disk of the two-level form and of the stride.
  options.diskBytes = options.levels[0].bytes;
  return std::make_unique<MultilevelStorage>(std::move(options));
}

std::string MultilevelStorage::levelDirectory(std::size_t k) const {
  const std::string base =
      options_.directory.empty() ? std::filesystem::temp_directory_path().string() : options_.directory;
  if (options_.levels.empty()) return base;
  const Options::Level& level = options_.levels[k - 1];
  return level.path.empty() ? (std::filesystem::path(base) / level.name).string() : level.path;
}

void MultilevelStorage::removeLevelDirectories() const {
  for (std::size_t k = 1; k <= options_.levels.size(); ++k) {
    if (!options_.levels[k - 1].path.empty()) continue;
    std::error_code ec;
    std::filesystem::remove(levelDirectory(k), ec);  // only when empty: a kept file or the user's stay
  }
}

std::string MultilevelStorage::spec() const {
  std::string text = "multilevel:ram=" + std::to_string(options_.ramBytes);
  if (options_.levels.empty()) {
    text += ",disk=" + std::to_string(options_.diskBytes);
  } else {
    text += ",levels=";
    for (std::size_t k = 0; k < options_.levels.size(); ++k) {
      const Options::Level& level = options_.levels[k];
      text += (k ? ";" : "") + level.name + ":" + std::to_string(level.bytes);
      if (!level.path.empty()) text += ":" + level.path;
      if (level.costed) text += "@" + costText(level.write) + ":" + costText(level.read);
    }
  }
  if (!options_.directory.empty()) text += ",dir=" + options_.directory;
  if (options_.compressionLevel != 3) text += ",level=" + std::to_string(options_.compressionLevel);
  if (options_.keepFile) text += ",keep=true";
  if (options_.costs) {
    text += ",costs=" + (options_.levels.empty() ? options_.costs->text()
                                                 : costText(options_.costs->forwardStep) + ":" +
                                                       costText(options_.costs->adjointStep));
  }
  if (options_.stride) text += ",schedule=stride";
  if (!options_.overlap) text += ",overlap=0";
  if (options_.syncWrites) text += ",sync=1";
  return text;
}

void MultilevelStorage::closeFile() {
  if (file_) {
    file_->close();
    file_.reset();
  }
  if (io_) prefetchedReads_ = io_->prefetchedReads();
  io_.reset();  // joins the I/O thread, which uses slotFiles_[0]
  lookahead_.reset();
  slotFiles_.clear();
}

void MultilevelStorage::beginStride() {
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
    slotBlocks_.emplace_back(counting_ ? nullptr : new double[static_cast<std::size_t>(count * n)]);
    for (std::int64_t i = count - 1; i >= 0; --i) {
      freeSlots_.push_back(static_cast<std::int64_t>(slots_.size() + static_cast<std::size_t>(i)));
    }
    for (std::int64_t i = 0; i < count; ++i)
      slots_.push_back(counting_ ? nullptr : slotBlocks_.back().get() + i * n);
  }
  const std::int64_t slot = freeSlots_.back();
  freeSlots_.pop_back();
  return slot;
}

void MultilevelStorage::openFile() {
  internal::StateFileOptions fileOptions;
  fileOptions.directory = levelDirectory(1);
  fileOptions.filePrefix = "hindsight-multilevel";
  fileOptions.compressionLevel = options_.compressionLevel;
  fileOptions.chunkStates = chunkStates_;
  fileOptions.bufferCount = 2;
  fileOptions.keepFile = options_.keepFile;
  fileOptions.failWriteAfterChunks = options_.failWriteAfterChunks;
  file_ = std::make_unique<internal::ChunkedStateFile>(fileOptions, info());
  filePath_ = file_->path();
}

void MultilevelStorage::recordStride(std::int64_t step, double t, ConstVectorRef z) {
  const std::size_t bytes = static_cast<std::size_t>(info().stateSize) * 8;
  while (step % stride_ == 0) {
    if (slotsInUseByKept_ < ramKeptLimit_ && availableSlots() > 0) {
      // A known trajectory needs ceil(N / stride) kept states; an unknown one gets blocks.
      const std::int64_t wanted = info().stepCount >= 0
                                      ? (info().stepCount + stride_ - 1) / stride_ - slotsInUseByKept_
                                      : kSlotsPerBlock;
      const std::int64_t slot = acquireSlot(std::min(wanted, ramKeptLimit_ - slotsInUseByKept_));
      if (!counting_) std::memcpy(slots_[static_cast<std::size_t>(slot)], z.data(), bytes);
      kept_.push_back(Kept{step, slot, -1});
      ++slotsInUseByKept_;
      return;
    }
    if (diskRows_ < diskCapacity_) {
      if (!counting_) {
        if (!file_) openFile();
        file_->append(t, z.data());
      }
      ++diskWrites_;
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

void MultilevelStorage::finishStride() {
  StorageCounters& c = mutableCounters();
  c.statesStored = static_cast<std::int64_t>(kept_.size());
  statesInRam_ = slotsInUseByKept_;
  cursor_ = static_cast<std::int64_t>(kept_.size()) - 1;
  if (counting_) c.uncompressedBytes = diskRows_ * stateBytes();
  if (file_) {
    file_->finishWriting(stepCount());
    c.bytesOnDisk = file_->fileBytes();
    c.uncompressedBytes = diskRows_ * stateBytes();
    c.compressedBytes = file_->storedStateBytes();
    c.ioSeconds = file_->ioSeconds();
    if (options_.afterForwardSweep) options_.afterForwardSweep(filePath_);
    file_->startReading(diskRows_ - 1);
  }
}

void MultilevelStorage::loadKept(std::size_t index, VectorRef z) {
  const Kept& k = kept_[index];
  if (k.slot >= 0) {
    if (!counting_)
      std::memcpy(z.data(), slots_[static_cast<std::size_t>(k.slot)],
                  static_cast<std::size_t>(info().stateSize) * 8);
  } else {
    if (!counting_) file_->read(k.row, z.data());
    ++diskReads_;
  }
}

void MultilevelStorage::releaseScratch() {
  for (std::int64_t slot : scratch_) releaseSlot(slot);
  scratch_.clear();
}

void MultilevelStorage::restoreStride(std::int64_t step, VectorRef z) {
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
    if (!counting_) std::memcpy(z.data(), slots_[static_cast<std::size_t>(scratch_.back())], bytes);
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
      if (i + 1 >= scratchFirst_ && i + 1 < step && !counting_) {
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

// ---- schedule=optimal ----

// The disk level of the plan: fixed-size slots of raw states in one file, written and read in any order
// with pwrite/pread. Written by hand because the plan rewrites slots after reading others, which the
// append-then-read chunked HDF5 file (storage/chunked_state_file.h) does not allow; the file lives for
// one run and is removed at its end unless keep=true.
//
// Slot format: the state's raw doubles, then two native-endian 64-bit words (the file is read only by the
// process that wrote it): the slot's index and the FNV-1a hash (engine/hash.h) of the index and the state's
// bytes. Every read checks both, so a flipped byte, a slot written at another offset or a file truncated or
// overwritten by something else is a StorageError naming the file and the slot, never a restored state (the
// chunked file's Fletcher32 does the same for schedule=stride). The 16 bytes per slot are not charged to
// disk=, which counts the states (as the stride's rows are counted uncompressed).
struct MultilevelStorage::SlotFile {
  static constexpr std::int64_t kTrailerBytes = 16;
  std::string path;
  int fd = -1;
  std::int64_t stateBytes = 0;
  std::int64_t recordBytes = 0;  // stateBytes + kTrailerBytes
  std::int64_t writes = 0;
  std::int64_t failAfter = -1;
  bool keep = false;
  std::vector<char> record;  // one slot, allocated once: reads and writes allocate nothing

  SlotFile(const std::string& directory, std::int64_t bytes, bool keepFile, std::int64_t failWritesAfter,
           bool syncWrites)
      : stateBytes(bytes),
        recordBytes(bytes + kTrailerBytes),
        failAfter(failWritesAfter),
        keep(keepFile),
        record(static_cast<std::size_t>(bytes + kTrailerBytes)) {
    std::error_code ec;
    std::filesystem::create_directories(directory, ec);
    internal::removeStaleScratchFiles(directory);
    path = (std::filesystem::path(directory) /
            internal::scratchFileName("hindsight-multilevel", ".slots", keepFile))
               .string();
    fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC | (syncWrites ? O_DSYNC : 0), 0600);
    if (fd < 0)
      throw StorageError("multilevel: cannot create the disk level: " + std::string(std::strerror(errno)),
                         path);
  }
  ~SlotFile() {
    if (fd >= 0) ::close(fd);
    if (!keep) ::unlink(path.c_str());
  }
  SlotFile(const SlotFile&) = delete;
  SlotFile& operator=(const SlotFile&) = delete;

  static std::uint64_t checksum(std::uint64_t slot, const char* state, std::int64_t bytes) {
    return fnv1a(state, static_cast<std::size_t>(bytes), fnv1a(&slot, sizeof slot));
  }

  void write(std::int64_t slot, const double* z) {
    if (failAfter >= 0 && writes >= failAfter) {
      throw StorageError(
          "multilevel: writing slot " + std::to_string(slot) + " failed: " + std::strerror(ENOSPC), path);
    }
    ++writes;
    const std::uint64_t trailer[2] = {
        static_cast<std::uint64_t>(slot),
        checksum(static_cast<std::uint64_t>(slot), reinterpret_cast<const char*>(z), stateBytes)};
    std::memcpy(record.data(), z, static_cast<std::size_t>(stateBytes));
    std::memcpy(record.data() + stateBytes, trailer, sizeof trailer);
    std::int64_t done = 0;
    while (done < recordBytes) {
      const ssize_t n = ::pwrite(fd, record.data() + done, static_cast<std::size_t>(recordBytes - done),
                                 slot * recordBytes + done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        throw StorageError("multilevel: writing slot " + std::to_string(slot) +
                               " failed: " + std::strerror(n < 0 ? errno : ENOSPC),
                           path);
      }
      done += n;
    }
  }
  void read(std::int64_t slot, double* z) {
    std::int64_t done = 0;
    while (done < recordBytes) {
      const ssize_t n = ::pread(fd, record.data() + done, static_cast<std::size_t>(recordBytes - done),
                                slot * recordBytes + done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        throw StorageError("multilevel: reading slot " + std::to_string(slot) + " failed: " +
                               (n < 0 ? std::string(std::strerror(errno)) : std::string("file truncated")),
                           path);
      }
      done += n;
    }
    std::uint64_t trailer[2];
    std::memcpy(trailer, record.data() + stateBytes, sizeof trailer);
    if (trailer[0] != static_cast<std::uint64_t>(slot) ||
        trailer[1] != checksum(static_cast<std::uint64_t>(slot), record.data(), stateBytes)) {
      throw StorageError(
          "multilevel: slot " + std::to_string(slot) +
              " of the disk level is corrupted (its checksum does not match the state read back); "
              "the file was changed while the run used it",
          path);
    }
    std::memcpy(z, record.data(), static_cast<std::size_t>(stateBytes));
  }
  std::int64_t size() const {
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(path, ec);
    return ec ? 0 : static_cast<std::int64_t>(bytes);
  }
};

MultilevelStorage::Layout MultilevelStorage::layoutFor(std::int64_t, int stateSize) const {
  const std::int64_t bytes = static_cast<std::int64_t>(stateSize) * 8;
  Layout layout{budgetBytes() / bytes, options_.diskBytes / bytes, {}};
  for (const Options::Level& level : options_.levels) layout.levelSlots.push_back(level.bytes / bytes);
  return layout;
}

void MultilevelStorage::doBegin() {
  closeFile();
  usesPlan_ = false;
  ramPool_.reset();
  poolSlots_ = 0;
  probeSteps_ = 0;
  probeTimes_.clear();
  recomputeSeconds_ = 0.0;
  slotIoSeconds_ = 0.0;
  diskWrites_ = 0;
  diskReads_ = 0;
  backwardSweep_ = false;
  hiddenSeconds_ = 0.0;
  prefetchedReads_ = 0;
  levelPlan_.reset();
  const std::size_t below = usesLevels() ? options_.levels.size() : 1;
  levelWrites_.assign(below, 0);
  levelReads_.assign(below, 0);
  levelRows_.assign(below, 0);
  if (options_.stride || info().stepCount < 0) {
    beginStride();
    return;
  }
  beginPlan();
}

void MultilevelStorage::beginPlan() {
  usesPlan_ = true;
  stride_ = 1;
  kept_.clear();
  diskRows_ = 0;
  statesInRam_ = 0;
  filePath_.clear();
  const std::int64_t steps = info().stepCount;
  const Layout layout = layoutFor(steps, info().stateSize);
  planRamSlots_ = layout.ramSlots;
  planDiskSlots_ = layout.diskSlots;
  std::int64_t below = planDiskSlots_;
  if (usesLevels()) {
    below = 0;
    levelsInUse_.clear();
    for (std::size_t k = 0; k < options_.levels.size(); ++k) {
      const Options::Level& level = options_.levels[k];
      levelsInUse_.push_back(StorageLevelCosts{layout.levelSlots[k], level.write, level.read});
      below += layout.levelSlots[k];
    }
    if (steps > kMaxLevelSteps) {
      throw StorageError("storage '" + spec() + "' plans " + std::to_string(options_.levels.size() + 1) +
                         " levels for up to 2^24 fixed steps, not " + std::to_string(steps) +
                         "; use two levels (disk=) or schedule=stride");
    }
  }
  if (planRamSlots_ < 1 || (steps >= 2 && planRamSlots_ + below < 2)) {
    throw StorageError("storage '" + spec() + "' cannot reverse " + std::to_string(steps) +
                       " steps: RAM holds " + std::to_string(planRamSlots_) +
                       (usesLevels() ? " and the levels below " : " and disk ") + std::to_string(below) +
                       " states of " + formatBytes(stateBytes()) +
                       (usesLevels() ? "; RAM must hold one state and all levels two; raise ram or levels"
                                     : "; RAM must hold one state and both levels two; raise ram or disk"));
  }
  if (options_.costs || steps == 1 || below == 0) {
    // Costs given, or nothing to choose (without disk slots every plan is revolve in RAM).
    choosePlan(options_.costs ? *options_.costs : ScheduleCosts{});
    return;
  }
  // Measure: a disk write and read now, the forward step from the first records (buffered in the top
  // slots of the RAM pool until the plan is chosen; the plan's first records use the bottom ones).
  ScheduleCosts measured;
  if (usesLevels()) {
    for (std::size_t k = 0; k < levelsInUse_.size(); ++k) {
      if (levelsInUse_[k].slots > 0)
        std::tie(levelsInUse_[k].write, levelsInUse_[k].read) = measureLevelCosts(levelDirectory(k + 1));
    }
  } else {
    measureDiskCosts(measured);
  }
  costsInUse_ = measured;
  // The probe states wait in the top RAM slots while the plan's first stores use the bottom ones, so at
  // most half the slots beside the first. One state always fits: with one or two RAM slots the single probe
  // state is copied out (below) before the plan stores anything, so even then the run plans by measured
  // costs -- the stride it used to fall back to here recomputed up to a thousand times more.
  probeSteps_ =
      std::min<std::int64_t>({kProbeSteps, steps - 1, std::max<std::int64_t>(1, (planRamSlots_ - 1) / 2)});
  poolSlots_ = planRamSlots_;
  holdBytes(poolSlots_ * stateBytes());
  ramPool_.reset(new double[static_cast<std::size_t>(poolSlots_ * info().stateSize)]);
}

void MultilevelStorage::measureDiskCosts(ScheduleCosts& costs) {
  std::tie(costs.diskWrite, costs.diskRead) = measureLevelCosts(levelDirectory(1));
}

std::pair<double, double> MultilevelStorage::measureLevelCosts(const std::string& directory) {
  SlotFile probe(directory, stateBytes(), false, -1, options_.syncWrites);
  std::vector<double> state(static_cast<std::size_t>(info().stateSize), 0.0);
  std::vector<double> writes, reads;
  for (int i = 0; i < 5; ++i) {
    Stopwatch watch;
    probe.write(0, state.data());
    writes.push_back(watch.restart());
    probe.read(0, state.data());
    reads.push_back(watch.seconds());
  }
  std::sort(writes.begin(), writes.end());
  std::sort(reads.begin(), reads.end());
  return {writes[2], reads[2]};
}

void MultilevelStorage::choosePlan(const ScheduleCosts& costs) {
  costsInUse_ = costs;
  const std::int64_t steps = info().stepCount;
  std::int64_t ramUsed = 0;
  std::vector<std::int64_t> used;  // slots of each level below RAM the plan uses at the most
  if (usesLevels()) {
    levelPlan_ = KLevelPlan::choose(steps, planRamSlots_, levelsInUse_, costs.forwardStep);
    levelPlan_->rewind();
    ramUsed = levelPlan_->slotsUsed()[0];
    used.assign(levelPlan_->slotsUsed().begin() + 1, levelPlan_->slotsUsed().end());
  } else {
    plan_ = TwoLevelPlan::choose(steps, planRamSlots_, planDiskSlots_, costs);
    plan_.rewind();
    ramUsed = plan_.ramSlotsUsed();
    used.push_back(plan_.diskSlotsUsed());
  }
  if (!ramPool_) {
    poolSlots_ = ramUsed;
    holdBytes(poolSlots_ * stateBytes());
    ramPool_.reset(new double[static_cast<std::size_t>(poolSlots_ * info().stateSize)]);
  }
  slotFiles_.clear();
  slotFiles_.resize(used.size());
  for (std::size_t k = 0; k < used.size(); ++k) {
    if (used[k] == 0) continue;
    slotFiles_[k] = std::make_unique<SlotFile>(levelDirectory(k + 1), stateBytes(), options_.keepFile,
                                               options_.failWriteAfterChunks, options_.syncWrites);
    if (filePath_.empty()) filePath_ = slotFiles_[k]->path;
  }
  // Write-behind and read-ahead (storage/overlapped_io.h) on the one level below RAM of the two-level plan;
  // with three or more levels every write and read waits.
  if (options_.overlap && !levelPlan_ && !slotFiles_.empty() && slotFiles_[0]) {
    SlotFile& file = *slotFiles_[0];
    io_ = std::make_unique<internal::OverlappedSlotIo>(
        info().stateSize, internal::OverlappedSlotIo::kDefaultQueueDepth,
        [&file](std::int64_t slot, const double* z) { file.write(slot, z); },
        [&file](std::int64_t slot, double* z) { file.read(slot, z); });
    lookahead_ = std::make_unique<internal::DiskEventLookahead>(plan_);
    hiddenSeconds_ =
        internal::hiddenDiskSeconds(plan_, costs, internal::OverlappedSlotIo::kDefaultQueueDepth);
  }
}

void MultilevelStorage::startNextRead() {
  // The rule of storage/overlapped_io.h: when the plan's next disk event is a read, start it now.
  const internal::DiskEvent* next = lookahead_->peek();
  if (next != nullptr && next->read) io_->prefetch(next->slot);
}

// The plan's actions on the RAM pool and the levels' slot files: levels as KLevelPlan's ints (0 = RAM) or
// TwoLevelPlan's StorageLevel. Forward sweep: `recorded` is the recorded state; backward: `z` the state at
// hand.
struct MultilevelStorage::PlanVisitor {
  MultilevelStorage& self;
  const double* recorded;
  VectorRef* z;
  static int index(StorageLevel level) { return level == StorageLevel::kRam ? 0 : 1; }
  void store(int level, std::int64_t slot) {
    self.storeSlot(level, slot, recorded != nullptr ? recorded : z->data());
    if (recorded != nullptr) ++self.mutableCounters().statesStored;
  }
  void store(StorageLevel level, std::int64_t slot) { store(index(level), slot); }
  void load(int level, std::int64_t slot) {
    if (z != nullptr) self.loadSlot(level, slot, z->data());
  }
  void load(StorageLevel level, std::int64_t slot) { load(index(level), slot); }
  void advance(std::int64_t from, std::int64_t to) {
    if (z == nullptr) return;
    Stopwatch watch;
    for (std::int64_t k = from; k < to; ++k) self.recompute(k, *z);
    self.recomputeSeconds_ += watch.seconds();
  }
};

void MultilevelStorage::storeSlot(int level, std::int64_t slot, const double* z) {
  const std::size_t n = static_cast<std::size_t>(info().stateSize);
  if (level == 0) {
    std::memcpy(ramPool_.get() + static_cast<std::size_t>(slot) * n, z, n * 8);
    return;
  }
  const std::size_t k = static_cast<std::size_t>(level - 1);
  Stopwatch watch;
  if (io_) {  // the two-level plan's one level below RAM
    lookahead_->pop(internal::DiskEvent{false, slot});
    io_->write(slot, z);
    if (backwardSweep_) startNextRead();
  } else {
    slotFiles_[k]->write(slot, z);
  }
  slotIoSeconds_ += watch.seconds();
  ++diskWrites_;
  ++levelWrites_[k];
  if (slot + 1 > levelRows_[k]) {  // the plan also writes while reversing
    diskRows_ += slot + 1 - levelRows_[k];
    levelRows_[k] = slot + 1;
  }
}

void MultilevelStorage::loadSlot(int level, std::int64_t slot, double* z) {
  const std::size_t n = static_cast<std::size_t>(info().stateSize);
  if (level == 0) {
    std::memcpy(z, ramPool_.get() + static_cast<std::size_t>(slot) * n, n * 8);
    return;
  }
  const std::size_t k = static_cast<std::size_t>(level - 1);
  Stopwatch watch;
  if (io_) {
    lookahead_->pop(internal::DiskEvent{true, slot});
    io_->read(slot, z);
    startNextRead();
  } else {
    slotFiles_[k]->read(slot, z);
  }
  slotIoSeconds_ += watch.seconds();
  ++diskReads_;
  ++levelReads_[k];
}

void MultilevelStorage::recordPlanned(std::int64_t step, const double* z) {
  PlanVisitor visitor{*this, z, nullptr};
  if (levelPlan_)
    levelPlan_->recordForward(step, visitor);
  else
    plan_.recordForward(step, visitor);
}

void MultilevelStorage::doRecord(std::int64_t step, double t, ConstVectorRef z, ConstVectorRef) {
  if (!usesPlan_) {
    recordStride(step, t, z);
    return;
  }
  const std::size_t n = static_cast<std::size_t>(info().stateSize);
  if (probeSteps_ > 0) {
    probeTimes_.push_back(std::chrono::duration<double>(Stopwatch::Clock::now().time_since_epoch()).count());
    if (step < probeSteps_) {
      std::memcpy(ramPool_.get() + static_cast<std::size_t>(poolSlots_ - 1 - step) * n, z.data(), n * 8);
      return;
    }
    // step == probeSteps_: the forward step is the median of the intervals between records.
    std::vector<double> intervals;
    for (std::size_t i = 1; i < probeTimes_.size(); ++i)
      intervals.push_back(probeTimes_[i] - probeTimes_[i - 1]);
    std::sort(intervals.begin(), intervals.end());
    ScheduleCosts measured = costsInUse_;
    const std::size_t m = intervals.size();
    measured.forwardStep =
        std::max(1e-9, m % 2 ? intervals[m / 2] : 0.5 * (intervals[m / 2 - 1] + intervals[m / 2]));
    measured.adjointStep = 0.0;  // not measurable before the backward sweep; it does not change the plan
    choosePlan(measured);
    std::vector<double> state(n);
    for (std::int64_t k = 0; k < probeSteps_; ++k) {
      std::memcpy(state.data(), ramPool_.get() + static_cast<std::size_t>(poolSlots_ - 1 - k) * n, n * 8);
      recordPlanned(k, state.data());
    }
    probeSteps_ = 0;
  }
  recordPlanned(step, z.data());
}

void MultilevelStorage::doFinish(double, ConstVectorRef, ConstVectorRef) {
  if (!usesPlan_) {
    finishStride();
    return;
  }
  if (io_) {
    Stopwatch watch;
    io_->drain();  // every write on disk (and any failure thrown) before the file is complete
    slotIoSeconds_ += watch.seconds();
  }
  StorageCounters& c = mutableCounters();
  c.bytesOnDisk = 0;
  for (const auto& file : slotFiles_) c.bytesOnDisk += file ? file->size() : 0;
  c.ioSeconds = slotIoSeconds_;
  statesInRam_ = 0;
  for (const auto& file : slotFiles_) {
    if (file && options_.afterForwardSweep) options_.afterForwardSweep(file->path);
  }
  backwardSweep_ = true;
  if (io_) startNextRead();
}

void MultilevelStorage::doRestore(std::int64_t step, VectorRef z) {
  if (!usesPlan_) {
    restoreStride(step, z);
    return;
  }
  PlanVisitor visitor{*this, nullptr, &z};
  if (levelPlan_)
    levelPlan_->restoreStep(step, visitor);
  else
    plan_.restoreStep(step, visitor);
  if (step == 0) {
    mutableCounters().ioSeconds = slotIoSeconds_;
    mutableCounters().predictedSeconds = predictedSeconds();
    mutableCounters().scheduleSeconds = measuredSeconds();
    closeFile();
    removeLevelDirectories();
    releaseBytes(poolSlots_ * stateBytes());
    ramPool_.reset();
    poolSlots_ = 0;
  }
}

}  // namespace hindsight

namespace hindsight {

namespace {

// The stride's recomputations, counted by TrajectoryStorage::recompute and not carried out. The stride
// recomputes each segment once when its scratch fits and in rounds otherwise, so the walk is bounded
// by a work limit instead of N alone.
class CountingRecomputer final : public StepRecomputer {
 public:
  void advance(std::int64_t, VectorRef) override {
    if (++advances_ > kMaxAdvances) {
      throw std::invalid_argument(
          "multilevel.schedule = stride is predicted by walking its recomputations, at most 2^32 of them; "
          "this one recomputes more (raise ram or disk, or lower --steps)");
    }
    if ((advances_ & 0xffffff) == 0) pollInterrupt();
  }

 private:
  static constexpr std::int64_t kMaxAdvances = std::int64_t{1} << 32;
  std::int64_t advances_ = 0;
};

}  // namespace

void MultilevelStorage::predictStride(const Options& options, const PredictionRequest& request,
                                      SchedulePrediction& p) {
  // The stride's own code (beginStride, recordStride, finishStride, restoreStride) on a copy in counting
  // mode, driven through the storage interface as the engine drives it: N records, finish, N restores.
  if (request.steps > prediction::kMaxWalkedSteps) {
    throw std::invalid_argument(
        "multilevel.schedule = stride is predicted up to --steps = " +
        std::to_string(prediction::kMaxWalkedSteps) +
        " (2^24; its placement is walked step by step); --steps = " + std::to_string(request.steps));
  }
  MultilevelStorage counter(options);
  counter.counting_ = true;
  counter.setVerifyRestores(false);
  TrajectoryInfo info;
  info.problemName = "hindsight schedule";
  info.stateSize = static_cast<int>(request.stateBytes / 8);
  info.t1 = static_cast<double>(request.steps);
  info.stepCount = request.steps;
  CountingRecomputer recomputer;
  const Vector z = Vector::Zero(info.stateSize);
  Vector restored(info.stateSize);
  counter.begin(info, recomputer);
  for (std::int64_t k = 0; k < request.steps; ++k) {
    if ((k & 0xffff) == 0) pollInterrupt();
    counter.record(k, static_cast<double>(k), z, z);
  }
  counter.finish(request.steps, static_cast<double>(request.steps), z, z);
  for (std::int64_t e = request.steps - 1; e >= 0; --e) {
    if ((e & 0xffff) == 0) pollInterrupt();
    counter.restore(e, restored);
  }
  const StorageCounters& c = counter.counters();
  p.plan =
      "stride " + std::to_string(counter.stride()) + ": " + std::to_string(counter.statesInRam()) +
      " kept states in RAM, " + std::to_string(counter.statesOnDisk()) +
      " on disk, the states between recomputed into the free RAM slots (in rounds where they do not all fit)";
  p.recomputedSteps = c.recomputedSteps;
  p.statesStored = c.statesStored;
  p.ramWrites = -1;  // scratch copies are not counted by the run either
  p.ramReads = -1;
  p.diskWrites = counter.diskWrites();
  p.diskReads = counter.diskReads();
  p.peakRamBytes = c.peakBytesInMemory;
  p.peakDiskBytes = c.uncompressedBytes;
}

ScheduleCosts MultilevelStorage::planningCosts(const Options& options, const PredictionRequest& request,
                                               const Layout& layout) {
  // As beginPlan: the spec's own costs first; without them a run measures its costs (--costs stands for
  // them), except when there is nothing to choose (one step, or no disk slot: every plan is revolve in
  // RAM), where it plans by 1:1:0:0.
  if (options.costs) return *options.costs;
  if (request.steps == 1 || layout.diskSlots == 0) return ScheduleCosts{};
  if (request.costs == nullptr)
    throw std::invalid_argument(
        "multilevel plans by its costs: give --costs uf:ub:wd:rd or costs= in the spec");
  return *request.costs;
}

void MultilevelStorage::warnAgainstStride(const Layout& layout, const PredictionRequest& request,
                                          SchedulePrediction& p) {
  // The trap rule (docs/theory/storage.md, "No silent trap"): a prediction more than twice as dear as a
  // simple alternative names it. For the stride that alternative is the plan schedule=optimal would run
  // with the same levels, under the same cost model (the spec's costs=, else --costs, else 1:1:0:0).
  if (layout.ramSlots < 1 || (request.steps >= 2 && layout.ramSlots + layout.diskSlots < 2)) return;
  const double stride = static_cast<double>(p.recomputedSteps) * p.costs.forwardStep +
                        static_cast<double>(p.diskWrites) * p.costs.diskWrite +
                        static_cast<double>(p.diskReads) * p.costs.diskRead;
  std::optional<TwoLevelPlan> chosen;
  try {
    chosen = TwoLevelPlan::choose(request.steps, layout.ramSlots, layout.diskSlots, p.costs);
  } catch (const std::invalid_argument&) {
    return;  // no plan counted for these levels: no alternative to name
  }
  const TwoLevelPlan& plan = *chosen;
  const double optimal = plan.counts().cost(p.costs);
  if (stride > kTrapFactor * optimal) {
    std::ostringstream text;
    text << "schedule=stride costs " << stride << " (recomputation + disk I/O, costs " << p.costs.text()
         << "), more than " << kTrapFactor << " times schedule=optimal's " << optimal << " ("
         << plan.counts().recomputedSteps << " recomputed steps: " << plan.describe()
         << "); drop schedule=stride";
    p.warning = text.str();
  }
}

TwoLevelPlan MultilevelStorage::fixedStepPlan(const TrajectoryStorage& storage,
                                              const PredictionRequest& request) {
  const auto& multilevel = dynamic_cast<const MultilevelStorage&>(storage);
  if (multilevel.usesLevels()) {
    throw std::invalid_argument(
        "multilevel with levels= of two or more levels below RAM has no two-level plan (and no action "
        "stream yet): use one level, or disk=");
  }
  const std::int64_t steps = request.steps, stateBytes = request.stateBytes;
  const Layout layout = multilevel.layoutFor(steps, static_cast<int>(stateBytes / 8));
  // The run's own check (MultilevelStorage::beginPlan), in the flags' words: the plan's message would
  // name neither the levels nor the state size.
  if (layout.ramSlots < 1 || (steps >= 2 && layout.ramSlots + layout.diskSlots < 2)) {
    throw std::invalid_argument(
        "multilevel.ram = " + formatBytes(multilevel.budgetBytes()) +
        " and multilevel.disk = " + formatBytes(multilevel.options().diskBytes) + " hold " +
        std::to_string(layout.ramSlots) + " and " + std::to_string(layout.diskSlots) +
        " states of --state-bytes = " + formatBytes(stateBytes) + " for --steps = " + std::to_string(steps) +
        "; RAM must hold one state and both levels two: raise ram or disk");
  }
  // The plan a run executes (doBegin), chosen by the costs predict() counts it with.
  return TwoLevelPlan::choose(steps, layout.ramSlots, layout.diskSlots,
                              planningCosts(multilevel.options(), request, layout));
}

namespace {

// KLevelPlan::lowerBound for `hindsight schedule --bound`, its errors in the flag's words.
double boundOf(std::int64_t steps, std::int64_t ramSlots, const std::vector<StorageLevelCosts>& levels,
               double forwardStep) {
  try {
    return KLevelPlan::lowerBound(steps, ramSlots, levels, forwardStep).bound;
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--bound: ") + e.what());
  }
}

}  // namespace

void MultilevelStorage::predict(const TrajectoryStorage& storage, const StorageSpec&,
                                const PredictionRequest& request, SchedulePrediction& p) {
  const auto& multilevel = dynamic_cast<const MultilevelStorage&>(storage);
  const std::int64_t steps = request.steps, stateBytes = request.stateBytes;
  const int n = static_cast<int>(stateBytes / 8);
  // The spec's own costs take precedence over --costs (already in p), as in a run, for both schedules.
  if (multilevel.options().costs) p.costs = *multilevel.options().costs;
  // For a prediction the sizes are the input: a level that cannot hold the states is named as flags.
  const std::string levels = "multilevel.ram = " + formatBytes(multilevel.budgetBytes()) +
                             " and multilevel.disk = " + formatBytes(multilevel.options().diskBytes);
  const Layout layout = multilevel.layoutFor(steps, n);
  if (multilevel.options().stride) {
    try {
      predictStride(multilevel.options(), request, p);
    } catch (const StorageError& e) {  // a run would fail at its start
      throw std::invalid_argument(levels + " with --state-bytes = " + formatBytes(stateBytes) + ": " +
                                  e.what());
    }
    warnAgainstStride(layout, request, p);
    if (request.lowerBound) {
      throw std::invalid_argument(
          "--bound: multilevel.schedule = stride takes scratch rounds, not a plan of H-Revolve's family; "
          "bound the default schedule (no schedule=)");
    }
    return;
  }
  if (multilevel.usesLevels()) {
    predictLevels(multilevel, request, layout, p);
    return;
  }
  const ScheduleCosts costs = planningCosts(multilevel.options(), request, layout);
  TwoLevelPlan plan = fixedStepPlan(storage, request);
  p.plan = plan.describe();
  // A run with overlap=1 hides part of its disk I/O: the same model the run's predictedSeconds() uses.
  if (multilevel.options().overlap) {
    p.hiddenIoCost = internal::hiddenDiskSeconds(plan, costs, internal::OverlappedSlotIo::kDefaultQueueDepth);
    if (p.hiddenIoCost > 0.0) p.plan += "; disk I/O overlapped with computation (write-behind, read-ahead)";
  }
  if (request.lowerBound) {
    p.lowerBound =
        boundOf(steps, layout.ramSlots,
                {StorageLevelCosts{layout.diskSlots, costs.diskWrite, costs.diskRead}}, costs.forwardStep);
  }
  const TwoLevelPlan::Counts& c = plan.counts();
  p.recomputedSteps = c.recomputedSteps;
  p.statesStored = c.statesStored;
  p.ramWrites = c.ramWrites;
  p.ramReads = c.ramReads;
  p.diskWrites = c.diskWrites;
  p.diskReads = c.diskReads;
  if (p.ramWrites < 0 && steps <= TwoLevelPlan::kMaxSimulatedSteps) {
    // The RAM copies of the leaves plan, by running the plan the strategy runs with a counting visitor.
    const TwoLevelPlan::Counts walked = plan.walk();
    p.ramWrites = walked.ramWrites;
    p.ramReads = walked.ramReads;
  }
  p.peakRamBytes = prediction::checkedProduct(plan.ramSlotsUsed(), stateBytes, "peak RAM bytes");
  p.peakDiskBytes = prediction::checkedProduct(plan.diskSlotsUsed(), stateBytes, "peak disk bytes");
}

KLevelPlan MultilevelStorage::levelPlanFor(const MultilevelStorage& multilevel,
                                           const PredictionRequest& request, const Layout& layout,
                                           ScheduleCosts& costs, std::vector<StorageLevelCosts>* levelsOut) {
  // As beginPlan: the spec's costs, else nothing to choose (one step, or no slot below RAM) and 1:1 with
  // free levels; --costs has four numbers (two levels) and cannot stand for the K levels' measured costs.
  const Options& options = multilevel.options();
  const std::string levels =
      "multilevel.ram = " + formatBytes(multilevel.budgetBytes()) + " and multilevel.levels";
  std::vector<StorageLevelCosts> below;
  std::int64_t slots = 0;
  for (std::size_t k = 0; k < options.levels.size(); ++k) {
    below.push_back(StorageLevelCosts{layout.levelSlots[k], options.levels[k].write, options.levels[k].read});
    slots += layout.levelSlots[k];
  }
  const std::int64_t steps = request.steps;
  if (layout.ramSlots < 1 || (steps >= 2 && layout.ramSlots + slots < 2)) {
    throw std::invalid_argument(levels + " hold " + std::to_string(layout.ramSlots) + " and " +
                                std::to_string(slots) + " states of --state-bytes = " +
                                formatBytes(request.stateBytes) + " for --steps = " + std::to_string(steps) +
                                "; RAM must hold one state and all levels two: raise ram or levels");
  }
  if (steps > kMaxLevelSteps) {
    throw std::invalid_argument(std::to_string(options.levels.size() + 1) +
                                " levels (multilevel.levels) are planned for --steps up to 2^24 = " +
                                std::to_string(kMaxLevelSteps) + "; --steps = " + std::to_string(steps));
  }
  if (options.costs) {
    costs = *options.costs;
  } else if (steps == 1 || slots == 0) {
    costs = ScheduleCosts{};
  } else {
    throw std::invalid_argument(
        "multilevel with levels= plans by its costs: give costs=uf:ub and each level's @WRITE:READ in the "
        "spec "
        "(--costs describes two levels)");
  }
  if (levelsOut != nullptr) *levelsOut = below;
  return KLevelPlan::choose(steps, layout.ramSlots, below, costs.forwardStep);
}

void MultilevelStorage::predictLevels(const MultilevelStorage& multilevel, const PredictionRequest& request,
                                      const Layout& layout, SchedulePrediction& p) {
  ScheduleCosts costs;
  std::vector<StorageLevelCosts> below;
  const KLevelPlan plan = levelPlanFor(multilevel, request, layout, costs, &below);
  p.costs = ScheduleCosts{costs.forwardStep, costs.adjointStep, 0.0, 0.0};
  if (request.lowerBound) p.lowerBound = boundOf(request.steps, layout.ramSlots, below, costs.forwardStep);
  p.plan = plan.describe();
  const KLevelPlan::Counts& c = plan.counts();
  p.recomputedSteps = c.recomputedSteps;
  p.statesStored = c.forwardStores;
  p.ramWrites = c.writes[0];
  p.ramReads = c.reads[0];
  p.diskWrites = 0;
  p.diskReads = 0;
  p.peakDiskBytes = 0;
  p.levels.clear();
  const std::vector<Options::Level>& levels = multilevel.options().levels;
  for (std::size_t k = 1; k < c.writes.size(); ++k) {
    LevelTraffic level;
    level.name = levels[k - 1].name;
    level.writes = c.writes[k];
    level.reads = c.reads[k];
    level.peakBytes = prediction::checkedProduct(plan.slotsUsed()[k], request.stateBytes, "peak level bytes");
    level.write = levels[k - 1].write;
    level.read = levels[k - 1].read;
    if (!multilevel.options().costs) level.write = level.read = 0.0;  // nothing to choose: free levels
    p.diskWrites += level.writes;
    p.diskReads += level.reads;
    p.peakDiskBytes += level.peakBytes;
    p.levels.push_back(level);
  }
  p.peakRamBytes = prediction::checkedProduct(plan.slotsUsed()[0], request.stateBytes, "peak RAM bytes");
}

void MultilevelStorage::writeActions(const TrajectoryStorage& storage, const StorageSpec&,
                                     const PredictionRequest& request, std::ostream& out) {
  const auto& multilevel = dynamic_cast<const MultilevelStorage&>(storage);
  if (multilevel.usesLevels()) {
    throw std::invalid_argument(
        "--actions prints plans of RAM and disk; multilevel with three or more levels (levels=) has no "
        "action "
        "stream yet (its counts are printed without --actions)");
  }
  const std::int64_t steps = request.steps;
  if (multilevel.options().stride) {
    throw std::invalid_argument(
        "--actions prints two-level plans; multilevel.schedule = stride's scratch rounds are not a plan "
        "(print "
        "its counts without --actions)");
  }
  TwoLevelPlan plan = fixedStepPlan(storage, request);
  prediction::ActionWriter writer{out};
  for (std::int64_t k = 0; k < steps; ++k) {
    out << "record " << k << '\n';
    plan.recordForward(k, writer);
  }
  for (std::int64_t e = steps - 1; e >= 0; --e) {
    out << "restore " << e << '\n';
    plan.restoreStep(e, writer);
  }
}

}  // namespace hindsight
