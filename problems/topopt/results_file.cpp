#include <hindsight/problems/topopt/results_file.h>

#include <hdf5.h>

#include <fcntl.h>
#include <unistd.h>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <functional>
#include <stdexcept>

namespace hindsight {
namespace {

/// The real-valued history columns: dataset name in /history and the record member it stores. One
/// table for writing and reading, so the two cannot drift apart.
const std::pair<const char*, double IterationRecord::*> kHistoryColumns[] = {
    {"psi1", &IterationRecord::psi1},
    {"psi2", &IterationRecord::psi2},
    {"volume_fraction", &IterationRecord::volumeFraction},
    {"max_design_change", &IterationRecord::maxDesignChange},
    {"evaluation_seconds", &IterationRecord::evaluationSeconds},
    {"mma_seconds", &IterationRecord::mmaSeconds},
    {"total_seconds", &IterationRecord::totalSeconds}};

constexpr const char* kFormat = "hindsight-topology-results";
constexpr int kFormatVersion = 1;

// Silences HDF5's automatic error printing for the lifetime of the guard; errors are reported by
// return codes, which every call below checks.
class QuietHdf5 {
 public:
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &function_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, function_, data_); }
  QuietHdf5(const QuietHdf5&) = delete;
  QuietHdf5& operator=(const QuietHdf5&) = delete;

 private:
  H5E_auto2_t function_ = nullptr;
  void* data_ = nullptr;
};

