# The shader variants table (shaders/variants.cmake) read into lists; included by cmake/shaders.cmake (the
# build) and cmake/check_shader_variants.cmake (the ctest check), so both read it by the same rules.

# The rows of the variants table (shaders/variants.cmake) as three lists: run-time names, source paths (absolute)
# and defines (each row's names joined by spaces). Fails, naming the row, on a row that is malformed or whose
# source is missing.
function(dvs_read_shader_variants shader_root out_names out_sources out_defines)
  include(${shader_root}/variants.cmake)
  set(names)
  set(sources)
  set(defines)
  foreach(row IN LISTS DVS_SHADER_VARIANTS)
    string(REGEX MATCHALL "[^ \t]+" fields "${row}")
    list(LENGTH fields n)
    if(n LESS 3)
      message(FATAL_ERROR "${shader_root}/variants.cmake:\n  row \"${row}\" needs a run-time name, a source "
        ".comp and at least one define (a shader without defines is its .comp itself)")
    endif()
    list(POP_FRONT fields name source)
    if(NOT source MATCHES "\\.comp$" OR NOT EXISTS ${shader_root}/${source})
      message(FATAL_ERROR "${shader_root}/variants.cmake:\n  row ${name}: its source ${source} is not a .comp "
        "file below ${shader_root}; name an existing shader source")
    endif()
    list(JOIN fields " " row_defines)
    list(APPEND names ${name})
    list(APPEND sources ${shader_root}/${source})
    list(APPEND defines "${row_defines}")
  endforeach()
  set(${out_names} "${names}" PARENT_SCOPE)
  set(${out_sources} "${sources}" PARENT_SCOPE)
  set(${out_defines} "${defines}" PARENT_SCOPE)
endfunction()
