#include <hindsight/problems/topopt/geometry_export.h>

#include <hindsight/storage/atomic_file.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <string>

namespace hindsight {
namespace {

// Crossings stay this fraction of an edge away from the samples (no vertex on a sample point).
constexpr double kEdgeMargin = 1e-6;

void checkField(const DensityField& f, double iso) {
  if (f.nx < 1 || f.ny < 1)
    throw std::invalid_argument("geometry export: nx = " + std::to_string(f.nx) +
                                ", ny = " + std::to_string(f.ny) + " must be >= 1");
  if (f.values.size() != static_cast<Eigen::Index>(f.nx) * f.ny)
    throw std::invalid_argument("geometry export: the density field has " + std::to_string(f.values.size()) +
                                " values, expected nx * ny = " + std::to_string(f.nx * f.ny));
  if (!f.values.allFinite()) throw std::invalid_argument("geometry export: the density field is not finite");
  if (!(f.cellWidthMm > 0.0 && f.cellHeightMm > 0.0 && std::isfinite(f.cellWidthMm) &&
        std::isfinite(f.cellHeightMm)))
    throw std::invalid_argument("geometry export: element width and height must be > 0");
  if (!(iso > 0.0 && iso < 1.0)) {
    std::ostringstream out;
    out << "--iso " << iso << " must be in (0, 1)";
    throw std::invalid_argument(out.str());
  }
}

// The marching-squares decomposition: shared 2-D vertices, convex pieces (CCW vertex lists) and the
// outline segments (inside on the left).
struct Decomposition {
  std::vector<Eigen::Vector2d> points;
  std::vector<std::vector<int>> pieces;
  std::vector<std::array<int, 2>> segments;
};

Decomposition decompose(const DensityField& f, double iso) {
  checkField(f, iso);
  // Samples (I, J), I = 0..nx+1, J = 0..ny+1: element (I-1, J-1) inside, void on the ring.
  const int sx = f.nx + 2;
  const int sy = f.ny + 2;
  auto sample = [&](int i, int j) {
    if (i < 1 || i > f.nx || j < 1 || j > f.ny) return 0.0;
    return f.values((j - 1) * f.nx + (i - 1));
  };
  auto position = [&](int i, int j) {
    return Eigen::Vector2d((i - 0.5) * f.cellWidthMm, (j - 0.5) * f.cellHeightMm);
  };
  Decomposition out;
  std::vector<int> corner(static_cast<std::size_t>(sx) * sy, -1);
  std::vector<int> horizontal(static_cast<std::size_t>(sx) * sy, -1);  // edge (I,J)-(I+1,J)
  std::vector<int> vertical(static_cast<std::size_t>(sx) * sy, -1);    // edge (I,J)-(I,J+1)
  auto cornerId = [&](int i, int j) {
    int& id = corner[static_cast<std::size_t>(j) * sx + i];
    if (id < 0) {
      id = static_cast<int>(out.points.size());
      out.points.push_back(position(i, j));
    }
    return id;
  };
  // Crossing on the edge from sample a = (i, j) to b = (i + di, j + dj), di + dj = 1.
  auto crossingId = [&](int i, int j, bool alongX) {
    int& id = (alongX ? horizontal : vertical)[static_cast<std::size_t>(j) * sx + i];
    if (id < 0) {
      const double va = sample(i, j);
      const double vb = alongX ? sample(i + 1, j) : sample(i, j + 1);
      const double t = std::clamp((iso - va) / (vb - va), kEdgeMargin, 1.0 - kEdgeMargin);
      const Eigen::Vector2d a = position(i, j);
      const Eigen::Vector2d b = alongX ? position(i + 1, j) : position(i, j + 1);
      Eigen::Vector2d point = a + t * (b - a);
      if (iso < 0.5) {
        // Between a boundary element (density <= 1) and the void ring, a crossing at iso < 0.5 lies up to
        // half an element outside the rod; the rod ends at its edge, so the outline does too. (For
        // iso >= 0.5 every crossing is inside by construction, and left untouched.)
        point.x() = std::clamp(point.x(), 0.0, f.nx * f.cellWidthMm);
        point.y() = std::clamp(point.y(), 0.0, f.ny * f.cellHeightMm);
      }
      id = static_cast<int>(out.points.size());
      out.points.push_back(point);
    }
    return id;
  };

  for (int j = 0; j + 1 < sy; ++j) {
    for (int i = 0; i + 1 < sx; ++i) {
      const int ci[4] = {i, i + 1, i + 1, i};
      const int cj[4] = {j, j, j + 1, j + 1};
      bool in[4];
      double sum = 0.0;
      int count = 0;
      for (int k = 0; k < 4; ++k) {
        const double v = sample(ci[k], cj[k]);
        in[k] = v >= iso;
        sum += v;
        count += in[k] ? 1 : 0;
      }
      if (count == 0) continue;
      // Edge k joins corner k and k + 1: e0 bottom, e1 right, e2 top, e3 left (canonical ids).
      auto edge = [&](int k) {
        switch (k) {
          case 0:
            return crossingId(i, j, true);
          case 1:
            return crossingId(i + 1, j, false);
          case 2:
            return crossingId(i, j + 1, true);
          default:
            return crossingId(i, j, false);
        }
      };
      const bool saddle = count == 2 && in[0] == in[2];
      if (saddle && sum / 4.0 < iso) {
        // Two separate corners: a triangle at each.
        const int first = in[0] ? 0 : 1;
        for (int k : {first, first + 2}) {
          const int a = edge(k);
          const int b = edge((k + 3) % 4);
          out.pieces.push_back({cornerId(ci[k], cj[k]), a, b});
          out.segments.push_back({a, b});
        }
        continue;
      }
      std::vector<int> piece;
      std::vector<bool> isCrossing;
      for (int k = 0; k < 4; ++k) {
        if (in[k]) {
          piece.push_back(cornerId(ci[k], cj[k]));
          isCrossing.push_back(false);
        }
        if (in[k] != in[(k + 1) % 4]) {
          piece.push_back(edge(k));
          isCrossing.push_back(true);
        }
      }
      const std::size_t size = piece.size();
      for (std::size_t a = 0; a < size; ++a) {
        const std::size_t b = (a + 1) % size;
        if (isCrossing[a] && isCrossing[b]) out.segments.push_back({piece[a], piece[b]});
      }
      out.pieces.push_back(std::move(piece));
    }
  }
  return out;
}

std::string formatNumber(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.9g", value);
  return buffer;
}

}  // namespace

double Outline::area() const {
  double twice = 0.0;
  for (const auto& loop : loops) {
    for (std::size_t a = 0; a < loop.size(); ++a) {
      const Eigen::Vector2d& p = loop[a];
      const Eigen::Vector2d& q = loop[(a + 1) % loop.size()];
      twice += p.x() * q.y() - q.x() * p.y();
    }
  }
  return 0.5 * twice;
}

Outline contourOutline(const DensityField& field, double iso) {
  const Decomposition d = decompose(field, iso);
  // Every crossing starts exactly one segment and ends exactly one: chain them into loops.
  std::vector<int> next(d.points.size(), -1);
  for (const auto& s : d.segments) next[static_cast<std::size_t>(s[0])] = s[1];
  std::vector<bool> used(d.points.size(), false);
  Outline outline;
  for (const auto& s : d.segments) {
    if (used[static_cast<std::size_t>(s[0])]) continue;
    std::vector<Eigen::Vector2d> loop;
    int v = s[0];
    while (v >= 0 && !used[static_cast<std::size_t>(v)]) {
      used[static_cast<std::size_t>(v)] = true;
      loop.push_back(d.points[static_cast<std::size_t>(v)]);
      v = next[static_cast<std::size_t>(v)];
    }
    outline.loops.push_back(std::move(loop));
  }
  return outline;
}

TriangleMesh extrudedSolid(const DensityField& field, double iso, double thicknessMm) {
  if (!(thicknessMm > 0.0 && std::isfinite(thicknessMm)))
    throw std::invalid_argument("geometry export: the thickness must be > 0 and finite");
  const Decomposition d = decompose(field, iso);
  TriangleMesh mesh;
  const int count = static_cast<int>(d.points.size());
  // Vertex v at the bottom (z = 0) is v, at the top (z = thickness) v + count; unused ones are removed below.
  std::vector<Eigen::Vector3d> all(2 * static_cast<std::size_t>(count));
  for (int v = 0; v < count; ++v) {
    all[static_cast<std::size_t>(v)] = Eigen::Vector3d(d.points[v].x(), d.points[v].y(), 0.0);
    all[static_cast<std::size_t>(v + count)] = Eigen::Vector3d(d.points[v].x(), d.points[v].y(), thicknessMm);
  }
  std::vector<std::array<int, 3>> triangles;
  for (const auto& piece : d.pieces) {
    for (std::size_t k = 1; k + 1 < piece.size(); ++k) {
      triangles.push_back({piece[0] + count, piece[k] + count, piece[k + 1] + count});  // top, normal +z
      triangles.push_back({piece[0], piece[k + 1], piece[k]});                          // bottom, normal -z
    }
  }
  for (const auto& s : d.segments) {
    // Inside on the left of a -> b: the wall's outward normal is (dy, -dx).
    triangles.push_back({s[0], s[1], s[1] + count});
    triangles.push_back({s[0], s[1] + count, s[0] + count});
  }
  std::vector<int> renumber(all.size(), -1);
  for (auto& t : triangles) {
    for (int& v : t) {
      int& r = renumber[static_cast<std::size_t>(v)];
      if (r < 0) {
        r = static_cast<int>(mesh.vertices.size());
        mesh.vertices.push_back(all[static_cast<std::size_t>(v)]);
      }
      v = r;
    }
  }
  mesh.triangles = std::move(triangles);
  return mesh;
}

void writeOutlineSvg(const std::string& path, const Outline& outline, double widthMm, double heightMm) {
  std::string text = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  text += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + formatNumber(widthMm) + "mm\" height=\"" +
          formatNumber(heightMm) + "mm\" viewBox=\"0 0 " + formatNumber(widthMm) + " " +
          formatNumber(heightMm) + "\">\n";
  text += "<!-- hindsight design outline, millimetres, y up in the model (flipped here) -->\n";
  text += "<path fill=\"black\" fill-rule=\"evenodd\" stroke=\"none\" d=\"";
  for (const auto& loop : outline.loops) {
    for (std::size_t a = 0; a < loop.size(); ++a) {
      text += (a == 0 ? "M" : " L") + formatNumber(loop[a].x()) + " " + formatNumber(heightMm - loop[a].y());
    }
    text += " Z ";
  }
  text += "\"/>\n</svg>\n";
  writeBytesAtomically(path, text.data(), text.size(), "the SVG file");
}

void writeOutlineDxf(const std::string& path, const Outline& outline) {
  // AutoCAD R12 ASCII DXF: one closed POLYLINE per loop on layer OUTLINE; $INSUNITS 4 = millimetres.
  std::string text = "0\nSECTION\n2\nHEADER\n9\n$ACADVER\n1\nAC1009\n9\n$INSUNITS\n70\n4\n0\nENDSEC\n";
  text += "0\nSECTION\n2\nENTITIES\n";
  for (const auto& loop : outline.loops) {
    text += "0\nPOLYLINE\n8\nOUTLINE\n66\n1\n70\n1\n10\n0.0\n20\n0.0\n30\n0.0\n";
    for (const Eigen::Vector2d& p : loop)
      text += "0\nVERTEX\n8\nOUTLINE\n10\n" + formatNumber(p.x()) + "\n20\n" + formatNumber(p.y()) +
              "\n30\n0.0\n";
    text += "0\nSEQEND\n8\nOUTLINE\n";
  }
  text += "0\nENDSEC\n0\nEOF\n";
  writeBytesAtomically(path, text.data(), text.size(), "the DXF file");
}

void writeSolidStl(const std::string& path, const TriangleMesh& mesh) {
  std::string text = "solid hindsight_design\n";
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices[static_cast<std::size_t>(t[0])];
    const Eigen::Vector3d& b = mesh.vertices[static_cast<std::size_t>(t[1])];
    const Eigen::Vector3d& c = mesh.vertices[static_cast<std::size_t>(t[2])];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() > 0.0) n.normalize();
    text += "facet normal " + formatNumber(n.x()) + " " + formatNumber(n.y()) + " " + formatNumber(n.z()) +
            "\n outer loop\n";
    for (const Eigen::Vector3d* p : {&a, &b, &c})
      text +=
          "  vertex " + formatNumber(p->x()) + " " + formatNumber(p->y()) + " " + formatNumber(p->z()) + "\n";
    text += " endloop\nendfacet\n";
  }
  text += "endsolid hindsight_design\n";
  writeBytesAtomically(path, text.data(), text.size(), "the STL file");
}

