#include <hindsight/storage/chunked_state_file.h>
#include <hindsight/storage/scratch_files.h>

#include <hindsight/engine/stopwatch.h>
#include <hindsight/storage/hdf5.h>
#include <hindsight/storage/time_codec.h>

#include <zstd.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

namespace hindsight::internal {
namespace {

constexpr H5Z_filter_t kZstdFilterId = 32015;

// The zstd filter in the convention of the registered plugin (id 32015): cd_values[0] is the level,
// each chunk is one zstd frame with its content size.
size_t zstdFilter(unsigned flags, size_t cdCount, const unsigned cdValues[], size_t nbytes,
                  size_t* bufferSize, void** buffer) {
  if (flags & H5Z_FLAG_REVERSE) {
    const unsigned long long size = ZSTD_getFrameContentSize(*buffer, nbytes);
    if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN) return 0;
    void* out = H5allocate_memory(static_cast<size_t>(size), false);
    if (out == nullptr) return 0;
    const size_t result = ZSTD_decompress(out, static_cast<size_t>(size), *buffer, nbytes);
    if (ZSTD_isError(result) || result != size) {
      H5free_memory(out);
      return 0;
    }
    H5free_memory(*buffer);
    *buffer = out;
    *bufferSize = static_cast<size_t>(size);
    return result;
  }
  const int level = cdCount > 0 ? static_cast<int>(cdValues[0]) : 3;
  const size_t bound = ZSTD_compressBound(nbytes);
  void* out = H5allocate_memory(bound, false);
  if (out == nullptr) return 0;
  const size_t result = ZSTD_compress(out, bound, *buffer, nbytes, level);
  if (ZSTD_isError(result)) {
    H5free_memory(out);
    return 0;
  }
  H5free_memory(*buffer);
  *buffer = out;
  *bufferSize = bound;
  return result;
}

const H5Z_class2_t kZstdClass = {H5Z_CLASS_T_VERS,   kZstdFilterId, 1,       1,
                                 "zstd (hindsight)", nullptr,       nullptr, &zstdFilter};

}  // namespace

bool ensureZstdFilter() {
  static std::once_flag once;
  static bool available = false;
  std::call_once(once, [] {
    const hdf5::ErrorSilencer quiet;
    if (H5Zfilter_avail(kZstdFilterId) > 0) {
      available = true;
    } else {
      available = H5Zregister(&kZstdClass) >= 0;
    }
    H5Eclear2(H5E_DEFAULT);
  });
  return available;
}

struct ChunkedStateFile::Impl {
  enum class Status { kFree, kFilling, kWriting, kReading, kReady, kInUse };
  struct Buffer {
    std::vector<double> data;  // chunkStates rows of stateSize, then chunkStates times
    Status status = Status::kFree;
    std::int64_t chunk = -1;
  };
  enum class Kind { kCreate, kWrite, kFinalize, kOpenRead, kRead };
  struct Task {
    Kind kind;
    int buffer = -1;
    std::int64_t chunk = 0;
    std::int64_t rows = 0;
    std::uint64_t ticket = 0;
  };

  StateFileOptions options;
  TrajectoryInfo info;
  std::string path;
  std::int64_t n = 0;
  std::int64_t chunkStates = 1;

  // Owner-thread state.
  int filling = -1;
  std::int64_t rowsInFilling = 0;
  std::int64_t rowCount = 0;
  int loaded = -1;
  bool closed = false;

  // Shared state, guarded by mutex.
  mutable std::mutex mutex;
  std::condition_variable changed;
  std::vector<Buffer> buffers;
  // Pending tasks: a ring allocated once (each buffer has at most one task in flight, plus the
  // synchronous ones), so that submitting allocates nothing.
  std::vector<Task> tasks;
  std::size_t firstTask = 0;
  std::size_t taskCount = 0;
  std::uint64_t nextTicket = 1;
  std::uint64_t completedTicket = 0;
  bool stop = false;
  bool failed = false;
  std::string error;
  double seconds = 0.0;
  std::int64_t fileSize = 0;
  std::int64_t storedBytes = 0;

  // Background-thread state: the HDF5 handles.
  hdf5::Handle file, states, times;
  std::int64_t chunksWritten = 0;
  std::int64_t stepCount = -1;
  bool created = false;  // only a file we created is ever removed
  std::thread worker;

