// Building damaged HDF5 files for the reader fuzz tests: objects of random shape and type written with
// the plain C API (the readers must not trust what a file says about itself), and byte-level damage
// of a good file (truncation as after a crash, flipped bits as on a bad disk).
#pragma once

#include "fuzz/fuzz_support.h"

#include <hdf5.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace hindsight::fuzz {

/// Silences HDF5's error printing in the test itself (the readers silence their own).
class QuietHdf5 {
 public:
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &function_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, function_, data_); }
  QuietHdf5(const QuietHdf5&) = delete;
  QuietHdf5& operator=(const QuietHdf5&) = delete;

 private:
  H5E_auto2_t function_ = nullptr;
  void* data_ = nullptr;
};

/// HDF5 identifiers (files, groups, datasets, attributes, ...) open in this process: a reader must
/// close everything it opened, also when it throws half-way through a damaged file.
inline ssize_t openHdf5Objects() { return H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL); }

/// Doubles a damaged file may hold: inside and at the edges of a design's range, and non-finite ones.
inline double interestingDouble(Mutator& m) {
  static const std::vector<double> values = {0.5,
                                             1.0,
                                             0.01,
                                             0.0099999,
                                             1.0000001,
                                             0.0,
                                             -0.0,
                                             -1.0,
                                             2.0,
                                             1e308,
                                             std::numeric_limits<double>::denorm_min(),
                                             std::numeric_limits<double>::quiet_NaN(),
                                             std::numeric_limits<double>::infinity(),
                                             -std::numeric_limits<double>::infinity()};
  return m.chance(0.7) ? 0.01 + 0.99 * std::uniform_real_distribution<double>(0.0, 1.0)(m.rng())
                       : m.pick(values);
}

/// Integers a damaged file may hold where a count or size belongs.
inline long long interestingInteger(Mutator& m) {
  static const std::vector<long long> values = {0,           1,
                                                2,           3,
                                                4,           5,
                                                7,           -1,
                                                -2,          1000,
                                                1 << 20,     (1LL << 31) - 1,
                                                1LL << 31,   -(1LL << 31),
                                                1LL << 40,   (1LL << 62),
                                                -(1LL << 62)};
  return m.pick(values);
}

/// A dataspace of random rank (0 = scalar) with dimensions near `like` (or exactly it).
inline std::vector<hsize_t> randomDims(Mutator& m, const std::vector<hsize_t>& like) {
  if (m.chance(0.4)) return like;
  std::vector<hsize_t> dims(m.below(4));
  for (std::size_t d = 0; d < dims.size(); ++d) {
    const hsize_t base = d < like.size() ? like[d] : 3;
    dims[d] = m.chance(0.2) ? 0 : (m.chance(0.5) ? base : 1 + m.below(9));
  }
  return dims;
}

