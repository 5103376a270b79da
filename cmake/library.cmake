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
  $<BUILD_INTERFACE:${CMAKE_SOURCE_DIR}/engine/include> $<BUILD_INTERFACE:${DVS_GENERATED_INCLUDE_DIR}>
  $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
target_compile_features(dvs_core INTERFACE cxx_std_17)
target_link_libraries(dvs_core PUBLIC Vulkan::Vulkan
  PRIVATE nlohmann_json::nlohmann_json PkgConfig::LIBZIP PkgConfig::SENTENCEPIECE TinyGLTF::TinyGLTF ${DVS_OPENCV_CORE_LIBS})
# The version script keeps std:: template instantiations (which hidden visibility cannot reach: libstdc++ marks
# its namespace visible) out of the export table; --no-undefined names a missing dependency at link time, not in
# the application.
# (Not under the sanitizers: their runtime is linked into programs only, so a library leaves its symbols undefined.)
set(DVS_LIBRARY_NO_UNDEFINED "LINKER:--no-undefined")
if(DVS_SANITIZE OR DVS_FUZZ)
  set(DVS_LIBRARY_NO_UNDEFINED "")
endif()
target_link_options(dvs_core PRIVATE "LINKER:--version-script=${CMAKE_CURRENT_LIST_DIR}/dvs_exports.map"
  ${DVS_LIBRARY_NO_UNDEFINED})

# libdvs_video.so (target dvs_video, imported as dvs::video): the video component's objects. It calls the core's
# exported dvs::detail::set_video_backend in libdvs.so (linked first, so that name binds there) and takes its own
# copies of the few io helpers it uses from dvs_io, which are hidden in libdvs.so: video_probe, disk_space,
# host_tensor, quiet_stderr (its copy of the log choice is set through VideoBackend::set_logs) and injected_faults
# (the test-only DVS_FAULTS write count is then kept per library). It exports dvs::enable_video_files() alone.
if(TARGET dvs_video_objects)
  add_library(dvs_video SHARED $<TARGET_OBJECTS:dvs_video_objects>)
  add_library(dvs::video ALIAS dvs_video)
  # RUNPATH $ORIGIN: installed, it finds libdvs.so.0 beside itself, also for a program that needs it alone (a linker
  # with --as-needed drops libdvs from a program that calls only read_video_frames) or Python's ctypes loading it.
  set_target_properties(dvs_video PROPERTIES
    OUTPUT_NAME dvs_video EXPORT_NAME video VERSION ${PROJECT_VERSION} SOVERSION 0
    LINK_DEPENDS ${CMAKE_CURRENT_LIST_DIR}/dvs_video_exports.map INSTALL_RPATH "$ORIGIN")
  target_link_libraries(dvs_video PUBLIC dvs_core PRIVATE dvs_io ${DVS_OPENCV_VIDEO_LIBS})
  target_link_options(dvs_video PRIVATE "LINKER:--version-script=${CMAKE_CURRENT_LIST_DIR}/dvs_video_exports.map"
    ${DVS_LIBRARY_NO_UNDEFINED})
endif()
