#include <hindsight/problems/rod/design_io.h>

#include <hdf5.h>

#include <unistd.h>
#include <cstdio>

namespace hindsight {
namespace {

/// Silences HDF5's automatic error printing for the lifetime of the object; errors are reported
/// through exceptions instead.
class QuietHdf5 {
 public:
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &function_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, function_, data_); }

 private:
  H5E_auto2_t function_ = nullptr;
  void* data_ = nullptr;
};

/// Closes an HDF5 handle at scope exit.
struct Handle {
  hid_t id;
  herr_t (*close)(hid_t);
  ~Handle() {
    if (id >= 0) close(id);
  }
};

}  // namespace

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

Vector readDesignFile(const std::string& path, const rod::RodConfig& config) {
  QuietHdf5 quiet;
  const int nx = config.elementsAlongLength, ny = config.elementsThroughHeight;
  Handle file{H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  if (file.id < 0) throw std::invalid_argument("cannot open design file '" + path + "' as HDF5");
  Handle dataset{H5Dopen2(file.id, "x", H5P_DEFAULT), H5Dclose};
  if (dataset.id < 0) throw std::invalid_argument("design file '" + path + "' has no dataset 'x'");
  Handle space{H5Dget_space(dataset.id), H5Sclose};
  hsize_t dims[2] = {0, 0};
  if (H5Sget_simple_extent_ndims(space.id) != 2 || H5Sget_simple_extent_dims(space.id, dims, nullptr) != 2 ||
      dims[0] != static_cast<hsize_t>(ny) || dims[1] != static_cast<hsize_t>(nx)) {
    throw std::invalid_argument("dataset 'x' in '" + path + "' must have shape (ny, nx) = (" +
                                std::to_string(ny) + ", " + std::to_string(nx) + ")");
  }
  std::vector<double> grid(static_cast<std::size_t>(nx) * ny);
  if (H5Dread(dataset.id, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, grid.data()) < 0) {
    throw std::invalid_argument("cannot read dataset 'x' of '" + path + "'");
  }
  Vector design(config.designCount());
  for (int d = 0; d < config.designCount(); ++d) {
    const int i = d / ny + 1, j = d % ny;
    const double v = grid[static_cast<std::size_t>(j) * nx + i];
    if (!(v >= config.designLowerBound && v <= 1.0)) {
      throw std::invalid_argument("design file '" + path + "': x[" + std::to_string(j) + "][" +
                                  std::to_string(i) + "] = " + std::to_string(v) + " is outside [" +
                                  std::to_string(config.designLowerBound) + ", 1]");
    }
    design(d) = v;
  }
  return design;
}

void writeDesignFields(const std::string& path, const rod::RodConfig& config,
                       const std::vector<std::pair<std::string, Vector>>& fields, double interfaceValue) {
  QuietHdf5 quiet;
  const std::string temporary = path + ".tmp-" + std::to_string(::getpid());
  bool ok = true;
  {
    Handle file{H5Fcreate(temporary.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose};
    if (file.id < 0) throw StorageError("cannot create HDF5 file", path);
    const hsize_t dims[2] = {static_cast<hsize_t>(config.elementsThroughHeight),
                             static_cast<hsize_t>(config.elementsAlongLength)};
    for (const auto& [name, values] : fields) {
      const std::vector<double> grid = designToGrid(config, values, interfaceValue);
      Handle space{H5Screate_simple(2, dims, nullptr), H5Sclose};
      Handle dataset{
          H5Dcreate2(file.id, name.c_str(), H5T_IEEE_F64LE, space.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
          H5Dclose};
      ok = ok && dataset.id >= 0 &&
           H5Dwrite(dataset.id, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, grid.data()) >= 0;
    }
    ok = ok && H5Fflush(file.id, H5F_SCOPE_GLOBAL) >= 0;
  }
  if (!ok || std::rename(temporary.c_str(), path.c_str()) != 0) {
    std::remove(temporary.c_str());
    throw StorageError("cannot write HDF5 file (disk full or not writable?)", path);
  }
}

}  // namespace hindsight
