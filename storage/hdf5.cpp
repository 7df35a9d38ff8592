#include <hindsight/storage/hdf5.h>

#include <algorithm>
#include <mutex>

namespace hindsight::hdf5 {
namespace {

// The error stack's innermost entries say what went wrong ("Permission denied"); the outer ones only
// repeat which API call failed.
herr_t collectError(unsigned depth, const H5E_error2_t* error, void* data) {
  auto* out = static_cast<std::string*>(data);
  if (depth < 3 && error->desc != nullptr) *out += (out->empty() ? "" : "; ") + std::string(error->desc);
  return 0;
}

std::string join(const std::vector<hsize_t>& dims) {
  std::string text = "(";
  for (std::size_t i = 0; i < dims.size(); ++i) text += (i > 0 ? ", " : "") + std::to_string(dims[i]);
  return text + ")";
}

hsize_t elementCount(const std::vector<hsize_t>& dims) {
  hsize_t count = 1;
  for (hsize_t d : dims) count *= d;
  return count;
}

// Throws Error for `action` on the object `name` below `parent` (empty name: `parent` itself). The
// stack is read before anything else calls HDF5 and clears it.
[[noreturn]] void fail(hid_t parent, const std::string& action, const std::string& name = {}) {
  const std::string reason = errorMessage();
  throw Error(action + " '" + objectName(parent, name) + "': " + reason, fileName(parent));
}

hid_t checked(hid_t id, hid_t parent, const std::string& action, const std::string& name = {}) {
  if (id < 0) fail(parent, action, name);
  return id;
}

void checked(herr_t status, hid_t parent, const std::string& action, const std::string& name = {}) {
  if (status < 0) fail(parent, action, name);
}

std::string rowRange(hsize_t first, hsize_t count) {
  return std::to_string(first) + ".." + std::to_string(first + count - 1);
}

// The file-space selection of rows [first, first + count[0]) and a memory space of `count`.
struct RowSelection {
  Handle fileSpace;
  Handle memorySpace;
};

RowSelection selectRows(hid_t dataset, hsize_t first, const std::vector<hsize_t>& count,
                        const std::string& action) {
  RowSelection selection;
  selection.fileSpace = Handle(checked(H5Dget_space(dataset), dataset, action), H5Sclose);
  std::vector<hsize_t> start(count.size(), 0);
  start[0] = first;
  checked(H5Sselect_hyperslab(selection.fileSpace.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                              nullptr),
          dataset, action);
  selection.memorySpace = Handle(
      checked(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr), dataset, action),
      H5Sclose);
  return selection;
}

void writeScalarAttribute(hid_t object, const std::string& name, hid_t memoryType, hid_t fileType,
                          const void* value) {
  const std::string action = "cannot write attribute '" + name + "' of";
  Handle space(checked(H5Screate(H5S_SCALAR), object, action), H5Sclose);
  Handle attribute(checked(H5Acreate2(object, name.c_str(), fileType, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                           object, action),
                   H5Aclose);
  checked(H5Awrite(attribute.get(), memoryType, value), object, action);
}

Handle openAttribute(hid_t object, const std::string& name) {
  if (!hasAttribute(object, name)) {
    throw Error("attribute '" + name + "' of '" + objectName(object, {}) + "' is missing", fileName(object));
  }
  return Handle(
      checked(H5Aopen(object, name.c_str(), H5P_DEFAULT), object, "cannot open attribute '" + name + "' of"),
      H5Aclose);
}

// H5Aread writes every element of the attribute, so one that a damaged or foreign file stores as an
// array would overflow the caller's single value: refuse anything but exactly one element.
void requireOneElement(hid_t object, hid_t attribute, const std::string& name) {
  const std::string action = "cannot read attribute '" + name + "' of";
  Handle space(checked(H5Aget_space(attribute), object, action), H5Sclose);
  if (H5Sget_simple_extent_npoints(space.get()) != 1) {  // negative: HDF5 failed, also refused
    throw Error("attribute '" + name + "' of '" + objectName(object, {}) + "' is not a single value",
                fileName(object));
  }
}

void readScalarAttribute(hid_t object, const std::string& name, hid_t memoryType, void* value) {
  Handle attribute = openAttribute(object, name);
  requireOneElement(object, attribute.get(), name);
  checked(H5Aread(attribute.get(), memoryType, value), object, "cannot read attribute '" + name + "' of");
}

#ifndef H5_HAVE_THREADSAFE
// Without thread safety HDF5 has one printing switch for the process: silencers share it by count.
std::mutex silencerMutex;
int silencerCount = 0;
H5E_auto2_t savedFunction = nullptr;
void* savedData = nullptr;
#endif

}  // namespace

Handle& Handle::operator=(Handle&& other) noexcept {
  if (this != &other) {
    reset();
    id_ = other.id_;
    close_ = other.close_;
    other.id_ = -1;
  }
  return *this;
}

bool Handle::reset() {
  const herr_t status = id_ >= 0 ? close_(id_) : 0;
  id_ = -1;
  return status >= 0;
}

ErrorSilencer::ErrorSilencer() {
#ifdef H5_HAVE_THREADSAFE
  H5Eget_auto2(H5E_DEFAULT, &function_, &data_);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
#else
  std::lock_guard<std::mutex> lock(silencerMutex);
  if (silencerCount++ == 0) {
    H5Eget_auto2(H5E_DEFAULT, &savedFunction, &savedData);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
#endif
}

ErrorSilencer::~ErrorSilencer() {
#ifdef H5_HAVE_THREADSAFE
  H5Eset_auto2(H5E_DEFAULT, function_, data_);
#else
  std::lock_guard<std::mutex> lock(silencerMutex);
  if (--silencerCount == 0) H5Eset_auto2(H5E_DEFAULT, savedFunction, savedData);
#endif
}

std::string errorMessage() {
  std::string message;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, &collectError, &message);
  H5Eclear2(H5E_DEFAULT);
  std::replace(message.begin(), message.end(), '\n', ' ');
  return message.empty() ? "HDF5 error" : message;
}

std::string fileName(hid_t object) {
  const ssize_t length = H5Fget_name(object, nullptr, 0);
  if (length <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return {};
  }
  std::string name(static_cast<std::size_t>(length) + 1, '\0');
  H5Fget_name(object, name.data(), name.size());
  name.resize(static_cast<std::size_t>(length));
  return name;
}

std::string objectName(hid_t parent, const std::string& name) {
  std::string path;
  const ssize_t length = H5Iget_name(parent, nullptr, 0);
  if (length > 0) {
    path.assign(static_cast<std::size_t>(length) + 1, '\0');
    H5Iget_name(parent, path.data(), path.size());
    path.resize(static_cast<std::size_t>(length));
  } else {
    H5Eclear2(H5E_DEFAULT);
  }
  if (name.empty()) return path.empty() ? "/" : path;
  return (path.empty() || path.back() != '/' ? path + "/" : path) + name;
}

Handle createFile(const std::string& path, unsigned flags, const std::string& role) {
  const hid_t id = H5Fcreate(path.c_str(), flags, H5P_DEFAULT, H5P_DEFAULT);
  if (id < 0) throw Error("cannot create " + role + ": " + errorMessage(), path);
  return Handle(id, H5Fclose);
}

Handle openFileReadOnly(const std::string& path, const std::string& role) {
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) throw Error("cannot open " + role + " as HDF5: " + errorMessage(), path);
  return Handle(id, H5Fclose);
}

