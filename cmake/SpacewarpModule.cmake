# spacewarp_add_module(<name> <sources>...): the library of one module (core, coords, ...):
# target spacewarp_<name>, exported and aliased as spacewarp::<name>, configured like every
# project target, installed with the module's public headers as <spacewarp/<name>/...>. The
# module's detail/ folder holds internals and is not installed.
function(spacewarp_add_module name)
  set(target spacewarp_${name})
  add_library(${target} ${ARGN})
  add_library(spacewarp::${name} ALIAS ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${name})
  spacewarp_configure_target(${target})
  # One precompiled header for every module: building one costs as much as the parsing it
  # saves in about five files.
  if(NOT TARGET spacewarp_pch_modules)
    spacewarp_add_precompiled_header(spacewarp_pch_modules HEADERS ${SPACEWARP_PCH_COMMON}
                                     LIBS Eigen3::Eigen glm::glm TBB::tbb)
  endif()
  spacewarp_precompile_headers(${target} REUSE_FROM spacewarp_pch_modules)
  install(TARGETS ${target} EXPORT spacewarpTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/spacewarp/${name}
          FILES_MATCHING PATTERN "*.h" PATTERN "detail" EXCLUDE)
endfunction()