namespace {

void checkBoxField(const BoxDensityField& field) {
  if (field.nx < 1 || field.ny < 1 || field.nz < 1 ||
      field.values.size() != static_cast<Eigen::Index>(field.nx) * field.ny * field.nz)
    throw std::invalid_argument("BoxDensityField: values must have nx ny nz >= 1 entries");
  if (!(field.cellWidthMm > 0.0 && field.cellHeightMm > 0.0 && field.cellDepthMm > 0.0))
    throw std::invalid_argument("BoxDensityField: the cell sizes must be > 0");
}

}  // namespace

double BoxDensityField::at(int i, int j, int layer) const {
  // With symmetry the whole body's layers run from the back face: layer nz - 1 - k mirrors layer k.
  const int k = !midPlaneSymmetry ? layer : (layer < nz ? nz - 1 - layer : layer - nz);
  return values((static_cast<Eigen::Index>(i) * ny + j) * nz + k);
}

TriangleMesh voxelSurface(const BoxDensityField& field, double iso) {
  checkBoxField(field);
  if (!(iso > 0.0 && iso < 1.0))
    throw std::invalid_argument("voxelSurface: iso = " + std::to_string(iso) + " must be in (0, 1)");
  const int nx = field.nx, ny = field.ny, nz = field.layers();
  auto solid = [&](int i, int j, int k) {
    return i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz && field.at(i, j, k) >= iso;
  };
  TriangleMesh mesh;
  std::vector<int> index(static_cast<std::size_t>(nx + 1) * (ny + 1) * (nz + 1), -1);
  auto vertex = [&](int i, int j, int k) {
    int& v = index[(static_cast<std::size_t>(i) * (ny + 1) + j) * (nz + 1) + k];
    if (v < 0) {
      v = static_cast<int>(mesh.vertices.size());
      mesh.vertices.emplace_back(i * field.cellWidthMm, j * field.cellHeightMm, k * field.cellDepthMm);
    }
    return v;
  };
  // Face of element (i, j, k) towards axis a, side s (0: low, 1: high): its four corners counter-clockwise
  // seen from outside, i.e. along the outward normal (the axes' cyclic order b = a + 1, c = a + 2 gives
  // e_b x e_c = e_a on the high side; the low side is the reverse).
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) {
        if (!solid(i, j, k)) continue;
        for (int a = 0; a < 3; ++a) {
          for (int side = 0; side < 2; ++side) {
            int n[3] = {i, j, k};
            n[a] += side == 0 ? -1 : 1;
            if (solid(n[0], n[1], n[2])) continue;
            const int b = (a + 1) % 3, c = (a + 2) % 3;
            int corner[4][3];
            const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
            for (int q = 0; q < 4; ++q) {
              int p[3] = {i, j, k};
              p[a] += side;
              p[b] += du[q];
              p[c] += dv[q];
              for (int e = 0; e < 3; ++e) corner[q][e] = p[e];
            }
            int v[4];
            for (int q = 0; q < 4; ++q) v[q] = vertex(corner[q][0], corner[q][1], corner[q][2]);
            if (side == 1) {
              mesh.triangles.push_back({v[0], v[1], v[2]});
              mesh.triangles.push_back({v[0], v[2], v[3]});
            } else {
              mesh.triangles.push_back({v[0], v[2], v[1]});
              mesh.triangles.push_back({v[0], v[3], v[2]});
            }
          }
        }
      }
    }
  }
  return mesh;
}