  // ---- background thread ----
  void run() {
    const hdf5::ErrorSilencer quiet;  // this thread's own switch: we report errors ourselves
    std::unique_lock<std::mutex> lock(mutex);
    for (;;) {
      changed.wait(lock, [&] { return stop || taskCount > 0; });
      if (stop) break;
      const Task task = tasks[firstTask];
      firstTask = (firstTask + 1) % tasks.size();
      --taskCount;
      const bool skip = failed;
      lock.unlock();
      std::string message;
      double elapsed = 0.0;
      if (!skip) {
        const Stopwatch timer;
        try {
          execute(task);
        } catch (const std::exception& e) {
          message = e.what();
        }
        elapsed = timer.seconds();
      }
      lock.lock();
      seconds += elapsed;
      if (!message.empty() && !failed) {
        failed = true;
        error = message;
      }
      if (task.kind == Kind::kWrite) buffers[static_cast<std::size_t>(task.buffer)].status = Status::kFree;
      if (task.kind == Kind::kRead)
        buffers[static_cast<std::size_t>(task.buffer)].status = failed ? Status::kFree : Status::kReady;
      completedTicket = task.ticket;
      changed.notify_all();
    }
    lock.unlock();
    times.reset();
    states.reset();
    file.reset();
  }

  void execute(const Task& task) {
#ifndef H5_HAVE_THREADSAFE
    // A library built without thread safety must never be entered by two I/O threads at once.
    static std::mutex libraryMutex;
    std::lock_guard<std::mutex> libraryLock(libraryMutex);
#endif
    switch (task.kind) {
      case Kind::kCreate:
        create();
        break;
      case Kind::kWrite:
        write(task);
        break;
      case Kind::kFinalize:
        finalize();
        break;
      case Kind::kOpenRead:
        openRead();
        break;
      case Kind::kRead:
        readChunk(task);
        break;
    }
  }

  hdf5::Handle filteredChunks(int rank, const hsize_t* chunk) {
    hdf5::Handle dcpl = hdf5::propertyList(H5P_DATASET_CREATE);
    hdf5::check(H5Pset_chunk(dcpl.get(), rank, chunk), "chunk layout");
    const unsigned level = static_cast<unsigned>(options.compressionLevel);
    if (options.codec == StateFileOptions::Codec::kTime) {
      const unsigned values[3] = {rank == 2 ? static_cast<unsigned>(chunk[1]) : 1u,
                                  static_cast<unsigned>(options.timeOrder), level};
      hdf5::check(H5Pset_filter(dcpl.get(), static_cast<H5Z_filter_t>(kTimeCodecFilterId), H5Z_FLAG_MANDATORY,
                                3, values),
                  "time codec filter 306");
    } else {
      hdf5::check(H5Pset_shuffle(dcpl.get()), "shuffle filter");
      hdf5::check(H5Pset_filter(dcpl.get(), kZstdFilterId, H5Z_FLAG_MANDATORY, 1, &level),
                  "zstd filter 32015");
    }
    hdf5::check(H5Pset_fletcher32(dcpl.get()), "Fletcher32 filter");
    return dcpl;
  }

  // Whole chunks go straight between our buffers and the file: no chunk cache.
  static hdf5::Handle uncachedAccess() {
    hdf5::Handle access = hdf5::propertyList(H5P_DATASET_ACCESS);
    hdf5::check(H5Pset_chunk_cache(access.get(), 0, 0, 1.0), "chunk cache");
    return access;
  }

