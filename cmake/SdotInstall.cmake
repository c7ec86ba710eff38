# Install and export: consumers use find_package(sdot) and link sdot::sdot.
include(CMakePackageConfigHelpers)
install(TARGETS sdot EXPORT sdotTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT sdotTargets NAMESPACE sdot:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/sdot)
# A static libsdot carries its private dependencies (Qhull, libpng, CGAL) into consumers' link lines.
get_target_property(_sdot_type sdot TYPE)
if(_sdot_type STREQUAL "STATIC_LIBRARY")
  set(SDOT_STATIC_LIBRARY ON)
else()
  set(SDOT_STATIC_LIBRARY OFF)
endif()
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/sdotConfig.cmake.in
  ${PROJECT_BINARY_DIR}/sdotConfig.cmake INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/sdot)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/sdotConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/sdotConfig.cmake ${PROJECT_BINARY_DIR}/sdotConfigVersion.cmake
  ${PROJECT_SOURCE_DIR}/cmake/FindCHOLMOD.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/sdot)
if(SDOT_BUILD_CLI)
  install(TARGETS sdot_command RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