void writeDensityVtu(const std::string& path, const BoxDensityField& field) {
  checkBoxField(field);
  const int nx = field.nx, ny = field.ny, nz = field.layers();
  Matrix points(3, static_cast<Eigen::Index>(nx + 1) * (ny + 1) * (nz + 1));
  Eigen::Index column = 0;
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      for (int k = 0; k <= nz; ++k, ++column)
        points.col(column) << i * field.cellWidthMm, j * field.cellHeightMm, k * field.cellDepthMm;
    }
  }
  writeDensityVtu(path, field, points, {});
}

void writeDensityVtu(const std::string& path, const BoxDensityField& field, ConstMatrixRef points,
                     const std::vector<std::pair<std::string, Matrix>>& pointVectors) {
  checkBoxField(field);
  const int nx = field.nx, ny = field.ny, nz = field.layers();
  const long pointCount = static_cast<long>(nx + 1) * (ny + 1) * (nz + 1);
  const long cells = static_cast<long>(nx) * ny * nz;
  auto checkPoints = [&](const Matrix& m, const std::string& name) {
    if (m.rows() != 3 || m.cols() != pointCount)
      throw std::invalid_argument("writeDensityVtu: " + name + " is " + std::to_string(m.rows()) + " x " +
                                  std::to_string(m.cols()) + ", expected 3 x " + std::to_string(pointCount) +
                                  " (the grid's points)");
  };
  checkPoints(points, "points");
  for (const auto& [name, values] : pointVectors) checkPoints(values, "point vector '" + name + "'");
  auto point = [&](int i, int j, int k) { return (static_cast<long>(i) * (ny + 1) + j) * (nz + 1) + k; };
  auto appendVectors = [](std::string& text, const Matrix& m) {
    for (Eigen::Index c = 0; c < m.cols(); ++c)
      text += formatNumber(m(0, c)) + " " + formatNumber(m(1, c)) + " " + formatNumber(m(2, c)) + "\n";
  };
  std::string text =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" "
      "byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"" +
      std::to_string(pointCount) + "\" NumberOfCells=\"" + std::to_string(cells) + "\">\n";
  text += "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  appendVectors(text, points);
  text +=
      "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" "
      "format=\"ascii\">\n";
  // VTK_HEXAHEDRON's order: the bottom face counter-clockwise, then the top face.
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) {
        const long ids[8] = {
            point(i, j, k),     point(i + 1, j, k),     point(i + 1, j + 1, k),     point(i, j + 1, k),
            point(i, j, k + 1), point(i + 1, j, k + 1), point(i + 1, j + 1, k + 1), point(i, j + 1, k + 1)};
        for (long id : ids) text += std::to_string(id) + " ";
        text += "\n";
      }
    }
  }
  text += "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  for (long c = 1; c <= cells; ++c) text += std::to_string(8 * c) + "\n";
  text += "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (long c = 0; c < cells; ++c) text += "12\n";
  text += "</DataArray>\n</Cells>\n";
  if (!pointVectors.empty()) {
    text += "<PointData Vectors=\"" + pointVectors.front().first + "\">\n";
    for (const auto& [name, values] : pointVectors) {
      text +=
          "<DataArray type=\"Float64\" Name=\"" + name + "\" NumberOfComponents=\"3\" format=\"ascii\">\n";
      appendVectors(text, values);
      text += "</DataArray>\n";
    }
    text += "</PointData>\n";
  }
  text +=
      "<CellData Scalars=\"density\">\n<DataArray type=\"Float64\" "
      "Name=\"density\" format=\"ascii\">\n";
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) text += formatNumber(field.at(i, j, k)) + "\n";
    }
  }
  text += "</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  writeBytesAtomically(path, text.data(), text.size(), "the VTU file");
}

std::vector<std::string> exportSolidGeometry(const std::string& stem, const BoxDensityField& field,
                                             double iso) {
  const TriangleMesh surface = voxelSurface(field, iso);
  const std::vector<std::string> paths = {stem + ".stl", stem + ".vtu"};
  writeSolidStl(paths[0], surface);
  writeDensityVtu(paths[1], field);
  return paths;
}

std::vector<std::string> exportGeometry(const std::string& stem, const DensityField& field, double iso,
                                        double thicknessMm) {
  const Outline outline = contourOutline(field, iso);
  const TriangleMesh mesh = extrudedSolid(field, iso, thicknessMm);
  const std::vector<std::string> paths = {stem + ".svg", stem + ".dxf", stem + ".stl"};
  writeOutlineSvg(paths[0], outline, field.nx * field.cellWidthMm, field.ny * field.cellHeightMm);
  writeOutlineDxf(paths[1], outline);
  writeSolidStl(paths[2], mesh);
  return paths;
}

}  // namespace hindsight
