# Install rules and the exported package: find_package(spacewarp CONFIG) gives
# spacewarp::spacewarp and one spacewarp::<module> target per module.
include(CMakePackageConfigHelpers)

install(EXPORT spacewarpTargets
        NAMESPACE spacewarp::
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/spacewarp)

configure_package_config_file(
  ${PROJECT_SOURCE_DIR}/cmake/spacewarpConfig.cmake.in
  ${PROJECT_BINARY_DIR}/spacewarpConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/spacewarp)
write_basic_package_version_file(
  ${PROJECT_BINARY_DIR}/spacewarpConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
# FindCHOLMOD.cmake goes along: the exported static libraries link CHOLMOD::CHOLMOD, which
# spacewarpConfig.cmake defines through it.
install(FILES ${PROJECT_BINARY_DIR}/spacewarpConfig.cmake
              ${PROJECT_BINARY_DIR}/spacewarpConfigVersion.cmake
              ${PROJECT_SOURCE_DIR}/cmake/FindCHOLMOD.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/spacewarp)
