#include <hindsight/problems/rod/design_io.h>

#include <hindsight/storage/atomic_file.h>
#include <hindsight/storage/hdf5.h>

#include <iomanip>
#include <sstream>

namespace hindsight {

namespace {

// The grid's layers: 1 for the plate, nz for the solid, whose grid is (nz, ny, nx) with layer k at
// index (k ny + j) nx + i and design variable d = ((i - 1) ny + j) nz + k (problems/rod/solid_model.h).
int layersOf(const rod::RodConfig& config) { return config.isSolid() ? config.elementsThroughThickness : 1; }

struct Cell {
  int i, j, k;
};

Cell cellOf(const rod::RodConfig& config, int d) {
  const int ny = config.elementsThroughHeight, layers = layersOf(config);
  return {d / (ny * layers) + 1, (d / layers) % ny, d % layers};
}

std::size_t gridIndex(const rod::RodConfig& config, const Cell& c) {
  return (static_cast<std::size_t>(c.k) * config.elementsThroughHeight + c.j) * config.elementsAlongLength +
         c.i;
}

// "x[j][i] (row j, column i)" of the plate, "x[k][j][i] (layer k, row j, column i)" of the solid.
std::string cellName(const rod::RodConfig& config, const Cell& c, const char* column) {
  const std::string layer = config.isSolid() ? "[" + std::to_string(c.k) + "]" : "";
  const std::string layerWord = config.isSolid() ? "layer " + std::to_string(c.k) + ", " : "";
  return "x" + layer + "[" + std::to_string(c.j) + "][" + std::to_string(c.i) + "] (" + layerWord + "row " +
         std::to_string(c.j) + ", " + column + std::to_string(c.i) + ")";
}

}  // namespace

std::vector<std::size_t> designGridShape(const rod::RodConfig& config) {
  const auto ny = static_cast<std::size_t>(config.elementsThroughHeight);
  const auto nx = static_cast<std::size_t>(config.elementsAlongLength);
  if (config.isSolid()) return {static_cast<std::size_t>(config.elementsThroughThickness), ny, nx};
  return {ny, nx};
}

std::vector<double> designToGrid(const rod::RodConfig& config, ConstVectorRef values, double interfaceValue) {
  const int nx = config.elementsAlongLength, ny = config.elementsThroughHeight;
  if (values.size() != config.designCount()) {
    throw std::invalid_argument("design field has " + std::to_string(values.size()) + " values, expected " +
                                std::to_string(config.designCount()));
  }
  std::vector<double> grid(static_cast<std::size_t>(nx) * ny * layersOf(config), interfaceValue);
  for (int d = 0; d < config.designCount(); ++d) grid[gridIndex(config, cellOf(config, d))] = values(d);
  return grid;
}

Vector gridToDesign(const rod::RodConfig& config, const double* grid, const std::string& source) {
  const int nx = config.elementsAlongLength, ny = config.elementsThroughHeight;
  // The interface columns are rigid (not design variables) and hold 1; any other value there means
  // the file is not the design the user thinks it is, so it is refused rather than replaced.
  for (int k = 0; k < layersOf(config); ++k) {
    for (int j = 0; j < ny; ++j) {
      for (const int i : {0, nx - 1}) {
        const Cell c{i, j, k};
        const double v = grid[gridIndex(config, c)];
        if (v != 1.0) {
          std::ostringstream value;
          value << std::setprecision(17) << v;
          throw std::invalid_argument(source + ": " + cellName(config, c, "interface column ") + " = " +
                                      value.str() + " must be 1: the end columns are not design variables");
        }
      }
    }
  }
  Vector design(config.designCount());
  for (int d = 0; d < config.designCount(); ++d) {
    const Cell c = cellOf(config, d);
    const double v = grid[gridIndex(config, c)];
    if (!(v >= config.designLowerBound && v <= 1.0)) {
      std::ostringstream value;
      value << std::setprecision(17) << v;
      throw std::invalid_argument(source + ": " + cellName(config, c, "column ") + " = " + value.str() +
                                  " is outside [" + std::to_string(config.designLowerBound) + ", 1]");
    }
    design(d) = v;
  }
  return design;
}

Vector readDesignFile(const std::string& path, const rod::RodConfig& config) {
  const hdf5::ErrorSilencer quiet;
  // A user's input: a bad file is bad input (exit code 2), not a storage failure.
  hdf5::Handle file;
  try {
    file = hdf5::openFileReadOnly(path);
  } catch (const hdf5::Error&) {
    throw std::invalid_argument("cannot open design file '" + path + "' as HDF5");
  }
  if (!hdf5::exists(file.get(), "x"))
    throw std::invalid_argument("design file '" + path + "' has no dataset 'x'");
  const std::vector<std::size_t> gridShape = designGridShape(config);
  const std::vector<hsize_t> shape(gridShape.begin(), gridShape.end());
  std::vector<double> grid(static_cast<std::size_t>(config.elementsAlongLength) *
                           config.elementsThroughHeight * layersOf(config));
  try {
    if (hdf5::shape(hdf5::openDataset(file.get(), "x").get()) != shape) {
      const int nx = config.elementsAlongLength, ny = config.elementsThroughHeight;
      throw std::invalid_argument(
          "dataset 'x' in '" + path + "' must have shape " +
          (config.isSolid() ? "(nz, ny, nx) = (" + std::to_string(config.elementsThroughThickness) + ", "
                            : std::string("(ny, nx) = (")) +
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
  const std::vector<std::size_t> gridShape = designGridShape(config);
  const std::vector<hsize_t> dims(gridShape.begin(), gridShape.end());
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
