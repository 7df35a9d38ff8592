#include <hindsight/problems/topopt/results_file.h>

#include <hindsight/storage/atomic_file.h>
#include <hindsight/storage/hdf5.h>

#include <algorithm>
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

[[noreturn]] void fail(const std::string& what) { throw hdf5::Error(what, {}); }

// ---- writing ----

// An extendible (chunked, unlimited first dimension) dataset of `dims` holding `data`.
void writeExtendible(hid_t parent, const char* name, hid_t memType, hid_t fileType, std::vector<hsize_t> dims,
                     const void* data) {
  std::vector<hsize_t> maxDims = dims;
  maxDims[0] = H5S_UNLIMITED;
  std::vector<hsize_t> chunk = dims;
  chunk[0] = dims.size() == 1 ? 64 : 1;
  for (hsize_t& size : chunk) size = std::max<hsize_t>(size, 1);
  const hdf5::Handle properties = hdf5::propertyList(H5P_DATASET_CREATE);
  hdf5::check(H5Pset_chunk(properties.get(), static_cast<int>(chunk.size()), chunk.data()), "chunking");
  const hdf5::Handle dataset = hdf5::createDataset(parent, name, fileType, dims, maxDims, properties.get());
  hdf5::write(dataset.get(), memType, data);
}

void writeVector(hid_t parent, const char* name, const Vector& v) {
  hdf5::writeDoubles(parent, name, {static_cast<hsize_t>(v.size())}, v.data());
}

void writeContents(hid_t file, const ResultsData& data) {
  const std::size_t rows = data.history.size();
  hdf5::writeStringAttribute(file, "format", kFormat);
  hdf5::writeAttribute(file, "format_version", kFormatVersion);
  hdf5::writeStringAttribute(file, "configuration", data.configurationJson);
  hdf5::writeAttribute(file, "completed_iterations", static_cast<int>(rows));
  hdf5::writeAttribute(file, "finished", data.finished ? 1 : 0);
  hdf5::writeAttribute(file, "nx", data.nx);
  hdf5::writeAttribute(file, "ny", data.ny);
  hdf5::writeAttribute(file, "updates", data.state.iteration);
  hdf5::writeAttribute(file, "objective_scale", data.state.objectiveScale);

  {
    const hdf5::Handle group = hdf5::createGroup(file, "history");
    std::vector<int> iteration(rows);
    for (std::size_t k = 0; k < rows; ++k) iteration[k] = data.history[k].iteration;
    writeExtendible(group.get(), "iteration", H5T_NATIVE_INT, H5T_STD_I32LE, {rows}, iteration.data());
    for (std::size_t k = 0; k < rows; ++k) iteration[k] = data.history[k].backtracks;
    writeExtendible(group.get(), "backtracks", H5T_NATIVE_INT, H5T_STD_I32LE, {rows}, iteration.data());
    std::vector<double> column(rows);
    for (const auto& [name, member] : kHistoryColumns) {
      for (std::size_t k = 0; k < rows; ++k) column[k] = data.history[k].*member;
      writeExtendible(group.get(), name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, {rows}, column.data());
    }
  }
  {
    const std::size_t cells = static_cast<std::size_t>(data.nx) * static_cast<std::size_t>(data.ny);
    std::vector<double> designs(rows * cells);
    for (std::size_t k = 0; k < rows; ++k) {
      std::copy(data.densities[k].data(), data.densities[k].data() + cells, designs.begin() + k * cells);
    }
    writeExtendible(file, "designs", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE,
                    {rows, static_cast<hsize_t>(data.ny), static_cast<hsize_t>(data.nx)}, designs.data());
  }
  {
    const hdf5::Handle group = hdf5::createGroup(file, "state");
    writeVector(group.get(), "design", data.state.design);
    writeVector(group.get(), "mma_xold1", data.state.mma.xold1);
    writeVector(group.get(), "mma_xold2", data.state.mma.xold2);
    writeVector(group.get(), "mma_low", data.state.mma.low);
    writeVector(group.get(), "mma_upp", data.state.mma.upp);
    hdf5::writeAttribute(group.get(), "mma_iteration", data.state.mma.iteration);
  }
  {
    const hdf5::Handle group = hdf5::createGroup(file, "final");
    // Column-major dofCount x modeCount is row-major modeCount x dofCount.
    hdf5::writeDoubles(
        group.get(), "modes",
        {static_cast<hsize_t>(data.finalModes.cols()), static_cast<hsize_t>(data.finalModes.rows())},
        data.finalModes.data());
    hdf5::writeDoubles(group.get(), "frequencies_hz", {data.finalFrequenciesHz.size()},
                       data.finalFrequenciesHz.data());
  }
}