Handle createMemoryFile(const std::string& name) {
  const Handle access = propertyList(H5P_FILE_ACCESS);
  // 64 KiB increments: a results file of the 200 x 12 rod grows by about 20 kB per iteration.
  if (H5Pset_fapl_core(access.get(), 64 * 1024, 0) < 0)
    throw Error("cannot set up an HDF5 file in memory: " + errorMessage(), name);
  const hid_t id = H5Fcreate(name.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, access.get());
  if (id < 0) throw Error("cannot create an HDF5 file in memory: " + errorMessage(), name);
  return Handle(id, H5Fclose);
}

std::vector<unsigned char> fileImage(hid_t file) {
  const std::string action = "cannot take the image of the HDF5 file";
  checked(H5Fflush(file, H5F_SCOPE_GLOBAL), file, action);
  const ssize_t size = H5Fget_file_image(file, nullptr, 0);
  if (size < 0) fail(file, action);
  std::vector<unsigned char> image(static_cast<std::size_t>(size));
  if (H5Fget_file_image(file, image.data(), image.size()) != size) fail(file, action);
  return image;
}

void closeFile(Handle& file) {
  const std::string path = fileName(file.get());
  if (!file.reset()) throw Error("cannot close the HDF5 file (disk full?): " + errorMessage(), path);
}

