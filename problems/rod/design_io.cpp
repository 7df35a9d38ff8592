#include <hindsight/problems/rod/design_io.h>

#include <hindsight/storage/atomic_file.h>
#include <hindsight/storage/hdf5.h>

#include <iomanip>
#include <sstream>

namespace hindsight {

std::vector<double> designToGrid(const rod::RodConfig& config, ConstVectorRef values, double interfaceValue) {
  const int nx = config.elementsAlongLength, ny = config.elementsThroughHeight;
  if (values.size() != config.designCount()) {
    throw std::invalid_argument("design field has " + std::to_string(values.size()) + " values, expected " +
                                std::to_string(config.designCount()));
  }
  std::vector<double> grid(static_cast<std::size_t>(nx) * ny, interfaceValue);
  for (int d = 0; d < config.designCount(); ++d) {
    const int i = d / ny + 1, j = d % ny;
    grid[static_cast<std::size_t>(j) * nx + i] = values(d);
  }
  return grid;
}

Vector gridToDesign(const rod::RodConfig& config, const double* grid, const std::string& source) {
  const int nx = config.elementsAlongLength, ny = config.elementsThroughHeight;
  // The interface columns are rigid (not design variables) and hold 1; any other value there means
  // the file is not the design the user thinks it is, so it is refused rather than replaced.
  for (int j = 0; j < ny; ++j) {
    for (const int i : {0, nx - 1}) {
      const double v = grid[static_cast<std::size_t>(j) * nx + i];
      if (v != 1.0) {
        std::ostringstream value;
        value << std::setprecision(17) << v;
        throw std::invalid_argument(source + ": x[" + std::to_string(j) + "][" + std::to_string(i) +
                                    "] (row " + std::to_string(j) + ", interface column " +
                                    std::to_string(i) + ") = " + value.str() +
                                    " must be 1: the end columns are not design variables");
      }
    }
  }
  Vector design(config.designCount());
  for (int d = 0; d < config.designCount(); ++d) {
    const int i = d / ny + 1, j = d % ny;
    const double v = grid[static_cast<std::size_t>(j) * nx + i];
    if (!(v >= config.designLowerBound && v <= 1.0)) {
      std::ostringstream value;
      value << std::setprecision(17) << v;
      throw std::invalid_argument(source + ": x[" + std::to_string(j) + "][" + std::to_string(i) + "] (row " +
                                  std::to_string(j) + ", column " + std::to_string(i) + ") = " + value.str() +
                                  " is outside [" + std::to_string(config.designLowerBound) + ", 1]");
    }
    design(d) = v;
  }
  return design;
}

Vector readDesignFile(const std::string& path, const rod::RodConfig& config) {
  const hdf5::ErrorSilencer quiet;
  const int nx = config.elementsAlongLength, ny = config.elementsThroughHeight;
  // A user's input: a bad file is bad input (exit code 2), not a storage failure.
  hdf5::Handle file;
  try {
    file = hdf5::openFileReadOnly(path);
  } catch (const hdf5::Error&) {
    throw std::invalid_argument("cannot open design file '" + path + "' as HDF5");
  }
  if (!hdf5::exists(file.get(), "x"))
    throw std::invalid_argument("design file '" + path + "' has no dataset 'x'");
  const std::vector<hsize_t> shape = {static_cast<hsize_t>(ny), static_cast<hsize_t>(nx)};
  std::vector<double> grid(static_cast<std::size_t>(nx) * ny);
  try {
    if (hdf5::shape(hdf5::openDataset(file.get(), "x").get()) != shape) {
      throw std::invalid_argument("dataset 'x' in '" + path + "' must have shape (ny, nx) = (" +
                                  std::to_string(ny) + ", " + std::to_string(nx) + ")");
    }
    hdf5::read(file.get(), "x", H5T_NATIVE_DOUBLE, shape, grid.data());
  } catch (const hdf5::Error& e) {
    throw std::invalid_argument("design file '" + path + "': " + e.what());
  }
  return gridToDesign(config, grid.data(), "design file '" + path + "'");
}

void writeDesignFields(const std::string& path, const rod::RodConfig& config,
                       const std::vector<std::pair<std::string, Vector>>& fields, double interfaceValue) {
  const hdf5::ErrorSilencer quiet;
  const std::vector<hsize_t> dims = {static_cast<hsize_t>(config.elementsThroughHeight),
                                     static_cast<hsize_t>(config.elementsAlongLength)};
  writeFileAtomically(path, [&](const std::string& temporary) {
    try {
      hdf5::Handle file = hdf5::createFile(temporary, H5F_ACC_TRUNC, "the design file");
      for (const auto& [name, values] : fields) {
        hdf5::writeDoubles(file.get(), name, dims, designToGrid(config, values, interfaceValue).data());
      }
      hdf5::closeFile(file);
    } catch (const hdf5::Error& e) {
      throw StorageError(e.what(), path);
    }
  });
}

}  // namespace hindsight