// ---- reading ----

Vector readVector(hid_t parent, const char* name, hsize_t size) {
  Vector v(static_cast<Eigen::Index>(size));
  hdf5::read(parent, name, H5T_NATIVE_DOUBLE, {size}, v.data());
  return v;
}

// The shape of a dataset that must exist and have `rank` dimensions.
std::vector<hsize_t> shapeOf(hid_t parent, const char* name, std::size_t rank) {
  const std::vector<hsize_t> dims = hdf5::shape(hdf5::openDataset(parent, name).get());
  if (dims.size() != rank) {
    fail("dataset '" + hdf5::objectName(parent, name) + "' has " + std::to_string(dims.size()) +
         " dimensions, expected " + std::to_string(rank));
  }
  return dims;
}

// The counts and sizes in the root attributes are only what the file claims. Before memory of that size
// is allocated, the dataset must have exactly that shape and fit in the file (writeContents stores
// every element uncompressed): a damaged file claiming 2^31 iterations is refused, not allocated for.
void requireShape(hid_t file, hid_t parent, const char* name, const std::vector<hsize_t>& expected) {
  if (shapeOf(parent, name, expected.size()) != expected) {
    fail("dataset '" + hdf5::objectName(parent, name) + "' does not have the shape the attributes give");
  }
  hsize_t fileSize = 0;
  if (H5Fget_filesize(file, &fileSize) < 0) fail("cannot read the file's size");
  hsize_t bytes = sizeof(double);
  for (const hsize_t d : expected) {
    if (d != 0 && bytes > fileSize / d)
      fail("dataset '" + hdf5::objectName(parent, name) + "' is larger than the file");
    bytes *= d;
  }
}

