#include <hindsight/storage/disk_storage.h>

#include <hindsight/storage/chunked_state_file.h>

#include <algorithm>
#include <limits>

namespace hindsight {

bool DiskStorage::Options::IsValid(std::string* error) const {
  std::string message;
  if (directory.empty())
    message = "disk.dir must name a directory";
  else if (compressionLevel < 1 || compressionLevel > 22)
    message = "disk.level = " + std::to_string(compressionLevel) + " must be in [1, 22]";
  else if (chunkStates < 0)
    message = "disk.chunk = " + std::to_string(chunkStates) + " must be positive (or 0 for automatic)";
  else if (budgetBytes <= 0)
    message = "disk.budget = " + std::to_string(budgetBytes) + " must be positive";
  if (error != nullptr) *error = message;
  return message.empty();
}

DiskStorage::DiskStorage(Options options)
    : TrajectoryStorage(std::max<std::int64_t>(1, options.budgetBytes)), options_(std::move(options)) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument(error);
}

DiskStorage::~DiskStorage() { closeFile(); }

std::unique_ptr<TrajectoryStorage> DiskStorage::create(const StorageSpec& spec) {
  Options options;
  options.directory = spec.text("dir", "");
  if (options.directory.empty()) throw std::invalid_argument("disk.dir is required, e.g. disk:dir=/tmp");
  options.compressionLevel = static_cast<int>(spec.integer("level", 3, 1, 22));
  options.chunkStates = spec.integer("chunk", 0, 1, std::int64_t{1} << 30);
  options.budgetBytes = spec.bytes("budget", kDefaultBudget);
  options.keepFile = spec.text("keep", "false", {"true", "false"}) == "true";
  options.timeCodec = spec.text("codec", "time", {"time", "zstd"}) == "time";
  options.stages = spec.integer("stages", 0, 0, 1) == 1;
  return std::make_unique<DiskStorage>(std::move(options));
}

std::string DiskStorage::spec() const {
  std::string text = "disk:dir=" + options_.directory;
  if (options_.compressionLevel != 3) text += ",level=" + std::to_string(options_.compressionLevel);
  if (options_.chunkStates > 0) text += ",chunk=" + std::to_string(options_.chunkStates);
  if (options_.budgetBytes != kDefaultBudget) text += ",budget=" + std::to_string(options_.budgetBytes);
  if (options_.keepFile) text += ",keep=true";
  if (!options_.timeCodec) text += ",codec=zstd";
  if (options_.stages) text += ",stages=1";
  return text;
}

void DiskStorage::closeFile() {
  if (file_) {
    file_->close();
    file_.reset();
  }
  if (heldBytes_ > 0) {
    releaseBytes(std::min(heldBytes_, counters().bytesInMemory));
    heldBytes_ = 0;
  }
}

DiskStorage::Layout DiskStorage::layoutFor(std::int64_t rowDoubles, std::int64_t rows) const {
  const std::int64_t rowBytes = (rowDoubles + 1) * 8;  // ChunkedStateFile::bufferBytes of one row
  std::int64_t chunk = options_.chunkStates;
  if (chunk == 0) {
    chunk = std::clamp<std::int64_t>((std::int64_t{1} << 20) / rowBytes, 1, 4096);
    // The time codec predicts each row from the previous rows of its chunk: at least 16 rows when
    // the budget allows (the full-order rod's rows are 10^4-10^5 doubles).
    if (options_.timeCodec) chunk = std::max<std::int64_t>(chunk, 16);
    chunk = std::min(chunk, std::max<std::int64_t>(1, budgetBytes() / (3 * rowBytes)));
  }
  chunk = std::min(chunk, rows);
  Layout layout;
  layout.chunkStates = chunk;
  // A chunk= beyond what any budget holds saturates (begin() then refuses it by the budget).
  layout.bufferBytes = chunk > std::numeric_limits<std::int64_t>::max() / rowBytes
                           ? std::numeric_limits<std::int64_t>::max()
                           : chunk * rowBytes;
  layout.bufferCount = static_cast<int>(std::clamp<std::int64_t>(budgetBytes() / layout.bufferBytes, 1, 3));
  return layout;
}

void DiskStorage::doBegin() {
  closeFile();
  heldBytes_ = 0;  // begin() has already released everything
  // With step data a row is the state followed by the step's stage values.
  TrajectoryInfo rowInfo = info();
  rowInfo.stateSize = static_cast<int>(info().stateSize + info().stepDataSize);
  row_.assign(info().stepDataSize > 0 ? static_cast<std::size_t>(rowInfo.stateSize) : 0, 0.0);
  const int n = rowInfo.stateSize;
  const std::int64_t rows = info().stepCount >= 0 ? info().stepCount + 1 : std::int64_t{1} << 40;
  const Layout layout = layoutFor(n, rows);
  const std::int64_t chunk = layout.chunkStates;
  const std::int64_t bufferBytes = layout.bufferBytes;
  const int bufferCount = layout.bufferCount;
  holdBytes(bufferCount * bufferBytes);  // throws StorageError when not even one buffer fits
  heldBytes_ = bufferCount * bufferBytes;
  chunkStates_ = chunk;

  internal::StateFileOptions fileOptions;
  fileOptions.directory = options_.directory;
  fileOptions.compressionLevel = options_.compressionLevel;
  fileOptions.chunkStates = chunk;
  fileOptions.bufferCount = bufferCount;
  fileOptions.keepFile = options_.keepFile;
  fileOptions.codec = options_.timeCodec ? internal::StateFileOptions::Codec::kTime
                                         : internal::StateFileOptions::Codec::kZstd;
  fileOptions.failWriteAfterChunks = options_.failWriteAfterChunks;
  file_ = std::make_unique<internal::ChunkedStateFile>(fileOptions, rowInfo);
  filePath_ = file_->path();
}

