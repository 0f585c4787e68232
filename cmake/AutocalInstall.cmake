include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

install(TARGETS autocal EXPORT autocalTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY include/autocal DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT autocalTargets NAMESPACE autocal::
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/autocal)

configure_package_config_file(cmake/autocalConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/autocalConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/autocal)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/autocalConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/autocalConfig.cmake
              ${CMAKE_CURRENT_BINARY_DIR}/autocalConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/autocal)
