# `cmake --install build --prefix P`: the public headers, libdvs (dvs::core), libdvs_video (dvs::video) when built,
# the programs, the CMake package (find_package(dvs CONFIG) with COMPONENTS core video) and the pkg-config files
# (dvs, dvs-video). Every path is relative to the prefix, so the package can be installed anywhere.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(DVS_CMAKE_PACKAGE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/dvs)

install(DIRECTORY engine/include/dvs DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.hpp" PATTERN "*.h")
install(FILES ${DVS_GENERATED_INCLUDE_DIR}/dvs/version.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/dvs)

install(TARGETS dvs_core EXPORT dvsTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT dvsTargets NAMESPACE dvs:: DESTINATION ${DVS_CMAKE_PACKAGE_DIR})
if(TARGET dvs_video)
  install(TARGETS dvs_video EXPORT dvsVideoTargets LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(EXPORT dvsVideoTargets NAMESPACE dvs:: DESTINATION ${DVS_CMAKE_PACKAGE_DIR})
endif()

# The programs link the static libraries (as in the build tree), so they need no RPATH to find libdvs.
install(TARGETS dvs RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
if(TARGET dvs-weights)
  install(TARGETS dvs-weights RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()

configure_package_config_file(cmake/dvsConfig.cmake.in ${CMAKE_CURRENT_BINARY_DIR}/dvsConfig.cmake
  INSTALL_DESTINATION ${DVS_CMAKE_PACKAGE_DIR})
# find_package(dvs 0.1) accepts any 0.x at or above 0.1.
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/dvsConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/dvsConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/dvsConfigVersion.cmake
  DESTINATION ${DVS_CMAKE_PACKAGE_DIR})

# pkg-config: the prefix is found from the .pc file's own place (${pcfiledir}), so an install with --prefix works.
file(RELATIVE_PATH DVS_PC_TO_PREFIX ${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_LIBDIR}/pkgconfig ${CMAKE_INSTALL_PREFIX})
string(REGEX REPLACE "/$" "" DVS_PC_TO_PREFIX "${DVS_PC_TO_PREFIX}")
set(DVS_PC_NAMES dvs)
if(TARGET dvs_video)
  list(APPEND DVS_PC_NAMES dvs-video)
endif()
foreach(pc ${DVS_PC_NAMES})
  configure_file(cmake/${pc}.pc.in ${CMAKE_CURRENT_BINARY_DIR}/${pc}.pc @ONLY)
  install(FILES ${CMAKE_CURRENT_BINARY_DIR}/${pc}.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
endforeach()