  void create() {
    if (!ensureZstdFilter()) throw std::runtime_error("cannot register the zstd HDF5 filter (id 32015)");
    if (!ensureTimeCodecFilter())
      throw std::runtime_error("cannot register the time codec HDF5 filter (id 306)");
    file = hdf5::createFile(path, H5F_ACC_EXCL, "the trajectory file");
    created = true;
    const std::vector<hsize_t> dims = {0, static_cast<hsize_t>(n)};
    const std::vector<hsize_t> maxDims = {H5S_UNLIMITED, static_cast<hsize_t>(n)};
    const hsize_t chunk[2] = {static_cast<hsize_t>(chunkStates), static_cast<hsize_t>(n)};
    const hdf5::Handle access = uncachedAccess();
    states = hdf5::createDataset(file.get(), "states", H5T_IEEE_F64LE, dims, maxDims,
                                 filteredChunks(2, chunk).get(), access.get());
    times = hdf5::createDataset(file.get(), "times", H5T_IEEE_F64LE, {0}, {H5S_UNLIMITED},
                                filteredChunks(1, chunk).get(), access.get());
    hdf5::writeStringAttribute(file.get(), "format", "hindsight trajectory 1");
    hdf5::writeStringAttribute(file.get(), "problem", info.problemName);
    hdf5::writeAttribute(file.get(), "stateSize", n);
    hdf5::writeAttribute(file.get(), "t0", info.t0);
    hdf5::writeAttribute(file.get(), "t1", info.t1);
    hdf5::writeStringAttribute(file.get(), "hindsightVersion", version());
    hdf5::writeAttribute(file.get(), "chunkStates", chunkStates);
    hdf5::writeStringAttribute(file.get(), "codec",
                               options.codec == StateFileOptions::Codec::kTime ? "time" : "zstd");
  }

  void write(const Task& task) {
    if (options.failWriteAfterChunks >= 0 && chunksWritten >= options.failWriteAfterChunks) {
      throw std::runtime_error("cannot write chunk " + std::to_string(task.chunk) +
                               ": No space left on device (fault injected by failWriteAfterChunks = " +
                               std::to_string(options.failWriteAfterChunks) + ")");
    }
    const Buffer& buffer = buffers[static_cast<std::size_t>(task.buffer)];
    const hsize_t first = static_cast<hsize_t>(task.chunk * chunkStates);
    const hsize_t rows = static_cast<hsize_t>(task.rows);
    hdf5::writeRows(states.get(), first, {rows, static_cast<hsize_t>(n)}, buffer.data.data());
    hdf5::writeRows(times.get(), first, {rows}, buffer.data.data() + chunkStates * n);
    ++chunksWritten;
  }

  void finalize() {
    hdf5::writeAttribute(file.get(), "stepCount", stepCount);
    const std::int64_t stored = static_cast<std::int64_t>(H5Dget_storage_size(states.get()));
    hdf5::check(H5Fflush(file.get(), H5F_SCOPE_LOCAL), "cannot flush the trajectory file");
    if (!times.reset() || !states.reset() || !file.reset()) {
      throw std::runtime_error("cannot close the trajectory file: " + hdf5::errorMessage());
    }
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    std::lock_guard<std::mutex> lock(mutex);
    storedBytes = stored;
    fileSize = ec ? 0 : static_cast<std::int64_t>(size);
  }

  void openRead() {
    if (!ensureZstdFilter() || !ensureTimeCodecFilter())
      throw std::runtime_error("cannot register the HDF5 filters 32015 and 306");
    file = hdf5::openFileReadOnly(path, "the trajectory file");
    states = hdf5::openDataset(file.get(), "states", uncachedAccess().get());
    const std::vector<hsize_t> dims = hdf5::shape(states.get());
    if (dims != std::vector<hsize_t>{static_cast<hsize_t>(rowCount), static_cast<hsize_t>(n)}) {
      throw std::runtime_error("the trajectory file holds " + std::to_string(dims.size() > 0 ? dims[0] : 0) +
                               " x " + std::to_string(dims.size() > 1 ? dims[1] : 0) + " states, expected " +
                               std::to_string(rowCount) + " x " + std::to_string(n) +
                               " (truncated or replaced?)");
    }
  }

  void readChunk(const Task& task) {
    Buffer& buffer = buffers[static_cast<std::size_t>(task.buffer)];
    const hsize_t first = static_cast<hsize_t>(task.chunk * chunkStates);
    const hsize_t rows = static_cast<hsize_t>(std::min(chunkStates, rowCount - task.chunk * chunkStates));
    try {
      hdf5::readRows(states.get(), first, {rows, static_cast<hsize_t>(n)}, buffer.data.data());
    } catch (const hdf5::Error& e) {
      throw std::runtime_error(std::string(e.what()) + " (corrupted or truncated file?)");
    }
  }

  // ---- owner thread ----
  [[noreturn]] void throwFailure() const { throw StorageError("disk storage: " + error, path); }

