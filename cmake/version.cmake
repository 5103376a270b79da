# dvs/version.h (DVS_VERSION_MAJOR/MINOR/PATCH, C and C++) from the project's version: generated into the build
# tree, on the include path of every dvs target (through dvs_io) and of dvs::core, installed beside the public
# headers (cmake/install.cmake).
set(DVS_GENERATED_INCLUDE_DIR ${CMAKE_BINARY_DIR}/generated/include)
configure_file(${CMAKE_CURRENT_LIST_DIR}/version.h.in ${DVS_GENERATED_INCLUDE_DIR}/dvs/version.h @ONLY)
