# FindTetGen: TetGen 1.5 built as a library (Debian: libtet1.5-dev, header tetgen.h, library
# libtet). Defines TetGen_FOUND, TetGen_INCLUDE_DIR and TetGen_LIBRARY. No imported target:
# spacewarp links the library by path, so its exported package needs no find_dependency().
# Code that includes tetgen.h must be compiled with -DTETLIBRARY (TetGen then reports errors
# by `throw int` instead of exit()).
find_path(TetGen_INCLUDE_DIR tetgen.h PATH_SUFFIXES tetgen)
find_library(TetGen_LIBRARY NAMES tet tetgen)

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(TetGen REQUIRED_VARS TetGen_LIBRARY TetGen_INCLUDE_DIR)
mark_as_advanced(TetGen_INCLUDE_DIR TetGen_LIBRARY)