// Owns one HDF5 identifier.
class Handle {
 public:
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  ~Handle() {
    if (id_ >= 0) close_(id_);
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  hid_t get() const { return id_; }
  // Closes now and reports whether closing succeeded (the file's last writes happen here).
  bool close() {
    const herr_t status = id_ >= 0 ? close_(id_) : 0;
    id_ = -1;
    return status >= 0;
  }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

struct Context {
  std::string path;
  [[noreturn]] void fail(const std::string& what) const { throw StorageError("results file: " + what, path); }
  hid_t check(hid_t id, const std::string& what) const {
    if (id < 0) fail(what);
    return id;
  }
  void ok(herr_t status, const std::string& what) const {
    if (status < 0) fail(what);
  }
};

// ---- writing ----

void writeAttribute(const Context& c, hid_t object, const char* name, hid_t memType, hid_t fileType,
                    const void* value) {
  Handle space(c.check(H5Screate(H5S_SCALAR), "dataspace"), H5Sclose);
  Handle attribute(c.check(H5Acreate2(object, name, fileType, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                           std::string("create attribute ") + name),
                   H5Aclose);
  c.ok(H5Awrite(attribute.get(), memType, value), name);
}
void writeInt(const Context& c, hid_t object, const char* name, int value) {
  const int v = value;
  writeAttribute(c, object, name, H5T_NATIVE_INT, H5T_STD_I32LE, &v);
}
void writeDouble(const Context& c, hid_t object, const char* name, double value) {
  writeAttribute(c, object, name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, &value);
}
void writeString(const Context& c, hid_t object, const char* name, const std::string& value) {
  Handle type(c.check(H5Tcopy(H5T_C_S1), "string type"), H5Tclose);
  c.ok(H5Tset_size(type.get(), std::max<std::size_t>(1, value.size())), "string size");
  c.ok(H5Tset_strpad(type.get(), H5T_STR_NULLPAD), "string padding");
  std::string padded = value;
  if (padded.empty()) padded.push_back('\0');
  writeAttribute(c, object, name, type.get(), type.get(), padded.data());
}

// An extendible (chunked, unlimited first dimension) dataset of `rank` dims holding `data`.
void writeExtendible(const Context& c, hid_t parent, const char* name, hid_t memType, hid_t fileType,
                     std::vector<hsize_t> dims, const void* data) {
  std::vector<hsize_t> maxDims = dims;
  maxDims[0] = H5S_UNLIMITED;
  std::vector<hsize_t> chunk = dims;
  chunk[0] = dims.size() == 1 ? 64 : 1;
  for (hsize_t& size : chunk) size = std::max<hsize_t>(size, 1);
  const int rank = static_cast<int>(dims.size());
  Handle space(c.check(H5Screate_simple(rank, dims.data(), maxDims.data()), "dataspace"), H5Sclose);
  Handle properties(c.check(H5Pcreate(H5P_DATASET_CREATE), "dataset properties"), H5Pclose);
  c.ok(H5Pset_chunk(properties.get(), rank, chunk.data()), "chunking");
  Handle dataset(
      c.check(H5Dcreate2(parent, name, fileType, space.get(), H5P_DEFAULT, properties.get(), H5P_DEFAULT),
              std::string("create dataset ") + name),
      H5Dclose);
  if (dims[0] > 0) c.ok(H5Dwrite(dataset.get(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), name);
}

void writeFixed(const Context& c, hid_t parent, const char* name, std::vector<hsize_t> dims,
                const double* data) {
  const int rank = static_cast<int>(dims.size());
  Handle space(c.check(H5Screate_simple(rank, dims.data(), nullptr), "dataspace"), H5Sclose);
  Handle dataset(
      c.check(H5Dcreate2(parent, name, H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
              std::string("create dataset ") + name),
      H5Dclose);
  bool empty = false;
  for (hsize_t d : dims) empty = empty || d == 0;
  if (!empty) c.ok(H5Dwrite(dataset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), name);
}

void writeVector(const Context& c, hid_t parent, const char* name, const Vector& v) {
  writeFixed(c, parent, name, {static_cast<hsize_t>(v.size())}, v.data());
}

void syncPath(const Context& c, const std::string& path, bool directory) {
  const int fd = ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd < 0) c.fail("cannot open " + path + " to sync it: " + std::strerror(errno));
  const int status = ::fsync(fd);
  ::close(fd);
  if (status != 0) c.fail("fsync of " + path + " failed: " + std::strerror(errno));
}

void writeContents(const Context& c, hid_t file, const ResultsData& data) {
  const std::size_t rows = data.history.size();
  writeString(c, file, "format", kFormat);
  writeInt(c, file, "format_version", kFormatVersion);
  writeString(c, file, "configuration", data.configurationJson);
  writeInt(c, file, "completed_iterations", static_cast<int>(rows));
  writeInt(c, file, "finished", data.finished ? 1 : 0);
  writeInt(c, file, "nx", data.nx);
  writeInt(c, file, "ny", data.ny);
  writeInt(c, file, "updates", data.state.iteration);
  writeDouble(c, file, "objective_scale", data.state.objectiveScale);

  {
    Handle group(c.check(H5Gcreate2(file, "history", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "group history"),
                 H5Gclose);
    std::vector<int> iteration(rows);
    for (std::size_t k = 0; k < rows; ++k) iteration[k] = data.history[k].iteration;
    writeExtendible(c, group.get(), "iteration", H5T_NATIVE_INT, H5T_STD_I32LE, {rows}, iteration.data());
    for (std::size_t k = 0; k < rows; ++k) iteration[k] = data.history[k].backtracks;
    writeExtendible(c, group.get(), "backtracks", H5T_NATIVE_INT, H5T_STD_I32LE, {rows}, iteration.data());
    std::vector<double> column(rows);
    for (const auto& [name, member] : kHistoryColumns) {
      for (std::size_t k = 0; k < rows; ++k) column[k] = data.history[k].*member;
      writeExtendible(c, group.get(), name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, {rows}, column.data());
    }
  }
  {
    const std::size_t cells = static_cast<std::size_t>(data.nx) * static_cast<std::size_t>(data.ny);
    std::vector<double> designs(rows * cells);
    for (std::size_t k = 0; k < rows; ++k) {
      std::copy(data.densities[k].data(), data.densities[k].data() + cells, designs.begin() + k * cells);
    }
    writeExtendible(c, file, "designs", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE,
                    {rows, static_cast<hsize_t>(data.ny), static_cast<hsize_t>(data.nx)}, designs.data());
  }
  {
    Handle group(c.check(H5Gcreate2(file, "state", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "group state"),
                 H5Gclose);
    writeVector(c, group.get(), "design", data.state.design);
    writeVector(c, group.get(), "mma_xold1", data.state.mma.xold1);
    writeVector(c, group.get(), "mma_xold2", data.state.mma.xold2);
    writeVector(c, group.get(), "mma_low", data.state.mma.low);
    writeVector(c, group.get(), "mma_upp", data.state.mma.upp);
    writeInt(c, group.get(), "mma_iteration", data.state.mma.iteration);
  }
  {
    Handle group(c.check(H5Gcreate2(file, "final", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "group final"),
                 H5Gclose);
    // Column-major dofCount x modeCount is row-major modeCount x dofCount.
    writeFixed(c, group.get(), "modes",
               {static_cast<hsize_t>(data.finalModes.cols()), static_cast<hsize_t>(data.finalModes.rows())},
               data.finalModes.data());
    writeFixed(c, group.get(), "frequencies_hz", {data.finalFrequenciesHz.size()},
               data.finalFrequenciesHz.data());
  }
}

// ---- reading ----

bool hasAttribute(hid_t object, const char* name) { return H5Aexists(object, name) > 0; }

void readAttribute(const Context& c, hid_t object, const char* name, hid_t memType, void* value) {
  if (!hasAttribute(object, name)) c.fail(std::string("attribute '") + name + "' is missing");
  Handle attribute(c.check(H5Aopen(object, name, H5P_DEFAULT), name), H5Aclose);
  c.ok(H5Aread(attribute.get(), memType, value), name);
}
int readInt(const Context& c, hid_t object, const char* name) {
  int value = 0;
  readAttribute(c, object, name, H5T_NATIVE_INT, &value);
  return value;
}
double readDouble(const Context& c, hid_t object, const char* name) {
  double value = 0.0;
  readAttribute(c, object, name, H5T_NATIVE_DOUBLE, &value);
  return value;
}
std::string readString(const Context& c, hid_t object, const char* name) {
  if (!hasAttribute(object, name)) c.fail(std::string("attribute '") + name + "' is missing");
  Handle attribute(c.check(H5Aopen(object, name, H5P_DEFAULT), name), H5Aclose);
  Handle type(c.check(H5Aget_type(attribute.get()), name), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_STRING || H5Tis_variable_str(type.get()) > 0) {
    c.fail(std::string("attribute '") + name + "' is not a fixed-length string");
  }
  std::string value(H5Tget_size(type.get()), '\0');
  c.ok(H5Aread(attribute.get(), type.get(), value.data()), name);
  const auto end = value.find('\0');
  if (end != std::string::npos) value.resize(end);
  return value;
}

// Reads a dataset of the expected shape into `out` (resized), converting to `memType`.
template <typename T>
void readDataset(const Context& c, hid_t parent, const char* name, hid_t memType,
                 const std::vector<hsize_t>& shape, T* out) {
  Handle dataset(
      c.check(H5Dopen2(parent, name, H5P_DEFAULT), std::string("dataset '") + name + "' is missing"),
      H5Dclose);
  Handle space(c.check(H5Dget_space(dataset.get()), name), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(rank, 0)));
  if (rank < 0 || H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) < 0) c.fail(name);
  if (dims != shape) c.fail(std::string("dataset '") + name + "' has an unexpected shape");
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  if (total > 0) c.ok(H5Dread(dataset.get(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, out), name);
}

Vector readVector(const Context& c, hid_t parent, const char* name, hsize_t size) {
  Vector v(static_cast<Eigen::Index>(size));
  readDataset(c, parent, name, H5T_NATIVE_DOUBLE, {size}, v.data());
  return v;
}

hsize_t datasetRows(const Context& c, hid_t parent, const char* name) {
  Handle dataset(
      c.check(H5Dopen2(parent, name, H5P_DEFAULT), std::string("dataset '") + name + "' is missing"),
      H5Dclose);
  Handle space(c.check(H5Dget_space(dataset.get()), name), H5Sclose);
  hsize_t dims[2] = {0, 0};
  if (H5Sget_simple_extent_ndims(space.get()) != 2 ||
      H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0) {
    c.fail(std::string("dataset '") + name + "' is not two-dimensional");
  }
  return dims[0];
}

ResultsData readContents(const Context& c, hid_t file) {
  if (readString(c, file, "format") != kFormat) c.fail("not a hindsight topology results file");
  const int version = readInt(c, file, "format_version");
  if (version != kFormatVersion) c.fail("format_version " + std::to_string(version) + " is not supported");
  ResultsData data;
  data.configurationJson = readString(c, file, "configuration");
  const int rowsSigned = readInt(c, file, "completed_iterations");
  data.finished = readInt(c, file, "finished") != 0;
  data.nx = readInt(c, file, "nx");
  data.ny = readInt(c, file, "ny");
  data.state.iteration = readInt(c, file, "updates");
  data.state.objectiveScale = readDouble(c, file, "objective_scale");
  if (rowsSigned < 0 || data.nx < 1 || data.ny < 1 || data.state.iteration < 0)
    c.fail("inconsistent attributes");
  const auto rows = static_cast<hsize_t>(rowsSigned);

  {
    Handle group(c.check(H5Gopen2(file, "history", H5P_DEFAULT), "group 'history' is missing"), H5Gclose);
    std::vector<int> iteration(rows);
    readDataset(c, group.get(), "iteration", H5T_NATIVE_INT, {rows}, iteration.data());
    data.history.resize(rows);
    for (hsize_t k = 0; k < rows; ++k) data.history[k].iteration = iteration[k];
    readDataset(c, group.get(), "backtracks", H5T_NATIVE_INT, {rows}, iteration.data());
    for (hsize_t k = 0; k < rows; ++k) data.history[k].backtracks = iteration[k];
    std::vector<double> column(rows);
    for (const auto& [name, member] : kHistoryColumns) {
      readDataset(c, group.get(), name, H5T_NATIVE_DOUBLE, {rows}, column.data());
      for (hsize_t k = 0; k < rows; ++k) data.history[k].*member = column[k];
    }
  }
  {
    const auto nx = static_cast<hsize_t>(data.nx);
    const auto ny = static_cast<hsize_t>(data.ny);
    std::vector<double> designs(rows * nx * ny);
    readDataset(c, file, "designs", H5T_NATIVE_DOUBLE, {rows, ny, nx}, designs.data());
    for (hsize_t k = 0; k < rows; ++k) {
      data.densities.push_back(
          Eigen::Map<const Vector>(designs.data() + k * nx * ny, static_cast<Eigen::Index>(nx * ny)));
    }
  }
  {
    Handle group(c.check(H5Gopen2(file, "state", H5P_DEFAULT), "group 'state' is missing"), H5Gclose);
    Handle dataset(c.check(H5Dopen2(group.get(), "design", H5P_DEFAULT), "dataset 'state/design' is missing"),
                   H5Dclose);
    Handle space(c.check(H5Dget_space(dataset.get()), "state/design"), H5Sclose);
    const hssize_t n = H5Sget_simple_extent_npoints(space.get());
    if (n < 1) c.fail("dataset 'state/design' is empty");
    const auto size = static_cast<hsize_t>(n);
    data.state.design = readVector(c, group.get(), "design", size);
    data.state.mma.xold1 = readVector(c, group.get(), "mma_xold1", size);
    data.state.mma.xold2 = readVector(c, group.get(), "mma_xold2", size);
    data.state.mma.low = readVector(c, group.get(), "mma_low", size);
    data.state.mma.upp = readVector(c, group.get(), "mma_upp", size);
    data.state.mma.iteration = readInt(c, group.get(), "mma_iteration");
  }
  {
    Handle group(c.check(H5Gopen2(file, "final", H5P_DEFAULT), "group 'final' is missing"), H5Gclose);
    const hsize_t modeCount = datasetRows(c, group.get(), "modes");
    Handle dataset(c.check(H5Dopen2(group.get(), "modes", H5P_DEFAULT), "final/modes"), H5Dclose);
    Handle space(c.check(H5Dget_space(dataset.get()), "final/modes"), H5Sclose);
    hsize_t dims[2] = {0, 0};
    H5Sget_simple_extent_dims(space.get(), dims, nullptr);
    data.finalModes.resize(static_cast<Eigen::Index>(dims[1]), static_cast<Eigen::Index>(modeCount));
    readDataset(c, group.get(), "modes", H5T_NATIVE_DOUBLE, {modeCount, dims[1]}, data.finalModes.data());
    data.finalFrequenciesHz.resize(modeCount);
    readDataset(c, group.get(), "frequencies_hz", H5T_NATIVE_DOUBLE, {modeCount},
                data.finalFrequenciesHz.data());
  }
  return data;
}

}  // namespace

void writeResultsFile(const std::string& path, const ResultsData& data) {
  const std::size_t cells = static_cast<std::size_t>(data.nx) * static_cast<std::size_t>(data.ny);
  if (data.nx < 1 || data.ny < 1) throw std::invalid_argument("results: nx and ny must be >= 1");
  if (data.densities.size() != data.history.size()) {
    throw std::invalid_argument("results: " + std::to_string(data.densities.size()) + " density grids for " +
                                std::to_string(data.history.size()) + " history entries");
  }
  for (const Vector& grid : data.densities) {
    if (static_cast<std::size_t>(grid.size()) != cells)
      throw std::invalid_argument("results: density grid size");
  }
  const Eigen::Index n = data.state.design.size();
  if (n < 1 || data.state.mma.xold1.size() != n || data.state.mma.xold2.size() != n ||
      data.state.mma.low.size() != n || data.state.mma.upp.size() != n) {
    throw std::invalid_argument("results: state vectors must all have the design's length (>= 1)");
  }
  if (static_cast<std::size_t>(data.finalModes.cols()) != data.finalFrequenciesHz.size()) {
    throw std::invalid_argument("results: one frequency per final mode");
  }

  const QuietHdf5 quiet;
  const std::string partial = path + ".partial";
  const Context c{partial};
  std::remove(partial.c_str());
  {
    Handle file(c.check(H5Fcreate(partial.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), "cannot create"),
                H5Fclose);
    try {
      writeContents(c, file.get(), data);
    } catch (...) {
      file.close();
      std::remove(partial.c_str());
      throw;
    }
    if (!file.close()) {
      std::remove(partial.c_str());
      c.fail("closing failed");
    }
  }
  syncPath(c, partial, false);
  if (std::rename(partial.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(partial.c_str());
    throw StorageError("results file: rename of " + partial + " failed: " + reason, path);
  }
  const auto slash = path.find_last_of('/');
  syncPath(Context{path},
           slash == std::string::npos ? std::string(".") : path.substr(0, std::max<std::size_t>(slash, 1)),
           true);
}

ResultsData readResultsFile(const std::string& path) {
  const QuietHdf5 quiet;
  const Context c{path};
  Handle file(c.check(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), "cannot open as HDF5"), H5Fclose);
  return readContents(c, file.get());
}

std::string readResultsConfiguration(const std::string& path) {
  const QuietHdf5 quiet;
  const Context c{path};
  Handle file(c.check(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), "cannot open as HDF5"), H5Fclose);
  if (readString(c, file.get(), "format") != kFormat) c.fail("not a hindsight topology results file");
  return readString(c, file.get(), "configuration");
}

}  // namespace hindsight
