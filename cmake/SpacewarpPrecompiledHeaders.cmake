# Precompiled headers: the heavy third-party and standard headers that most translation units of
# a target include (Eigen, oneTBB, GoogleTest, OpenVDB, pybind11, nlohmann/json, CLI11) are
# parsed once per target instead of once per file, which is most of the CPU time of a test file
# at -O1. Only third-party and standard headers: the project's own headers stay included where
# they are used, so a file that misses an include still fails in a build without them.
#
# On by default with GCC, except behind ccache, which caches no file compiled with a precompiled
# header unless its own settings allow it (sloppiness = pch_defines,time_macros): a cached build
# gains more from the cache. Targets share one header where their options match but their macro
# definitions differ, which GCC accepts for macros the header does not use and clang does not:
# off with clang (the fuzz build). -DSPACEWARP_PRECOMPILE_HEADERS=ON|OFF overrides the default.
set(_sw_pch_default ON)
if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "GNU" OR CMAKE_CXX_COMPILER_LAUNCHER MATCHES "ccache")
  set(_sw_pch_default OFF)
endif()
option(SPACEWARP_PRECOMPILE_HEADERS "Precompile the heavy third-party headers per target"
       ${_sw_pch_default})

# What every library module and test includes, directly or through core's public headers.
set(SPACEWARP_PCH_COMMON <algorithm> <cmath> <cstdint> <filesystem> <functional> <limits> <memory>
    <random> <sstream> <string> <string_view> <utility> <vector> <Eigen/Core> <glm/glm.hpp>
    <tbb/blocked_range.h> <tbb/parallel_for.h>)
set(SPACEWARP_PCH_TESTS ${SPACEWARP_PCH_COMMON} <gtest/gtest.h> <gmock/gmock.h>)

# spacewarp_precompile_headers(<target> HEADERS <header>... | REUSE_FROM <owner>): precompiles
# the headers for <target>, or uses <owner>'s precompiled header. No-op when
# SPACEWARP_PRECOMPILE_HEADERS is OFF. GCC uses a precompiled header only with the options it was
# built with and with every macro it was built with defined (macros the header does not use may
# be added), otherwise it parses the headers again; -Winvalid-pch says so, an error in CI.
function(spacewarp_precompile_headers target)
  cmake_parse_arguments(ARG "" "REUSE_FROM" "HEADERS" ${ARGN})
  if(NOT SPACEWARP_PRECOMPILE_HEADERS)
    return()
  endif()
  if(ARG_REUSE_FROM)
    target_precompile_headers(${target} REUSE_FROM ${ARG_REUSE_FROM})
  else()
    target_precompile_headers(${target} PRIVATE ${ARG_HEADERS})
  endif()
  target_compile_options(${target} PRIVATE -Winvalid-pch)
endfunction()

# spacewarp_add_precompiled_header(<owner> [EXECUTABLE] HEADERS <header>... [LIBS <lib>...]
# [OPTIONS <option>...]): a target that only builds a precompiled header for others to reuse
# (REUSE_FROM <owner>), with the options of a project target and of LIBS but none of the macro
# definitions that tell the users apart. EXECUTABLE for users that are executables (-fPIE, not
# the -fPIC of libraries in builds with the Python package).
function(spacewarp_add_precompiled_header owner)
  cmake_parse_arguments(ARG "EXECUTABLE" "" "HEADERS;LIBS;OPTIONS" ${ARGN})
  if(NOT SPACEWARP_PRECOMPILE_HEADERS)
    return()
  endif()
  set(src ${CMAKE_CURRENT_BINARY_DIR}/${owner}.cpp)
  if(ARG_EXECUTABLE)
    file(CONFIGURE OUTPUT ${src} CONTENT "int main() { return 0; }\n")
    add_executable(${owner} ${src})
  else()
    file(CONFIGURE OUTPUT ${src} CONTENT "namespace spacewarp {}\n")
    add_library(${owner} OBJECT ${src})
  endif()
  spacewarp_configure_target(${owner})
  target_link_libraries(${owner} PRIVATE ${ARG_LIBS})
  target_compile_options(${owner} PRIVATE ${ARG_OPTIONS})
  spacewarp_precompile_headers(${owner} HEADERS ${ARG_HEADERS})
endfunction()
