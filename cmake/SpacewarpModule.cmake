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
  install(TARGETS ${target} EXPORT spacewarpTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/spacewarp/${name}
          FILES_MATCHING PATTERN "*.h" PATTERN "detail" EXCLUDE)
endfunction()