Handle createGroup(hid_t parent, const std::string& name) {
  return Handle(checked(H5Gcreate2(parent, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), parent,
                        "cannot create group", name),
                H5Gclose);
}

Handle openGroup(hid_t parent, const std::string& name) {
  if (!exists(parent, name))
    throw Error("group '" + objectName(parent, name) + "' is missing", fileName(parent));
  return Handle(checked(H5Gopen2(parent, name.c_str(), H5P_DEFAULT), parent, "cannot open group", name),
                H5Gclose);
}

bool exists(hid_t parent, const std::string& name) {
  const htri_t found = H5Lexists(parent, name.c_str(), H5P_DEFAULT);
  if (found < 0) H5Eclear2(H5E_DEFAULT);
  return found > 0;
}

Handle createDataset(hid_t parent, const std::string& name, hid_t fileType, const std::vector<hsize_t>& dims,
                     const std::vector<hsize_t>& maxDims, hid_t creation, hid_t access) {
  const std::string action = "cannot create dataset";
  Handle space(checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(),
                                        maxDims.empty() ? nullptr : maxDims.data()),
                       parent, action, name),
               H5Sclose);
  return Handle(
      checked(H5Dcreate2(parent, name.c_str(), fileType, space.get(), H5P_DEFAULT, creation, access), parent,
              action, name),
      H5Dclose);
}

Handle openDataset(hid_t parent, const std::string& name, hid_t access) {
  if (!exists(parent, name))
    throw Error("dataset '" + objectName(parent, name) + "' is missing", fileName(parent));
  return Handle(checked(H5Dopen2(parent, name.c_str(), access), parent, "cannot open dataset", name),
                H5Dclose);
}

Handle propertyList(hid_t propertyClass) {
  const hid_t id = H5Pcreate(propertyClass);
  if (id < 0) throw Error("cannot create an HDF5 property list: " + errorMessage(), {});
  return Handle(id, H5Pclose);
}

std::vector<hsize_t> shape(hid_t dataset) {
  const std::string action = "cannot read the shape of dataset";
  Handle space(checked(H5Dget_space(dataset), dataset, action), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) fail(dataset, action);
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  if (H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) < 0) fail(dataset, action);
  return dims;
}

void write(hid_t dataset, hid_t memoryType, const void* data) {
  if (elementCount(shape(dataset)) == 0) return;
  checked(H5Dwrite(dataset, memoryType, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), dataset,
          "cannot write dataset");
}

void writeDoubles(hid_t parent, const std::string& name, const std::vector<hsize_t>& dims,
                  const double* data) {
  const Handle dataset = createDataset(parent, name, H5T_IEEE_F64LE, dims);
  write(dataset.get(), H5T_NATIVE_DOUBLE, data);
}

void read(hid_t parent, const std::string& name, hid_t memoryType, const std::vector<hsize_t>& expected,
          void* out) {
  const Handle dataset = openDataset(parent, name);
  const std::vector<hsize_t> dims = shape(dataset.get());
  if (dims != expected) {
    throw Error(
        "dataset '" + objectName(parent, name) + "' has shape " + join(dims) + ", expected " + join(expected),
        fileName(parent));
  }
  if (elementCount(dims) == 0) return;
  // The stored element type must be of the memory type's class and size: a damaged type message
  // (found by tests/fuzz) made HDF5's conversion copy past the buffer instead of failing.
  const Handle fileType(H5Dget_type(dataset.get()), H5Tclose);
  if (fileType.get() < 0 || H5Tget_class(fileType.get()) != H5Tget_class(memoryType) ||
      H5Tget_size(fileType.get()) != H5Tget_size(memoryType)) {
    throw Error("dataset '" + objectName(parent, name) + "' does not store elements of the expected type",
                fileName(parent));
  }
  checked(H5Dread(dataset.get(), memoryType, H5S_ALL, H5S_ALL, H5P_DEFAULT, out), parent,
          "cannot read dataset", name);
}

