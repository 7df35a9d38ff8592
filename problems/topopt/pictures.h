// Pictures of a density field on the nx x ny grid of square elements: a PNG for reports and a VTK
// file for ParaView.
//
// Element numbering is that of problems/topopt/density_filter.h: element (column, row) has index
// e = row * nx + column, row 0 at the bottom. Densities are the design variables, nominally in [0, 1].
//
// Both writers write to a temporary file beside the target and rename it onto the target only when
// everything was written and flushed to disk, so a crash or an I/O error never leaves a half-written
// picture under the target name (an existing file of that name is replaced only on success).
// I/O failures throw hindsight::StorageError whose path() is the target file; bad arguments throw
// std::invalid_argument naming the argument.
#pragma once

#include <hindsight/engine/types.h>

#include <string>

namespace hindsight {

/// Writes `density` (length nx * ny) as an 8-bit grayscale PNG of (nx * pixels_per_element) x
/// (ny * pixels_per_element) pixels: density 1 is black, 0 white, linear in between (values outside
/// [0, 1] are clamped), each element a square of pixels_per_element pixels, row 0 at the bottom of
/// the image. 4 pixels per element make the 200 x 12 rod an 800 x 48 image.
/// Throws std::invalid_argument when nx, ny or pixels_per_element is < 1, the length is wrong, a
/// density is NaN or the image would exceed 2^31 - 1 pixels; hindsight::StorageError when the file
/// cannot be written.
void writeDensityPng(const std::string& path, int nx, int ny, ConstVectorRef density,
                     int pixels_per_element = 4);

/// Writes `density` (length nx * ny) as a legacy ASCII VTK file (STRUCTURED_POINTS; opens in ParaView
/// and VisIt): (nx + 1) x (ny + 1) points with spacing element_size (in metres for the rod: 0.005),
/// origin (0, 0, 0), and one cell scalar "density" per element in the element numbering above, which
/// is VTK's cell order (x fastest). Values are written with 17 significant digits, so they read back
/// exactly. Throws std::invalid_argument when nx or ny is < 1, the length is wrong or element_size is
/// not positive and finite; hindsight::StorageError when the file cannot be written.
void writeDensityVtk(const std::string& path, int nx, int ny, ConstVectorRef density,
                     double element_size = 1.0);

}  // namespace hindsight
