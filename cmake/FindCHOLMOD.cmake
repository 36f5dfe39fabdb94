# FindCHOLMOD: SuiteSparse's CHOLMOD (Debian: libsuitesparse-dev, which ships no CMake config
# for it). Defines CHOLMOD_FOUND, CHOLMOD_INCLUDE_DIR (the folder of cholmod.h, usually
# include/suitesparse, since Eigen's CholmodSupport includes <cholmod.h>), CHOLMOD_LIBRARY,
# CHOLMOD_VERSION, and the imported target CHOLMOD::CHOLMOD.
#
# spacewarp's core links CHOLMOD::CHOLMOD privately; its static libraries still name the target
# in the exported package, so spacewarpConfig.cmake finds it again through this file, which is
# installed next to it.
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(CHOLMOD_LIBRARY cholmod)

# The version: cholmod_core.h up to SuiteSparse 6, cholmod.h from SuiteSparse 7.
set(CHOLMOD_VERSION "")
foreach(_sw_header cholmod.h cholmod_core.h)
  if(CHOLMOD_INCLUDE_DIR AND NOT CHOLMOD_VERSION AND EXISTS "${CHOLMOD_INCLUDE_DIR}/${_sw_header}")
    file(STRINGS "${CHOLMOD_INCLUDE_DIR}/${_sw_header}" _sw_lines
         REGEX "^#define CHOLMOD_(MAIN|SUB|SUBSUB)_VERSION +[0-9]+")
    set(_sw_parts "")
    foreach(_sw_part MAIN SUB SUBSUB)
      foreach(_sw_line IN LISTS _sw_lines)
        if(_sw_line MATCHES "^#define CHOLMOD_${_sw_part}_VERSION +([0-9]+)")
          list(APPEND _sw_parts ${CMAKE_MATCH_1})
        endif()
      endforeach()
    endforeach()
    list(LENGTH _sw_parts _sw_count)
    if(_sw_count EQUAL 3)
      list(JOIN _sw_parts "." CHOLMOD_VERSION)
    endif()
  endif()
endforeach()
unset(_sw_header)
unset(_sw_lines)
unset(_sw_parts)
unset(_sw_part)
unset(_sw_line)
unset(_sw_count)

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(CHOLMOD REQUIRED_VARS CHOLMOD_LIBRARY CHOLMOD_INCLUDE_DIR
                                  VERSION_VAR CHOLMOD_VERSION)
mark_as_advanced(CHOLMOD_INCLUDE_DIR CHOLMOD_LIBRARY)

if(CHOLMOD_FOUND AND NOT TARGET CHOLMOD::CHOLMOD)
  add_library(CHOLMOD::CHOLMOD UNKNOWN IMPORTED)
  set_target_properties(CHOLMOD::CHOLMOD PROPERTIES
    IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}")
endif()
