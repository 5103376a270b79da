# The video component (engine/src/video): OpenCV's video and depth-image readers and writers, which the core reaches
# through io/video_backend.hpp. Its objects are compiled once (position-independent, hidden symbols) and go
#  - into every program and test that links dvs_engine, as object files, so its static initializer registers it
#    there exactly as the core's own files once did (the dvs program reads and writes videos as before);
#  - into libdvs_video.so (dvs::video, cmake/library.cmake), which applications link for video files.
# Not built with DVS_VIDEO_IO=OFF.
if(NOT DVS_VIDEO_IO)
  return()
endif()
file(GLOB DVS_VIDEO_SOURCES CONFIGURE_DEPENDS engine/src/video/*.cpp)
add_library(dvs_video_objects OBJECT ${DVS_VIDEO_SOURCES})
target_include_directories(dvs_video_objects PRIVATE engine/src engine/include ${DVS_GENERATED_INCLUDE_DIR} ${OpenCV_INCLUDE_DIRS})
target_link_libraries(dvs_video_objects PRIVATE nlohmann_json::nlohmann_json)
set_target_properties(dvs_video_objects PROPERTIES
  POSITION_INDEPENDENT_CODE ON CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON)
target_link_libraries(dvs_engine INTERFACE $<TARGET_OBJECTS:dvs_video_objects> ${DVS_OPENCV_VIDEO_LIBS})
add_dependencies(dvs_engine dvs_video_objects)