  std::uint64_t submit(Task task) {  // called with mutex held
    task.ticket = nextTicket++;
    assert(taskCount < tasks.size());
    tasks[(firstTask + taskCount) % tasks.size()] = task;
    ++taskCount;
    changed.notify_all();
    return task.ticket;
  }

  void waitFor(std::uint64_t ticket) {
    std::unique_lock<std::mutex> lock(mutex);
    changed.wait(lock, [&] { return completedTicket >= ticket || failed; });
    if (failed) throwFailure();
  }

  int acquireFree(std::unique_lock<std::mutex>& lock) {
    int found = -1;
    changed.wait(lock, [&] {
      if (failed) return true;
      for (std::size_t i = 0; i < buffers.size(); ++i) {
        if (buffers[i].status == Status::kFree) {
          found = static_cast<int>(i);
          return true;
        }
      }
      return false;
    });
    if (failed) throwFailure();
    return found;
  }

  void flushFilling(std::unique_lock<std::mutex>&) {
    Buffer& buffer = buffers[static_cast<std::size_t>(filling)];
    buffer.status = Status::kWriting;
    const std::int64_t chunk = (rowCount - rowsInFilling) / chunkStates;
    submit(Task{Kind::kWrite, filling, chunk, rowsInFilling, 0});
    filling = -1;
    rowsInFilling = 0;
  }

  int findChunk(std::int64_t chunk) const {  // with mutex held
    for (std::size_t i = 0; i < buffers.size(); ++i) {
      const Status s = buffers[i].status;
      if (buffers[i].chunk == chunk && (s == Status::kReading || s == Status::kReady))
        return static_cast<int>(i);
    }
    return -1;
  }

  void requestRead(std::unique_lock<std::mutex>& lock, std::int64_t chunk, bool mayWait) {
    if (chunk < 0 || findChunk(chunk) >= 0) return;
    // Ready chunks nobody will ask for any more (rows only decrease) are free for reuse.
    for (auto& buffer : buffers) {
      if (buffer.status == Status::kReady && buffer.chunk > chunk) buffer.status = Status::kFree;
    }
    int target = -1;
    for (std::size_t i = 0; i < buffers.size() && target < 0; ++i) {
      if (buffers[i].status == Status::kFree) target = static_cast<int>(i);
    }
    if (target < 0) {
      if (!mayWait) return;  // a prefetch is only an optimization
      target = acquireFree(lock);
    }
    buffers[static_cast<std::size_t>(target)].status = Status::kReading;
    buffers[static_cast<std::size_t>(target)].chunk = chunk;
    submit(Task{Kind::kRead, target, chunk, 0, 0});
  }
};

ChunkedStateFile::ChunkedStateFile(const StateFileOptions& options, const TrajectoryInfo& info)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  assert(options.chunkStates >= 1 && options.bufferCount >= 1);
  s.options = options;
  s.info = info;
  s.n = info.stateSize;
  s.chunkStates = options.chunkStates;
  std::error_code ec;
  std::filesystem::create_directories(options.directory, ec);
  if (!std::filesystem::is_directory(options.directory)) {
    throw StorageError("disk storage: cannot use directory '" + options.directory + "'" +
                           (ec ? ": " + ec.message() : std::string(": not a directory")),
                       options.directory);
  }
  removeStaleScratchFiles(options.directory);
  s.path = (std::filesystem::path(options.directory) /
            scratchFileName(options.filePrefix, ".h5", options.keepFile))
               .string();
  s.buffers.resize(static_cast<std::size_t>(options.bufferCount));
  s.tasks.resize(2 * s.buffers.size() + 4);
  for (auto& buffer : s.buffers) {
    buffer.data.resize(static_cast<std::size_t>(bufferBytes(info.stateSize, options.chunkStates) / 8));
  }
  s.worker = std::thread([&s] { s.run(); });
  std::uint64_t ticket = 0;
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    ticket = s.submit(Impl::Task{Impl::Kind::kCreate, -1, 0, 0, 0});
  }
  try {
    s.waitFor(ticket);
  } catch (...) {
    close();
    throw;
  }
}

ChunkedStateFile::~ChunkedStateFile() { close(); }

const std::string& ChunkedStateFile::path() const { return impl_->path; }