void DiskStorage::doRecord(std::int64_t, double t, ConstVectorRef z, ConstVectorRef) {
  assert(file_);
  ++mutableCounters().statesStored;
  if (!row_.empty()) {
    std::copy(z.data(), z.data() + z.size(), row_.begin());  // appended with the stage values
    rowTime_ = t;
    return;
  }
  file_->append(t, z.data());
}

void DiskStorage::doRecordStepData(std::int64_t, ConstVectorRef data) {
  std::copy(data.data(), data.data() + data.size(), row_.begin() + info().stateSize);
  file_->append(rowTime_, row_.data());
  ++mutableCounters().stepDataStored;
}

void DiskStorage::doFinish(double t, ConstVectorRef z, ConstVectorRef) {
  assert(file_);
  if (!row_.empty()) {
    std::copy(z.data(), z.data() + z.size(), row_.begin());
    std::fill(row_.begin() + info().stateSize, row_.end(), 0.0);
    file_->append(t, row_.data());  // the final state too, so the file holds the whole trajectory
  } else {
    file_->append(t, z.data());  // the final state too, so the file holds the whole trajectory
  }
  file_->finishWriting(stepCount());
  StorageCounters& c = mutableCounters();
  c.bytesOnDisk = file_->fileBytes();
  c.uncompressedBytes = file_->rows() * (stateBytes() + (row_.empty() ? 0 : stepDataBytes()));
  c.compressedBytes = file_->storedStateBytes();
  c.ioSeconds = file_->ioSeconds();
  if (options_.afterForwardSweep) options_.afterForwardSweep(filePath_);
  if (stepCount() == 0) {
    closeFile();
    return;
  }
  file_->startReading(stepCount() - 1);
}

void DiskStorage::doRestore(std::int64_t step, VectorRef z) {
  assert(file_);
  if (!row_.empty()) {
    file_->read(step, row_.data());
    std::copy(row_.begin(), row_.begin() + z.size(), z.data());
    return;  // restoreStepData(step) follows
  }
  file_->read(step, z.data());
  if (step == 0) {
    mutableCounters().ioSeconds = file_->ioSeconds();
    closeFile();
  }
}

bool DiskStorage::doRestoreStepData(std::int64_t step, VectorRef data) {
  std::copy(row_.begin() + info().stateSize, row_.end(), data.data());
  if (step == 0) {
    mutableCounters().ioSeconds = file_->ioSeconds();
    closeFile();
  }
  return true;
}

}  // namespace hindsight

namespace hindsight {

void DiskStorage::predict(const TrajectoryStorage& storage, const StorageSpec&,
                          const PredictionRequest& request, SchedulePrediction& p) {
  const auto& disk = dynamic_cast<const DiskStorage&>(storage);
  const std::int64_t steps = request.steps;
  // stages=1: every row the state and its step record (S - 1 stage states and S rhs data), every adjoint
  // step served.
  const bool stageRows = disk.options_.stages && prediction::hasStageValues(request.stages);
  const std::int64_t rowDoubles = prediction::stageRowDoubles(request, stageRows, "disk");
  if (stageRows) p.stepDataStored = p.stepDataRestored = steps;
  // The run's own rule (layoutFor): rows N + 1, chunk and buffer count from the budget.
  const DiskStorage::Layout layout =
      disk.layoutFor(rowDoubles, prediction::checkedCount(static_cast<UnsignedInt128>(steps) + 1, "rows"));
  if (layout.bufferBytes > disk.budgetBytes()) {
    throw std::invalid_argument("disk: one chunk buffer of " + formatBytes(layout.bufferBytes) +
                                " exceeds disk.budget = " + formatBytes(disk.budgetBytes()));
  }
  p.plan = "every state on disk, " + std::to_string(layout.chunkStates) + " states per chunk";
  p.statesStored = steps;
  p.diskWrites = prediction::checkedCount(static_cast<UnsignedInt128>(steps) + 1, "disk writes");
  p.diskReads = steps;
  p.peakRamBytes = layout.bufferCount * layout.bufferBytes;
  p.peakDiskBytes = prediction::checkedProduct(p.diskWrites, 8 * rowDoubles, "disk bytes");
}

void DiskStorage::writeActions(const TrajectoryStorage&, const StorageSpec&, const PredictionRequest& request,
                               std::ostream& out) {
  prediction::writeEveryStateActions(request.steps, StorageLevel::kDisk, out);
}

}  // namespace hindsight
