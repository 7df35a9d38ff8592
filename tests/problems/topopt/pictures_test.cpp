// Tests of the design pictures: the PNG decodes (with libpng) to the expected pixels with row 0 at the
// bottom, the VTK file has the right header, cell count and exact values, and failures throw
// StorageError without leaving files behind.
#include <hindsight/problems/topopt/pictures.h>
#include "support/file_checks.h"
#include "support/fresh_directory.h"

#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight {
namespace {

namespace fs = std::filesystem;

// A fresh, empty directory per test (tests/support/fresh_directory.h removes it at the end).
fs::path TestDirectory() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = testing::freshDirectory(std::string("pictures/") + info->name());
  fs::create_directories(dir);
  return dir;
}

using testing::expectStorageErrorNaming;
using testing::listing;

struct Gray {
  unsigned width = 0, height = 0, fileFormat = 0;
  std::vector<std::uint8_t> pixels;
};

Gray DecodePng(const std::string& path) {
  png_image image;
  std::memset(&image, 0, sizeof(image));
  image.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_file(&image, path.c_str()) == 0)
    throw std::runtime_error(std::string("cannot decode PNG: ") + image.message);
  Gray result;
  result.fileFormat = image.format;
  image.format = PNG_FORMAT_GRAY;
  result.width = image.width;
  result.height = image.height;
  result.pixels.resize(PNG_IMAGE_SIZE(image));
  if (png_image_finish_read(&image, nullptr, result.pixels.data(), 0, nullptr) == 0)
    throw std::runtime_error(std::string("cannot decode PNG: ") + image.message);
  return result;
}

TEST(Pictures, PngDecodesToExpectedPixelsWithRowZeroAtTheBottom) {
  const fs::path dir = TestDirectory();
  const int nx = 5, ny = 3, scale = 4;
  Vector density(nx * ny);
  for (int e = 0; e < nx * ny; ++e) density(e) = e / double(nx * ny - 1);  // 0 .. 1
  density(0) = 1.0;                                                        // bottom-left: black
  density(nx * ny - 1) = 0.0;                                              // top-right: white
  density(1) = 1.7;                                                        // clamped to black
  density(2) = -0.3;                                                       // clamped to white
  const std::string path = (dir / "field.png").string();
  writeDensityPng(path, nx, ny, density, scale);

  const Gray image = DecodePng(path);
  EXPECT_EQ(image.fileFormat, static_cast<unsigned>(PNG_FORMAT_GRAY));  // stored as 8-bit gray
  ASSERT_EQ(image.width, unsigned(nx * scale));
  ASSERT_EQ(image.height, unsigned(ny * scale));
  for (unsigned py = 0; py < image.height; ++py) {
    for (unsigned px = 0; px < image.width; ++px) {
      const int row = ny - 1 - int(py) / scale;
      const int column = int(px) / scale;
      const double value = std::min(1.0, std::max(0.0, density(row * nx + column)));
      EXPECT_EQ(int(image.pixels[py * image.width + px]), int(std::lround(255.0 * (1.0 - value))))
          << "pixel (" << px << ", " << py << ")";
    }
  }
  // The corners in plain words: element 0 is at the bottom-left of the picture.
  EXPECT_EQ(image.pixels[(image.height - 1) * image.width + 0], 0);
  EXPECT_EQ(image.pixels[0 * image.width + image.width - 1], 255);
  EXPECT_EQ(listing(dir), std::set<std::string>{"field.png"});  // no temporary left
}

// The rod's 200 x 12 layout with a recognisable pattern, for looking at: solid end columns, solid top
// and bottom chords, diagonal struts, and a black 10 x 3 block at the bottom-left to show the
// orientation. The test checks the size; the picture itself was checked by eye.
TEST(Pictures, RodDesignPictureHasTheRodsSize) {
  const fs::path dir = TestDirectory();
  const int nx = 200, ny = 12;
  Vector density = Vector::Constant(nx * ny, 0.01);
  for (int row = 0; row < ny; ++row) {
    for (int column = 0; column < nx; ++column) {
      double& x = density(row * nx + column);
      if (column == 0 || column == nx - 1 || row == 0 || row == ny - 1) x = 1.0;
      if (std::abs((column % 24) - 2 * row) <= 1) x = 0.6;  // struts
      if (column < 10 && row < 3) x = 1.0;
    }
  }
  const std::string path = (dir / "rod.png").string();
  writeDensityPng(path, nx, ny, density);
  const Gray image = DecodePng(path);
  EXPECT_EQ(image.width, 800u);
  EXPECT_EQ(image.height, 48u);
}

