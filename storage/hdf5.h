// The one wrapper of the HDF5 C API, shared by the trajectory file (storage/chunked_state_file.cpp),
// the results file (problems/topopt/results_file.cpp) and the design files (problems/rod/design_io.cpp):
// identifiers closed by RAII, HDF5's own error printing silenced, and every failed call turned into
// hdf5::Error naming the object ("dataset '/history/psi1'") and HDF5's innermost reason ("Permission
// denied"). The file's path is in Error::file(); callers wrap it into their own StorageError.
//
// Include as "storage/hdf5.h"; the library's header stays <hdf5.h>.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace hindsight::hdf5 {

/// A failed HDF5 call. what(): the action, the object and HDF5's reason.
class Error : public std::runtime_error {
 public:
  Error(const std::string& what, std::string file) : std::runtime_error(what), file_(std::move(file)) {}
  /// The file of the object, or empty when unknown.
  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

/// Owns one identifier (file, group, dataset, dataspace, property list, attribute, datatype) and
/// closes it with the close function of its kind; -1 means none.
class Handle {
 public:
  using Close = herr_t (*)(hid_t);
  Handle() = default;
  Handle(hid_t id, Close close) : id_(id), close_(close) {}
  Handle(Handle&& other) noexcept : id_(other.id_), close_(other.close_) { other.id_ = -1; }
  Handle& operator=(Handle&& other) noexcept;
  ~Handle() { reset(); }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;

  hid_t get() const { return id_; }
  /// Closes now; false when closing failed (a file's last writes, e.g. onto a full disk, happen here).
  bool reset();

 private:
  hid_t id_ = -1;
  Close close_ = nullptr;
};

/// Turns off HDF5's printing of error stacks to stderr while it lives; the errors reach the caller
/// as exceptions carrying the stack's messages instead. HDF5 keeps the switch per thread in a
/// thread-safe build (Debian's is), so a thread that calls HDF5 needs its own silencer; in a build
/// without thread safety the switch is one for the process, and the silencers of all threads share
/// it by count so that the last one to end restores the printer.
class ErrorSilencer {
 public:
  ErrorSilencer();
  ~ErrorSilencer();
  ErrorSilencer(const ErrorSilencer&) = delete;
  ErrorSilencer& operator=(const ErrorSilencer&) = delete;

 private:
  H5E_auto2_t function_ = nullptr;
  void* data_ = nullptr;
};

/// The innermost messages of this thread's error stack ("Permission denied"), then clears it.
std::string errorMessage();

/// Throws Error(what + ": " + errorMessage()) when `status` < 0, else returns it.
template <typename T>
T check(T status, const std::string& what) {
  if (status < 0) throw Error(what + ": " + errorMessage(), {});
  return status;
}

/// The file and the path of `object` inside it, as HDF5 knows them; empty when unknown.
std::string fileName(hid_t object);
std::string objectName(hid_t parent, const std::string& name);

// ---- files, groups, datasets: each throws Error naming the object when HDF5 refuses ----

/// flags: H5F_ACC_TRUNC (replace) or H5F_ACC_EXCL (never replace). `role` names the file in the
/// message ("cannot create the trajectory file: Permission denied").
Handle createFile(const std::string& path, unsigned flags, const std::string& role = "the HDF5 file");
Handle openFileReadOnly(const std::string& path, const std::string& role = "the HDF5 file");
/// A new HDF5 file that lives in memory only (the core driver without backing store); `name` only
/// names it. fileImage() returns its bytes for the caller to write. Why: when HDF5 itself writes a
/// file onto a full disk, H5Fclose fails, the library keeps the file open, and its shutdown at exit
/// crashes on that file (HDF5 1.10.8: SIGSEGV in H5F__close_cb); a file in memory has no such write.
Handle createMemoryFile(const std::string& name);
/// The complete bytes of an open file, flushed first.
std::vector<unsigned char> fileImage(hid_t file);
/// Closes a file now, throwing when its last writes fail.
void closeFile(Handle& file);
Handle createGroup(hid_t parent, const std::string& name);
Handle openGroup(hid_t parent, const std::string& name);
/// Whether `parent` has a link (group or dataset) `name`.
bool exists(hid_t parent, const std::string& name);

/// A dataset of `dims`; `maxDims` (empty: fixed size) with H5S_UNLIMITED entries needs a chunked
/// `creation` property list.
Handle createDataset(hid_t parent, const std::string& name, hid_t fileType, const std::vector<hsize_t>& dims,
                     const std::vector<hsize_t>& maxDims = {}, hid_t creation = H5P_DEFAULT,
                     hid_t access = H5P_DEFAULT);
Handle openDataset(hid_t parent, const std::string& name, hid_t access = H5P_DEFAULT);
Handle propertyList(hid_t propertyClass);
/// The dimensions of a dataset.
std::vector<hsize_t> shape(hid_t dataset);

/// Writes `data` (memory type `memoryType`) as the whole dataset; nothing for an empty one.
void write(hid_t dataset, hid_t memoryType, const void* data);
/// A fixed-size float64 dataset of `dims` holding `data` (row-major).
void writeDoubles(hid_t parent, const std::string& name, const std::vector<hsize_t>& dims,
                  const double* data);
/// Reads the whole dataset `name`, which must have the shape `expected`, into `out`.
void read(hid_t parent, const std::string& name, hid_t memoryType, const std::vector<hsize_t>& expected,
          void* out);
/// Rows [first, first + count[0]) of a dataset (all columns of a rank-2 one) from or into `data`;
/// `count` has one entry per dimension.
void writeRows(hid_t dataset, hsize_t first, const std::vector<hsize_t>& count, const double* data);
void readRows(hid_t dataset, hsize_t first, const std::vector<hsize_t>& count, double* data);

// ---- attributes: scalars as int32, int64 and float64, strings as fixed-length null-padded ----

bool hasAttribute(hid_t object, const std::string& name);
void writeAttribute(hid_t object, const std::string& name, int value);
void writeAttribute(hid_t object, const std::string& name, std::int64_t value);
void writeAttribute(hid_t object, const std::string& name, double value);
void writeStringAttribute(hid_t object, const std::string& name, const std::string& value);
int readIntAttribute(hid_t object, const std::string& name);
double readDoubleAttribute(hid_t object, const std::string& name);
std::string readStringAttribute(hid_t object, const std::string& name);

}  // namespace hindsight::hdf5