void ChunkedStateFile::append(double t, const double* z) {
  Impl& s = *impl_;
  std::unique_lock<std::mutex> lock(s.mutex);
  if (s.failed) s.throwFailure();
  if (s.filling < 0) {
    s.filling = s.acquireFree(lock);
    s.buffers[static_cast<std::size_t>(s.filling)].status = Impl::Status::kFilling;
  }
  lock.unlock();  // the filling buffer belongs to this thread
  double* data = s.buffers[static_cast<std::size_t>(s.filling)].data.data();
  std::memcpy(data + s.rowsInFilling * s.n, z, static_cast<std::size_t>(s.n) * 8);
  data[s.chunkStates * s.n + s.rowsInFilling] = t;
  ++s.rowsInFilling;
  ++s.rowCount;
  if (s.rowsInFilling == s.chunkStates) {
    lock.lock();
    s.flushFilling(lock);
  }
}

void ChunkedStateFile::finishWriting(std::int64_t stepCount) {
  Impl& s = *impl_;
  std::uint64_t ticket = 0;
  {
    std::unique_lock<std::mutex> lock(s.mutex);
    if (s.failed) s.throwFailure();
    if (s.filling >= 0) {
      if (s.rowsInFilling > 0) {
        s.flushFilling(lock);
      } else {
        s.buffers[static_cast<std::size_t>(s.filling)].status = Impl::Status::kFree;
        s.filling = -1;
      }
    }
    s.stepCount = stepCount;
    ticket = s.submit(Impl::Task{Impl::Kind::kFinalize, -1, 0, 0, 0});
  }
  s.waitFor(ticket);
}

void ChunkedStateFile::startReading(std::int64_t firstRow) {
  Impl& s = *impl_;
  std::uint64_t ticket = 0;
  {
    std::unique_lock<std::mutex> lock(s.mutex);
    ticket = s.submit(Impl::Task{Impl::Kind::kOpenRead, -1, 0, 0, 0});
    if (firstRow >= 0 && firstRow < s.rowCount) s.requestRead(lock, firstRow / s.chunkStates, true);
  }
  s.waitFor(ticket);
}

void ChunkedStateFile::read(std::int64_t row, double* z) {
  Impl& s = *impl_;
  assert(row >= 0 && row < s.rowCount);
  const std::int64_t chunk = row / s.chunkStates;
  if (s.loaded < 0 || s.buffers[static_cast<std::size_t>(s.loaded)].chunk != chunk) {
    std::unique_lock<std::mutex> lock(s.mutex);
    if (s.failed) s.throwFailure();
    if (s.loaded >= 0) s.buffers[static_cast<std::size_t>(s.loaded)].status = Impl::Status::kFree;
    s.loaded = -1;
    s.requestRead(lock, chunk, true);
    const int index = s.findChunk(chunk);
    assert(index >= 0);
    s.changed.wait(lock, [&] {
      return s.failed || s.buffers[static_cast<std::size_t>(index)].status == Impl::Status::kReady;
    });
    if (s.failed) s.throwFailure();
    s.buffers[static_cast<std::size_t>(index)].status = Impl::Status::kInUse;
    s.loaded = index;
    s.requestRead(lock, chunk - 1, false);  // prefetch the chunk the backward sweep needs next
  }
  const double* data = s.buffers[static_cast<std::size_t>(s.loaded)].data.data();
  std::memcpy(z, data + (row - chunk * s.chunkStates) * s.n, static_cast<std::size_t>(s.n) * 8);
}

void ChunkedStateFile::close() noexcept {
  Impl& s = *impl_;
  if (s.closed) return;
  s.closed = true;
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    s.stop = true;
    s.changed.notify_all();
  }
  if (s.worker.joinable()) s.worker.join();
  if (!s.options.keepFile && s.created) {
    std::error_code ec;
    std::filesystem::remove(s.path, ec);
  }
}

std::int64_t ChunkedStateFile::rows() const { return impl_->rowCount; }

std::int64_t ChunkedStateFile::fileBytes() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->fileSize;
}

std::int64_t ChunkedStateFile::storedStateBytes() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->storedBytes;
}

double ChunkedStateFile::ioSeconds() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->seconds;
}

}  // namespace hindsight::internal
