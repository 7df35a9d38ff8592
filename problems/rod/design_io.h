// Designs and design-sized fields in HDF5 files, laid out as (ny, nx) arrays over ALL elements:
// element row j (bottom to top), column i (A to B). The interface columns i = 0 and i = nx-1 are
// not design variables; in a design they hold 1. Design variable d sits at column i = d / ny + 1,
// row j = d % ny (the order of rod::FeModel). The solid member's (rod.elementsThroughThickness = nz >= 1)
// are (nz, ny, nx) arrays, layer k (z upwards) first: design variable d = ((i - 1) ny + j) nz + k (the
// order of rod::SolidModel); "(ny, nx)" below then reads "(nz, ny, nx)".
#pragma once

#include <hindsight/engine/types.h>
#include <hindsight/problems/rod/rod_config.h>

#include <string>
#include <utility>
#include <vector>

namespace hindsight {

/// Reads dataset `x` of shape (ny, nx). Throws std::invalid_argument naming the file when it cannot
/// be opened, has no dataset x, has the wrong shape, holds a design value outside
/// [designLowerBound, 1] or NaN, or an interface-column value other than 1 (naming the row, column
/// and value).
Vector readDesignFile(const std::string& path, const rod::RodConfig& config);

/// The design variables of a (ny, nx) row-major grid over all elements (nx * ny values), checked as
/// readDesignFile checks dataset x: interface columns 1, design values in [designLowerBound, 1], no
/// NaN. Throws std::invalid_argument whose message starts with `source` ("design file 'x.h5'").
Vector gridToDesign(const rod::RodConfig& config, const double* grid, const std::string& source);

/// Writes each (name, values over design variables) as a (ny, nx) dataset; interface columns get
/// `interfaceValue` (1 for a design, 0 for a gradient). The file appears complete or not at all
/// (written to a temporary name, fsynced, then renamed: storage/atomic_file.h). Throws StorageError
/// naming the file on failure, std::invalid_argument when a field has the wrong length.
void writeDesignFields(const std::string& path, const rod::RodConfig& config,
                       const std::vector<std::pair<std::string, Vector>>& fields, double interfaceValue);

/// (ny, nx) of the plate, (nz, ny, nx) of the solid.
std::vector<std::size_t> designGridShape(const rod::RodConfig& config);

/// Design vector <-> (ny, nx) row-major array over all elements.
std::vector<double> designToGrid(const rod::RodConfig& config, ConstVectorRef values, double interfaceValue);

}  // namespace hindsight