/// Creates dataset `name` of `dims` with a random type (float64 either byte order, float32, int32,
/// uint8, fixed-length string) holding random values. False when HDF5 refuses (then nothing is made).
inline bool writeRandomDataset(Mutator& m, hid_t parent, const char* name, const std::vector<hsize_t>& dims) {
  const hid_t space = dims.empty() ? H5Screate(H5S_SCALAR)
                                   : H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
  if (space < 0) return false;
  hsize_t count = 1;
  for (hsize_t d : dims) count *= d;
  const int kind = static_cast<int>(m.below(6));
  hid_t fileType = -1;
  bool ok = false;
  if (kind == 5) {
    fileType = H5Tcopy(H5T_C_S1);
    H5Tset_size(fileType, 8);
  } else {
    const hid_t types[] = {H5T_IEEE_F64LE, H5T_IEEE_F64BE, H5T_IEEE_F32LE, H5T_STD_I32LE, H5T_STD_U8LE};
    fileType = H5Tcopy(types[kind]);
  }
  const hid_t dataset = H5Dcreate2(parent, name, fileType, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (dataset >= 0) {
    if (count == 0) {
      ok = true;
    } else if (kind == 5) {
      std::string text(count * 8, 'a');
      ok = H5Dwrite(dataset, fileType, H5S_ALL, H5S_ALL, H5P_DEFAULT, text.data()) >= 0;
    } else {
      std::vector<double> values(count);
      // Integer file types get finite values: HDF5's own conversion of NaN to an integer is not ours to test.
      for (double& v : values) v = kind >= 3 ? std::floor(10.0 * interestingDouble(m)) : interestingDouble(m);
      if (kind >= 3) {
        for (double& v : values) v = std::isfinite(v) ? std::fmax(-1e6, std::fmin(v, 1e6)) : 0.0;
      }
      ok = H5Dwrite(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) >= 0;
    }
    H5Dclose(dataset);
  }
  H5Tclose(fileType);
  H5Sclose(space);
  return ok;
}

/// Replaces attribute `name` of `object` (if any) with a random one: a scalar or an array, an int, a
/// double or a fixed-length string.
inline void writeRandomAttribute(Mutator& m, hid_t object, const char* name) {
  if (H5Aexists(object, name) > 0) H5Adelete(object, name);
  const hsize_t length = m.chance(0.6) ? 1 : m.below(6);  // 0 and more than one element included
  const hid_t space =
      m.chance(0.5) && length == 1 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &length, nullptr);
  if (space < 0) return;
  const int kind = static_cast<int>(m.below(3));
  hid_t type = kind == 0 ? H5Tcopy(H5T_STD_I32LE) : kind == 1 ? H5Tcopy(H5T_IEEE_F64LE) : H5Tcopy(H5T_C_S1);
  if (kind == 2) H5Tset_size(type, 1 + m.below(40));
  const hid_t attribute = H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
  if (attribute >= 0) {
    if (kind == 0) {
      std::vector<int> values(std::max<hsize_t>(length, 1));
      for (int& v : values) v = static_cast<int>(interestingInteger(m));
      H5Awrite(attribute, H5T_NATIVE_INT, values.data());
    } else if (kind == 1) {
      std::vector<double> values(std::max<hsize_t>(length, 1));
      for (double& v : values)
        v = m.chance(0.5) ? static_cast<double>(interestingInteger(m)) : interestingDouble(m);
      H5Awrite(attribute, H5T_NATIVE_DOUBLE, values.data());
    } else {
      std::string text(H5Tget_size(type) * std::max<hsize_t>(length, 1), 'h');
      if (m.chance(0.5))
        text.replace(
            0, std::min<std::size_t>(text.size(), 26),
            std::string("hindsight-topology-results").substr(0, std::min<std::size_t>(text.size(), 26)));
      H5Awrite(attribute, type, text.data());
    }
    H5Aclose(attribute);
  }
  H5Tclose(type);
  H5Sclose(space);
}

/// A good file's bytes damaged: cut short, bits flipped, stretches overwritten with random or zero
/// bytes. The HDF5 signature is kept most of the time so that the damage reaches past the library's
/// first check.
inline std::string damageBytes(Mutator& m, std::string bytes) {
  switch (m.below(4)) {
    case 0:  // truncated, as by a crash in the middle of a write
      bytes.resize(m.below(bytes.size()));
      break;
    case 1: {  // a few flipped bits
      const int flips = 1 + static_cast<int>(m.below(4));
      for (int f = 0; f < flips && !bytes.empty(); ++f)
        bytes[m.below(bytes.size())] ^= static_cast<char>(1u << m.below(8));
      break;
    }
    case 2: {  // a stretch of random bytes past the signature
      if (bytes.size() <= 8) break;
      const std::size_t at = 8 + m.below(bytes.size() - 8);
      const std::size_t length = std::min<std::size_t>(bytes.size() - at, 1 + m.below(64));
      for (std::size_t i = 0; i < length; ++i) bytes[at + i] = static_cast<char>(m.below(256));
      break;
    }
    default: {  // a stretch of zeros past the signature
      if (bytes.size() <= 8) break;
      const std::size_t at = 8 + m.below(bytes.size() - 8);
      const std::size_t length = std::min<std::size_t>(bytes.size() - at, 1 + m.below(512));
      std::fill(bytes.begin() + static_cast<std::ptrdiff_t>(at),
                bytes.begin() + static_cast<std::ptrdiff_t>(at + length), '\0');
      break;
    }
  }
  return bytes;
}

}  // namespace hindsight::fuzz
