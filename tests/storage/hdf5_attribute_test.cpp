// The HDF5 wrapper's attribute readers on attributes that are not single values: a damaged or
// foreign file may store "nx" as an array, and H5Aread would write all of it into one int.
#include <hindsight/storage/hdf5.h>

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace hindsight {
namespace {

// Creates attribute `name` on `object` with `count` elements of `type`, filled from `data`.
void writeArrayAttribute(hid_t object, const char* name, hid_t type, hsize_t count, const void* data) {
  const hid_t space = H5Screate_simple(1, &count, nullptr);
  const hid_t attribute = H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(attribute, 0);
  ASSERT_GE(H5Awrite(attribute, type, data), 0);
  H5Aclose(attribute);
  H5Sclose(space);
}

TEST(Hdf5Attributes, ArraysAreRefusedWhereOneValueIsRead) {
  const hdf5::ErrorSilencer quiet;
  const std::string path = ::testing::TempDir() + "/hindsight_array_attributes.h5";
  hdf5::Handle file = hdf5::createFile(path, H5F_ACC_TRUNC);
  const int ints[64] = {7};
  const double doubles[64] = {1.5};
  writeArrayAttribute(file.get(), "ints", H5T_NATIVE_INT, 64, ints);
  writeArrayAttribute(file.get(), "doubles", H5T_NATIVE_DOUBLE, 64, doubles);
  writeArrayAttribute(file.get(), "empty", H5T_NATIVE_INT, 0, ints);
  const hid_t text = H5Tcopy(H5T_C_S1);
  H5Tset_size(text, 4);
  writeArrayAttribute(file.get(), "strings", text, 16, std::string(64, 'a').data());
  H5Tclose(text);
  hdf5::writeAttribute(file.get(), "one", 3);

  EXPECT_THROW(hdf5::readIntAttribute(file.get(), "ints"), hdf5::Error);
  EXPECT_THROW(hdf5::readDoubleAttribute(file.get(), "doubles"), hdf5::Error);
  EXPECT_THROW(hdf5::readIntAttribute(file.get(), "empty"), hdf5::Error);
  EXPECT_THROW(hdf5::readStringAttribute(file.get(), "strings"), hdf5::Error);
  try {
    hdf5::readIntAttribute(file.get(), "ints");
  } catch (const hdf5::Error& e) {
    EXPECT_NE(std::string(e.what()).find("'ints'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not a single value"), std::string::npos) << e.what();
  }
  EXPECT_EQ(hdf5::readIntAttribute(file.get(), "one"), 3);  // scalars still read
  file.reset();
  std::remove(path.c_str());
}

}  // namespace
}  // namespace hindsight