void writeRows(hid_t dataset, hsize_t first, const std::vector<hsize_t>& count, const double* data) {
  const std::string action = "cannot write rows " + rowRange(first, count[0]) + " of dataset";
  std::vector<hsize_t> extent = shape(dataset);
  if (extent.size() != count.size()) fail(dataset, action);
  if (first + count[0] > extent[0]) {
    extent[0] = first + count[0];
    checked(H5Dset_extent(dataset, extent.data()), dataset, action);
  }
  const RowSelection rows = selectRows(dataset, first, count, action);
  checked(
      H5Dwrite(dataset, H5T_NATIVE_DOUBLE, rows.memorySpace.get(), rows.fileSpace.get(), H5P_DEFAULT, data),
      dataset, action);
}

void readRows(hid_t dataset, hsize_t first, const std::vector<hsize_t>& count, double* data) {
  const std::string action = "cannot read rows " + rowRange(first, count[0]) + " of dataset";
  const RowSelection rows = selectRows(dataset, first, count, action);
  checked(
      H5Dread(dataset, H5T_NATIVE_DOUBLE, rows.memorySpace.get(), rows.fileSpace.get(), H5P_DEFAULT, data),
      dataset, action);
}

bool hasAttribute(hid_t object, const std::string& name) {
  const htri_t found = H5Aexists(object, name.c_str());
  if (found < 0) H5Eclear2(H5E_DEFAULT);
  return found > 0;
}

void writeAttribute(hid_t object, const std::string& name, int value) {
  writeScalarAttribute(object, name, H5T_NATIVE_INT, H5T_STD_I32LE, &value);
}

void writeAttribute(hid_t object, const std::string& name, std::int64_t value) {
  writeScalarAttribute(object, name, H5T_NATIVE_INT64, H5T_STD_I64LE, &value);
}

void writeAttribute(hid_t object, const std::string& name, double value) {
  writeScalarAttribute(object, name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, &value);
}

void writeStringAttribute(hid_t object, const std::string& name, const std::string& value) {
  const std::string action = "cannot write attribute '" + name + "' of";
  // Fixed length, null-padded: what h5py and the plain C API read without a variable-length type.
  Handle type(checked(H5Tcopy(H5T_C_S1), object, action), H5Tclose);
  checked(H5Tset_size(type.get(), std::max<std::size_t>(1, value.size())), object, action);
  checked(H5Tset_strpad(type.get(), H5T_STR_NULLPAD), object, action);
  std::string padded = value;
  if (padded.empty()) padded.push_back('\0');
  writeScalarAttribute(object, name, type.get(), type.get(), padded.data());
}

int readIntAttribute(hid_t object, const std::string& name) {
  int value = 0;
  readScalarAttribute(object, name, H5T_NATIVE_INT, &value);
  return value;
}

double readDoubleAttribute(hid_t object, const std::string& name) {
  double value = 0.0;
  readScalarAttribute(object, name, H5T_NATIVE_DOUBLE, &value);
  return value;
}

std::string readStringAttribute(hid_t object, const std::string& name) {
  const Handle attribute = openAttribute(object, name);
  const std::string action = "cannot read attribute '" + name + "' of";
  Handle type(checked(H5Aget_type(attribute.get()), object, action), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_STRING || H5Tis_variable_str(type.get()) > 0) {
    throw Error("attribute '" + name + "' of '" + objectName(object, {}) + "' is not a fixed-length string",
                fileName(object));
  }
  requireOneElement(object, attribute.get(), name);
  std::string value(H5Tget_size(type.get()), '\0');
  checked(H5Aread(attribute.get(), type.get(), value.data()), object, action);
  const auto end = value.find('\0');
  if (end != std::string::npos) value.resize(end);
  return value;
}

}  // namespace hindsight::hdf5
