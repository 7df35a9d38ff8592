// Tests of the geometry export (problems/topopt/geometry_export.h): the enclosed area of the outline
// against the solid fraction (within one element row), holes oriented clockwise, a closed and
// consistently oriented STL (every edge in exactly two triangles, once in each direction, also after
// reading the written file back), the enclosed volume, and the SVG/DXF files' structure.
#include <hindsight/problems/topopt/geometry_export.h>

#include "support/file_checks.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <tuple>

#include <unistd.h>

namespace hindsight {
namespace {

namespace fs = std::filesystem;

// A rod-like crisp design: solid frame with elliptical holes and a diagonal web, 60 x 12 elements.
DensityField TrussDesign(int nx = 60, int ny = 12) {
  DensityField f;
  f.nx = nx;
  f.ny = ny;
  f.cellWidthMm = 2.5;
  f.cellHeightMm = 2.5;
  f.values = Vector::Zero(nx * ny);
  for (int r = 0; r < ny; ++r) {
    for (int c = 0; c < nx; ++c) {
      const double x = (c + 0.5) / nx, y = (r + 0.5) / ny;
      bool solid = r < 2 || r >= ny - 2 || c < 3 || c >= nx - 3;  // frame
      const double phase = std::fmod(x * 4.0, 1.0);
      if (std::abs(phase - y) < 0.12 || std::abs(phase - (1.0 - y)) < 0.12) solid = true;  // webs
      f.values(r * nx + c) = solid ? 1.0 : 0.01;
    }
  }
  return f;
}

double SolidArea(const DensityField& f, double iso) {
  int solid = 0;
  for (Eigen::Index e = 0; e < f.values.size(); ++e) solid += f.values(e) >= iso ? 1 : 0;
  return solid * f.cellWidthMm * f.cellHeightMm;
}

TEST(GeometryExport, EnclosedAreaMatchesTheSolidFractionWithinOneElementRow) {
  const DensityField f = TrussDesign();
  const Outline outline = contourOutline(f, 0.5);
  const double row = f.nx * f.cellWidthMm * f.cellHeightMm;
  std::cout << "[ outline  ] " << outline.loops.size() << " loops, area " << outline.area() << " mm^2, solid "
            << SolidArea(f, 0.5) << " mm^2, one row " << row << " mm^2\n";
  EXPECT_GT(outline.loops.size(), 3u);  // the outer boundary and holes
  EXPECT_NEAR(outline.area(), SolidArea(f, 0.5), row);
  // Exactly one counter-clockwise loop (the outer boundary, the design is connected); the holes are
  // clockwise.
  int positive = 0;
  for (const auto& loop : outline.loops) {
    Outline single;
    single.loops.push_back(loop);
    positive += single.area() > 0.0 ? 1 : 0;
  }
  EXPECT_EQ(positive, 1);
}

TEST(GeometryExport, GrayFieldAreaFollowsTheIsoValue) {
  // A smooth gray field (a dome): at every iso the contour is the interpolated level set, whose area
  // matches the count of elements above the iso within one element row, and shrinks as iso grows.
  DensityField f = TrussDesign(80, 16);
  for (int r = 0; r < f.ny; ++r) {
    for (int c = 0; c < f.nx; ++c) {
      const double x = (c + 0.5) / f.nx - 0.5, y = (r + 0.5) / f.ny - 0.5;
      f.values(r * f.nx + c) = std::clamp(1.0 - 2.0 * x * x - 3.0 * y * y, 0.0, 1.0);
    }
  }
  double previous = 1e300;
  for (double iso : {0.3, 0.5, 0.7, 0.9}) {
    const Outline outline = contourOutline(f, iso);
    EXPECT_EQ(outline.loops.size(), 1u) << iso;
    EXPECT_NEAR(outline.area(), SolidArea(f, iso), f.nx * f.cellWidthMm * f.cellHeightMm) << iso;
    EXPECT_LT(outline.area(), previous);
    previous = outline.area();
  }
  EXPECT_THROW(contourOutline(f, 1.0), std::invalid_argument);
  EXPECT_THROW(contourOutline(f, 0.0), std::invalid_argument);
}

// A low iso value must not draw the outline outside the rod: the crossings between a boundary element
// and the void around the rod (up to half an element beyond the edge at iso 0.1) end at the rod's edge.
// The solid and its volume stay consistent.
TEST(GeometryExport, LowIsoOutlineStaysWithinTheRod) {
  const DensityField f = TrussDesign();
  const double width = f.nx * f.cellWidthMm, height = f.ny * f.cellHeightMm;
  for (double iso : {0.05, 0.1, 0.3, 0.5}) {
    const Outline outline = contourOutline(f, iso);
    double lowX = 1e300, highX = -1e300, lowY = 1e300, highY = -1e300;
    for (const auto& loop : outline.loops) {
      for (const Eigen::Vector2d& point : loop) {
        lowX = std::min(lowX, point.x());
        highX = std::max(highX, point.x());
        lowY = std::min(lowY, point.y());
        highY = std::max(highY, point.y());
      }
    }
    EXPECT_GE(lowX, 0.0) << iso;
    EXPECT_LE(highX, width * (1 + 1e-15)) << iso;
    EXPECT_GE(lowY, 0.0) << iso;
    EXPECT_LE(highY, height * (1 + 1e-15)) << iso;
    // The solid frame reaches the edges: the outline spans the rod.
    EXPECT_NEAR(lowX, 0.0, 1e-9) << iso;
    EXPECT_NEAR(highX, width, 1e-9) << iso;
    EXPECT_LE(outline.area(), width * height * (1 + 1e-12)) << iso;
  }
}

// Every directed edge once, its reverse once: closed (each edge in two triangles) and consistently
// oriented.
void ExpectClosedAndOriented(const std::vector<std::array<int, 3>>& triangles) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& t : triangles) {
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  }
  int bad = 0;
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    if (count != 1 || reverse == directed.end() || reverse->second != 1) ++bad;
  }
  EXPECT_EQ(bad, 0) << "edges not shared by exactly two triangles in opposite directions";
}

