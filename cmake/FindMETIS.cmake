# FindMETIS: METIS 5 (Debian 12 libmetis-dev), which ships neither a pkg-config nor a CMake package file.
# Defines METIS::METIS, METIS_FOUND, METIS_INCLUDE_DIR and METIS_LIBRARY. Installed with hindsight's
# package files, so that find_package(hindsight COMPONENTS rod) finds it the same way.
find_path(METIS_INCLUDE_DIR metis.h)
# The library named metis: Debian also ships SCOTCH's METIS compatibility layers (libscotchmetisv5),
# whose orderings differ, under other names.
find_library(METIS_LIBRARY NAMES metis)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(METIS REQUIRED_VARS METIS_LIBRARY METIS_INCLUDE_DIR)
if(METIS_FOUND AND NOT TARGET METIS::METIS)
  add_library(METIS::METIS UNKNOWN IMPORTED)
  set_target_properties(METIS::METIS PROPERTIES IMPORTED_LOCATION "${METIS_LIBRARY}"
                        INTERFACE_INCLUDE_DIRECTORIES "${METIS_INCLUDE_DIR}")
endif()
mark_as_advanced(METIS_INCLUDE_DIR METIS_LIBRARY)
