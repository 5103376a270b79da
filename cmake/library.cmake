# The shared library libdvs.so (target dvs_core, imported as dvs::core): the public API of engine/include/dvs over
# the objects of dvs_io, dvs_spec, dvs_engine and dvs_shaders. Those objects are compiled once, position-independent
# and with hidden symbols, and serve both the static libraries (the dvs program and the tests) and this library.
include(GNUInstallDirs)

set(DVS_LIBRARY_OBJECT_TARGETS dvs_io dvs_spec dvs_engine dvs_shaders)
set_target_properties(${DVS_LIBRARY_OBJECT_TARGETS} PROPERTIES
  POSITION_INDEPENDENT_CODE ON CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON)

set(DVS_LIBRARY_OBJECTS "")
foreach(t ${DVS_LIBRARY_OBJECT_TARGETS})
  list(APPEND DVS_LIBRARY_OBJECTS $<TARGET_OBJECTS:${t}>)
endforeach()
add_library(dvs_core SHARED ${DVS_LIBRARY_OBJECTS})
add_library(dvs::core ALIAS dvs_core)
set_target_properties(dvs_core PROPERTIES
  OUTPUT_NAME dvs EXPORT_NAME core VERSION ${PROJECT_VERSION} SOVERSION 0
  LINK_DEPENDS ${CMAKE_CURRENT_LIST_DIR}/dvs_exports.map)
target_include_directories(dvs_core INTERFACE
  $<BUILD_INTERFACE:${CMAKE_SOURCE_DIR}/engine/include> $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
target_compile_features(dvs_core INTERFACE cxx_std_17)
target_link_libraries(dvs_core PUBLIC Vulkan::Vulkan
  PRIVATE nlohmann_json::nlohmann_json PkgConfig::LIBZIP PkgConfig::SENTENCEPIECE TinyGLTF::TinyGLTF ${OpenCV_LIBS})
# The version script keeps std:: template instantiations (which hidden visibility cannot reach: libstdc++ marks
# its namespace visible) out of the export table; --no-undefined names a missing dependency at link time, not in
# the application.
target_link_options(dvs_core PRIVATE "LINKER:--version-script=${CMAKE_CURRENT_LIST_DIR}/dvs_exports.map"
  "LINKER:--no-undefined")
