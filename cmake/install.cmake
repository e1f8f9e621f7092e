# Install rules: `cmake --install build [--prefix P]` (or `make install`)
# puts the commands in bin/, libgi.so and libgi.a in lib/, the public
# headers in include/gi/, gi.pc in lib/pkgconfig/ and the CMake package
# (find_package(gi) -> gi::gi) in lib/cmake/gi/.
include(CMakePackageConfigHelpers)
set(GI_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/gi)

install(TARGETS gi-server gi-bake gi-client gi-accuracy RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS gi EXPORT giTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS gicore EXPORT giStaticTargets ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(DIRECTORY core/include/gi DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.h")

install(EXPORT giTargets NAMESPACE gi:: DESTINATION ${GI_CMAKE_DIR})
install(EXPORT giStaticTargets NAMESPACE gi:: DESTINATION ${GI_CMAKE_DIR})
# The directory FindOpenVDB.cmake came from, for gi::gi_static's consumers.
find_path(GI_OPENVDB_MODULE_DIR FindOpenVDB.cmake PATHS ${CMAKE_MODULE_PATH} NO_DEFAULT_PATH)
configure_package_config_file(cmake/giConfig.cmake.in ${CMAKE_BINARY_DIR}/giConfig.cmake
                              INSTALL_DESTINATION ${GI_CMAKE_DIR})
# The SONAME changes with the minor version before 1.0 (core/CMakeLists.txt).
if(PROJECT_VERSION_MAJOR EQUAL 0)
  set(GI_COMPAT SameMinorVersion)
else()
  set(GI_COMPAT SameMajorVersion)
endif()
write_basic_package_version_file(${CMAKE_BINARY_DIR}/giConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY ${GI_COMPAT})
install(FILES ${CMAKE_BINARY_DIR}/giConfig.cmake ${CMAKE_BINARY_DIR}/giConfigVersion.cmake
        DESTINATION ${GI_CMAKE_DIR})

# gi.pc finds the prefix relative to itself, so --prefix at install time works.
file(RELATIVE_PATH GI_PC_PREFIX_FROM_PCDIR ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig ${CMAKE_INSTALL_PREFIX})
string(REGEX REPLACE "/$" "" GI_PC_PREFIX_FROM_PCDIR "${GI_PC_PREFIX_FROM_PCDIR}")
configure_file(cmake/gi.pc.in ${CMAKE_BINARY_DIR}/gi.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/gi.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