ResultsData readContents(hid_t file) {
  if (hdf5::readStringAttribute(file, "format") != kFormat) fail("not a hindsight topology results file");
  const int version = hdf5::readIntAttribute(file, "format_version");
  if (version != kFormatVersion) fail("format_version " + std::to_string(version) + " is not supported");
  ResultsData data;
  data.configurationJson = hdf5::readStringAttribute(file, "configuration");
  const int rowsSigned = hdf5::readIntAttribute(file, "completed_iterations");
  data.finished = hdf5::readIntAttribute(file, "finished") != 0;
  data.nx = hdf5::readIntAttribute(file, "nx");
  data.ny = hdf5::readIntAttribute(file, "ny");
  data.state.iteration = hdf5::readIntAttribute(file, "updates");
  data.state.objectiveScale = hdf5::readDoubleAttribute(file, "objective_scale");
  if (rowsSigned < 0 || data.nx < 1 || data.ny < 1 || data.state.iteration < 0)
    fail("inconsistent attributes");
  const auto rows = static_cast<hsize_t>(rowsSigned);

  {
    const hdf5::Handle group = hdf5::openGroup(file, "history");
    requireShape(file, group.get(), "iteration", {rows});
    std::vector<int> iteration(rows);
    hdf5::read(group.get(), "iteration", H5T_NATIVE_INT, {rows}, iteration.data());
    data.history.resize(rows);
    for (hsize_t k = 0; k < rows; ++k) data.history[k].iteration = iteration[k];
    hdf5::read(group.get(), "backtracks", H5T_NATIVE_INT, {rows}, iteration.data());
    for (hsize_t k = 0; k < rows; ++k) data.history[k].backtracks = iteration[k];
    std::vector<double> column(rows);
    for (const auto& [name, member] : kHistoryColumns) {
      hdf5::read(group.get(), name, H5T_NATIVE_DOUBLE, {rows}, column.data());
      for (hsize_t k = 0; k < rows; ++k) data.history[k].*member = column[k];
    }
  }
  {
    const auto nx = static_cast<hsize_t>(data.nx);
    const auto ny = static_cast<hsize_t>(data.ny);
    requireShape(file, file, "designs", {rows, ny, nx});
    std::vector<double> designs(rows * nx * ny);
    hdf5::read(file, "designs", H5T_NATIVE_DOUBLE, {rows, ny, nx}, designs.data());
    for (hsize_t k = 0; k < rows; ++k) {
      data.densities.push_back(
          Eigen::Map<const Vector>(designs.data() + k * nx * ny, static_cast<Eigen::Index>(nx * ny)));
    }
  }
  {
    const hdf5::Handle group = hdf5::openGroup(file, "state");
    const hsize_t size = shapeOf(group.get(), "design", 1)[0];
    if (size < 1) fail("dataset 'state/design' is empty");
    requireShape(file, group.get(), "design", {size});
    data.state.design = readVector(group.get(), "design", size);
    data.state.mma.xold1 = readVector(group.get(), "mma_xold1", size);
    data.state.mma.xold2 = readVector(group.get(), "mma_xold2", size);
    data.state.mma.low = readVector(group.get(), "mma_low", size);
    data.state.mma.upp = readVector(group.get(), "mma_upp", size);
    data.state.mma.iteration = hdf5::readIntAttribute(group.get(), "mma_iteration");
  }
  {
    const hdf5::Handle group = hdf5::openGroup(file, "final");
    const std::vector<hsize_t> dims = shapeOf(group.get(), "modes", 2);
    requireShape(file, group.get(), "modes", dims);
    const hsize_t modeCount = dims[0];
    data.finalModes.resize(static_cast<Eigen::Index>(dims[1]), static_cast<Eigen::Index>(modeCount));
    hdf5::read(group.get(), "modes", H5T_NATIVE_DOUBLE, dims, data.finalModes.data());
    data.finalFrequenciesHz.resize(modeCount);
    hdf5::read(group.get(), "frequencies_hz", H5T_NATIVE_DOUBLE, {modeCount}, data.finalFrequenciesHz.data());
  }
  return data;
}

// What the HDF5 layer and the checks above throw, as the StorageError this file's interface promises.
[[noreturn]] void rethrow(const hdf5::Error& e, const std::string& path) {
  throw StorageError("results file: " + std::string(e.what()), path);
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

  const hdf5::ErrorSilencer quiet;
  writeFileAtomically(path, [&](const std::string& temporary) {
    try {
      hdf5::Handle file = hdf5::createFile(temporary, H5F_ACC_TRUNC, "the results file");
      writeContents(file.get(), data);
      hdf5::closeFile(file);
    } catch (const hdf5::Error& e) {
      rethrow(e, path);
    }
  });
}

ResultsData readResultsFile(const std::string& path) {
  const hdf5::ErrorSilencer quiet;
  try {
    const hdf5::Handle file = hdf5::openFileReadOnly(path, "the results file");
    return readContents(file.get());
  } catch (const hdf5::Error& e) {
    rethrow(e, path);
  }
}

std::string readResultsConfiguration(const std::string& path) {
  const hdf5::ErrorSilencer quiet;
  try {
    const hdf5::Handle file = hdf5::openFileReadOnly(path, "the results file");
    if (hdf5::readStringAttribute(file.get(), "format") != kFormat)
      fail("not a hindsight topology results file");
    return hdf5::readStringAttribute(file.get(), "configuration");
  } catch (const hdf5::Error& e) {
    rethrow(e, path);
  }
}

}  // namespace hindsight
