// The geometry of a design for CAD: the contour of the density field at an iso value (default 0.5) as a
// 2-D outline (SVG, DXF) and as a closed solid, the outline extruded by the rod thickness (STL).
//
// Method: marching squares on the element densities sampled at the element centres, with a ring of
// void (density 0) around the grid so that every contour closes; crossings are interpolated linearly
// along the sampling-grid edges (kept at least 1e-6 of an edge away from the samples, so no contour
// vertex coincides with a sample point). A saddle cell is connected when the mean of its four
// samples is >= iso. Inside means density >= iso. Each marching-squares cell contributes a convex
// piece of the solid region (corners inside and crossings, counter-clockwise); the pieces tile the
// region and share their vertices exactly along common cell edges. So:
//   - the outline loops (SVG, DXF) are the piece edges between two crossings, chained: outer
//     boundaries counter-clockwise, holes clockwise (y up);
//   - the STL solid is every piece fan-triangulated as top (z = thickness) and bottom (z = 0) cap plus
//     two triangles per outline segment as the wall: watertight by construction (every edge is shared
//     by exactly two triangles, in opposite directions), outward normals.
// Written by hand: no Debian package does marching squares to SVG, DXF and STL; the algorithm is small.
//
// Coordinates are millimetres: x along the rod from the left face (joint A side), y up from the bottom
// face; element (column c, row r) spans [c w, (c+1) w] x [r h, (r+1) h] with w = L / nx, h = H / ny.
// The region of a solid 0/1 design is the union of its solid elements up to corners cut by
// marching squares (1/8 of an element per convex corner, added per concave one).
//
// Files are written atomically (storage/atomic_file.h): PATH is absent or complete.
#pragma once

#include <hindsight/engine/types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <string>
#include <utility>
#include <vector>

namespace hindsight {

/// A density field on the rod's element grid: values[row * nx + column] (pictures.h numbering).
struct DensityField {
  int nx = 0;
  int ny = 0;
  Vector values;
  double cellWidthMm = 1.0;
  double cellHeightMm = 1.0;
};

/// Closed outline loops in millimetres; outer boundaries counter-clockwise, holes clockwise.
struct Outline {
  std::vector<std::vector<Eigen::Vector2d>> loops;
  /// Signed shoelace area of all loops [mm^2]: the enclosed area (holes subtract).
  double area() const;
};

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;  ///< counter-clockwise seen from outside
};

/// The contour at `iso` (in (0, 1)) and the extruded solid of thickness `thicknessMm` (> 0).
/// Throws std::invalid_argument naming the argument for a bad size, value or iso.
Outline contourOutline(const DensityField& field, double iso);
TriangleMesh extrudedSolid(const DensityField& field, double iso, double thicknessMm);

/// Writers. Throw StorageError naming the path when the file cannot be written.
void writeOutlineSvg(const std::string& path, const Outline& outline, double widthMm, double heightMm);
void writeOutlineDxf(const std::string& path, const Outline& outline);
void writeSolidStl(const std::string& path, const TriangleMesh& mesh);

/// STEM.svg, STEM.dxf and STEM.stl of `field` at `iso`, extruded by thicknessMm. Returns the paths.
std::vector<std::string> exportGeometry(const std::string& stem, const DensityField& field, double iso,
                                        double thicknessMm);

// ---- The solid member (problems/rod/solid_model.h): densities on a box grid. ----

/// Element densities of the solid, values[(i ny + j) nz + k] (SolidModel's element order: column i along
/// the length, row j through the height, layer k through the thickness), on boxes of the given sizes.
/// With midPlaneSymmetry the layers are the half z >= 0 (layer 0 at the mid-plane); the writers below
/// mirror it into the whole body.
struct BoxDensityField {
  int nx = 0, ny = 0, nz = 0;
  Vector values;
  double cellWidthMm = 1.0, cellHeightMm = 1.0, cellDepthMm = 1.0;
  bool midPlaneSymmetry = false;
  /// The whole body's layers (2 nz with symmetry) and the density of layer k of the whole body.
  int layers() const { return midPlaneSymmetry ? 2 * nz : nz; }
  double at(int i, int j, int layer) const;
};

/// The surface of the elements with density >= iso: every face between such an element and one below
/// iso (or the outside), two triangles each, counter-clockwise seen from outside (outward normals),
/// vertices shared at the grid points. A closed surface: every directed edge has its reverse, so each
/// edge is shared by an even number of triangles, exactly two except where two solid elements touch only
/// along an edge (there four). Coordinates in mm: x along the rod from A's face, y up from the bottom, z
/// from the back face. Throws std::invalid_argument for a bad size or iso outside (0, 1).
TriangleMesh voxelSurface(const BoxDensityField& field, double iso);
/// The densities as a VTK XML unstructured grid (.vtu, ASCII) of hexahedra with the cell field
/// "density": ParaView opens it. The whole body (mirrored with symmetry), mm.
void writeDensityVtu(const std::string& path, const BoxDensityField& field);
/// The same grid and densities with its points at `points` (3 x (nx + 1)(ny + 1)(layers() + 1), column
/// (i (ny + 1) + j)(layers() + 1) + layer) and the point vectors `pointVectors` (name, 3 x points each;
/// the first is the active one): the deformed member of solid_motion_export.h. Throws
/// std::invalid_argument for a matrix of another size.
void writeDensityVtu(const std::string& path, const BoxDensityField& field, ConstMatrixRef points,
                     const std::vector<std::pair<std::string, Matrix>>& pointVectors);
/// STEM.stl (voxelSurface at iso) and STEM.vtu of the solid's field. Returns the paths.
std::vector<std::string> exportSolidGeometry(const std::string& stem, const BoxDensityField& field,
                                             double iso);

}  // namespace hindsight