TEST(GeometryExport, ExtrudedSolidIsClosedOrientedOutwardAndHasTheOutlineVolume) {
  const DensityField f = TrussDesign();
  const double thickness = 7.0;
  const TriangleMesh mesh = extrudedSolid(f, 0.5, thickness);
  ExpectClosedAndOriented(mesh.triangles);
  // Divergence theorem: the signed volume is area * thickness when every normal points outward.
  double volume = 0.0;
  for (const auto& t : mesh.triangles) {
    volume += mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]])) / 6.0;
  }
  EXPECT_NEAR(volume, contourOutline(f, 0.5).area() * thickness, 1e-9 * volume);
}

TEST(GeometryExport, WrittenFilesAreCompleteAndTheStlReadsBackClosed) {
  const fs::path dir = fs::temp_directory_path() / ("hindsight_geometry_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const DensityField f = TrussDesign();
  const std::vector<std::string> paths = exportGeometry((dir / "design").string(), f, 0.5, 7.0);
  ASSERT_EQ(paths.size(), 3u);
  EXPECT_EQ(testing::listing(dir), (std::set<std::string>{"design.svg", "design.dxf", "design.stl"}));

  // STL: vertices identified by their printed coordinates.
  std::ifstream stl(paths[2]);
  std::string word;
  std::map<std::string, int> ids;
  std::vector<std::array<int, 3>> triangles;
  std::array<int, 3> current{};
  int corner = 0;
  while (stl >> word) {
    if (word != "vertex") continue;
    std::string x, y, z;
    stl >> x >> y >> z;
    const auto it = ids.emplace(x + " " + y + " " + z, static_cast<int>(ids.size())).first;
    current[corner++] = it->second;
    if (corner == 3) {
      triangles.push_back(current);
      corner = 0;
    }
  }
  EXPECT_EQ(triangles.size(), extrudedSolid(f, 0.5, 7.0).triangles.size());
  ExpectClosedAndOriented(triangles);

  std::ifstream dxf(paths[1]);
  std::stringstream dxfText;
  dxfText << dxf.rdbuf();
  const std::string d = dxfText.str();
  std::size_t polylines = 0;
  for (std::size_t at = d.find("POLYLINE"); at != std::string::npos; at = d.find("POLYLINE", at + 1))
    ++polylines;
  EXPECT_EQ(polylines, contourOutline(f, 0.5).loops.size());
  EXPECT_NE(d.find("$INSUNITS\n70\n4\n"), std::string::npos);  // millimetres
  EXPECT_NE(d.rfind("0\nEOF\n"), std::string::npos);

  std::ifstream svg(paths[0]);
  std::stringstream svgText;
  svgText << svg.rdbuf();
  EXPECT_NE(svgText.str().find("viewBox=\"0 0 150 30\""), std::string::npos);
  EXPECT_NE(svgText.str().find("</svg>"), std::string::npos);
  fs::remove_all(dir);
}

TEST(GeometryExport, BadInputThrowsNamingTheProblem) {
  DensityField f = TrussDesign();
  f.values.resize(5);
  EXPECT_THROW(contourOutline(f, 0.5), std::invalid_argument);
  EXPECT_THROW(extrudedSolid(TrussDesign(), 0.5, 0.0), std::invalid_argument);
  try {
    contourOutline(TrussDesign(), 1.5);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--iso"), std::string::npos);
  }
}

}  // namespace
}  // namespace hindsight