TEST(Pictures, VtkFileHasHeaderCellCountAndExactValues) {
  const fs::path dir = TestDirectory();
  const int nx = 7, ny = 4;
  Vector density(nx * ny);
  for (int e = 0; e < nx * ny; ++e) density(e) = std::sin(0.3 * e) * std::sin(0.3 * e) + 1e-3 / 3.0;
  const std::string path = (dir / "field.vtk").string();
  writeDensityVtk(path, nx, ny, density, 0.005);

  std::ifstream in(path);
  ASSERT_TRUE(in.good());
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "# vtk DataFile Version 3.0");
  std::vector<std::string> header;
  for (int i = 0; i < 9 && std::getline(in, line); ++i) header.push_back(line);
  ASSERT_EQ(header.size(), 9u);
  EXPECT_EQ(header[1], "ASCII");
  EXPECT_EQ(header[2], "DATASET STRUCTURED_POINTS");
  EXPECT_EQ(header[3], "DIMENSIONS 8 5 1");
  EXPECT_EQ(header[6], "CELL_DATA 28");
  EXPECT_EQ(header[7], "SCALARS density double 1");
  EXPECT_EQ(header[8], "LOOKUP_TABLE default");
  std::istringstream spacing(header[5]);
  std::string keyword;
  double dx = 0, dy = 0;
  spacing >> keyword >> dx >> dy;
  EXPECT_EQ(keyword, "SPACING");
  EXPECT_EQ(dx, 0.005);
  EXPECT_EQ(dy, 0.005);

  std::vector<double> values;
  double value = 0;
  while (in >> value) values.push_back(value);
  EXPECT_TRUE(in.eof());  // nothing but numbers after the header
  ASSERT_EQ(values.size(), std::size_t(nx * ny));
  for (int e = 0; e < nx * ny; ++e) EXPECT_EQ(values[e], density(e)) << e;  // 17 digits: exact
}

TEST(Pictures, UnwritablePathThrowsStorageErrorAndLeavesNoFile) {
  const fs::path dir = TestDirectory();
  const Vector density = Vector::Constant(6, 0.5);

  // A directory that does not exist: nothing can be created.
  const std::string missing = (dir / "no_such_directory" / "design.png").string();
  expectStorageErrorNaming([&] { writeDensityPng(missing, 3, 2, density); }, missing);
  expectStorageErrorNaming([&] { writeDensityVtk(missing, 3, 2, density); }, missing);
  EXPECT_FALSE(fs::exists(missing));

  // The target is an existing non-empty directory: the temporary file is written completely, the
  // rename fails, and the temporary must be removed again. (Permission bits do not stop root, so
  // this is the portable way to make the last step fail.)
  const fs::path occupied = dir / "occupied";
  fs::create_directories(occupied / "inside");
  const std::set<std::string> before = listing(dir);
  expectStorageErrorNaming([&] { writeDensityPng(occupied.string(), 3, 2, density); }, occupied.string());
  expectStorageErrorNaming([&] { writeDensityVtk(occupied.string(), 3, 2, density); }, occupied.string());
  EXPECT_EQ(listing(dir), before);
  EXPECT_TRUE(fs::is_directory(occupied / "inside"));
}

TEST(Pictures, BadArgumentsThrowInvalidArgument) {
  const fs::path dir = TestDirectory();
  const std::string path = (dir / "bad.png").string();
  const Vector six = Vector::Constant(6, 0.5);
  auto expectNaming = [](auto&& call, const std::string& name) {
    try {
      call();
      ADD_FAILURE() << "no exception; expected one naming " << name;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  expectNaming([&] { writeDensityPng(path, 0, 6, six); }, "nx = 0");
  expectNaming([&] { writeDensityPng(path, 3, 3, six); }, "density has length 6");
  expectNaming([&] { writeDensityPng(path, 3, 2, six, 0); }, "pixels_per_element = 0");
  Vector withNan = six;
  withNan(4) = std::nan("");
  expectNaming([&] { writeDensityPng(path, 3, 2, withNan); }, "density(4)");
  expectNaming([&] { writeDensityVtk(path, 3, -1, six); }, "ny = -1");
  expectNaming([&] { writeDensityVtk(path, 3, 2, six, 0.0); }, "element_size");
  EXPECT_TRUE(listing(dir).empty());
}

}  // namespace
}  // namespace hindsight
