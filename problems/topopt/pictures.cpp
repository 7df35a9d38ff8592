#include <hindsight/problems/topopt/pictures.h>

#include <hindsight/storage/atomic_file.h>

#include <png.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace hindsight {
namespace {

void CheckField(const char* function, int nx, int ny, ConstVectorRef density) {
  if (nx < 1)
    throw std::invalid_argument(std::string(function) + ": nx = " + std::to_string(nx) + " must be >= 1");
  if (ny < 1)
    throw std::invalid_argument(std::string(function) + ": ny = " + std::to_string(ny) + " must be >= 1");
  if (density.size() != static_cast<Eigen::Index>(nx) * ny) {
    throw std::invalid_argument(std::string(function) + ": density has length " +
                                std::to_string(density.size()) +
                                ", expected nx * ny = " + std::to_string(static_cast<long long>(nx) * ny));
  }
}

std::string SystemError(const std::string& what) { return what + ": " + std::strerror(errno); }

}  // namespace

void writeDensityPng(const std::string& path, int nx, int ny, ConstVectorRef density,
                     int pixels_per_element) {
  CheckField("writeDensityPng", nx, ny, density);
  if (pixels_per_element < 1) {
    throw std::invalid_argument(
        "writeDensityPng: pixels_per_element = " + std::to_string(pixels_per_element) + " must be >= 1");
  }
  const long long width = static_cast<long long>(nx) * pixels_per_element;
  const long long height = static_cast<long long>(ny) * pixels_per_element;
  if (width * height > std::numeric_limits<int>::max()) {
    throw std::invalid_argument(
        "writeDensityPng: the image of " + std::to_string(width) + " x " + std::to_string(height) +
        " pixels is too large; reduce pixels_per_element = " + std::to_string(pixels_per_element));
  }
  for (Eigen::Index e = 0; e < density.size(); ++e) {
    if (std::isnan(density(e)))
      throw std::invalid_argument("writeDensityPng: density(" + std::to_string(e) + ") is NaN");
  }

  // Image rows run top to bottom, element rows bottom to top.
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(width * height));
  for (long long py = 0; py < height; ++py) {
    const int row = ny - 1 - static_cast<int>(py / pixels_per_element);
    for (long long px = 0; px < width; ++px) {
      const int column = static_cast<int>(px / pixels_per_element);
      const double value = std::clamp(density(static_cast<Eigen::Index>(row) * nx + column), 0.0, 1.0);
      pixels[static_cast<std::size_t>(py * width + px)] =
          static_cast<std::uint8_t>(std::lround(255.0 * (1.0 - value)));
    }
  }

  writeStreamAtomically(path, [&](std::FILE* file) -> std::string {
    // libpng's simplified API reports errors through the image structure instead of longjmp.
    png_image image;
    std::memset(&image, 0, sizeof(image));
    image.version = PNG_IMAGE_VERSION;
    image.width = static_cast<png_uint_32>(width);
    image.height = static_cast<png_uint_32>(height);
    image.format = PNG_FORMAT_GRAY;
    const int ok =
        png_image_write_to_stdio(&image, file, 0, pixels.data(), static_cast<png_int_32>(width), nullptr);
    std::string error;
    if (ok == 0) error = std::string("libpng: ") + image.message;
    png_image_free(&image);
    return error;
  });
}

void writeDensityVtk(const std::string& path, int nx, int ny, ConstVectorRef density, double element_size) {
  CheckField("writeDensityVtk", nx, ny, density);
  if (!(element_size > 0.0 && std::isfinite(element_size))) {
    std::ostringstream out;
    out << "writeDensityVtk: element_size = " << element_size << " must be positive and finite";
    throw std::invalid_argument(out.str());
  }
  writeStreamAtomically(path, [&](std::FILE* file) -> std::string {
    int status = std::fprintf(file,
                              "# vtk DataFile Version 3.0\n"
                              "hindsight density field, %d x %d elements\n"
                              "ASCII\n"
                              "DATASET STRUCTURED_POINTS\n"
                              "DIMENSIONS %d %d 1\n"
                              "ORIGIN 0 0 0\n"
                              "SPACING %.17g %.17g %.17g\n"
                              "CELL_DATA %lld\n"
                              "SCALARS density double 1\n"
                              "LOOKUP_TABLE default\n",
                              nx, ny, nx + 1, ny + 1, element_size, element_size, element_size,
                              static_cast<long long>(density.size()));
    for (Eigen::Index e = 0; e < density.size() && status >= 0; ++e)
      status = std::fprintf(file, "%.17g\n", density(e));
    if (status < 0 || std::ferror(file)) return SystemError("cannot write VTK data");
    return {};
  });
}

}  // namespace hindsight
