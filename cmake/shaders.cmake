# Compiles every compute shader under a folder to SPIR-V with glslc and embeds the words in a static
# library. A shader is looked up at run time by its path below shaders/ without the extension,
# e.g. "nn/groupnorm". No shader file is read at run time.

# Script mode (cmake -DSHADER=... -P shaders.cmake, run before each shader is compiled): fails the build when
# the shader, with its includes and defines expanded by glslc -E, names a combined texel-buffer sampler type
# (samplerBuffer, isamplerBuffer, usamplerBuffer). SPIR-V 1.6 forbids OpTypeSampledImage with Dim Buffer, so
# current driver stacks (Mesa 25, Vulkan 1.3+ validation) reject it; use textureBuffer +
# GL_EXT_samplerless_texture_functions + texelFetch(tex, i) (same uniform-texel-buffer descriptor).
if(CMAKE_SCRIPT_MODE_FILE)
  execute_process(COMMAND ${GLSLC} -E -I ${INCLUDE_DIR} ${SHADER}
                  OUTPUT_VARIABLE expanded ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "glslc -E ${SHADER} failed:\n${err}")
  endif()
  string(REGEX MATCH "(^|[^A-Za-z0-9_])[iu]?samplerBuffer([^A-Za-z0-9_]|$)" hit "${expanded}")
  if(hit)
    message(FATAL_ERROR "${SHADER}: declares or uses a combined sampler buffer (${hit}), which SPIR-V 1.6 "
      "drivers reject. Declare the input as textureBuffer/utextureBuffer/itextureBuffer, add "
      "'#extension GL_EXT_samplerless_texture_functions : require' and read it with texelFetch(tex, i).")
  endif()
  return()
endif()

set(DVS_SHADERS_CMAKE ${CMAKE_CURRENT_LIST_FILE})

function(dvs_embed_shaders target shader_root)
  file(GLOB_RECURSE sources CONFIGURE_DEPENDS ${shader_root}/*.comp)
  file(GLOB_RECURSE includes CONFIGURE_DEPENDS ${shader_root}/*.glsl)
  add_executable(dvs_spv_embed ${CMAKE_SOURCE_DIR}/cmake/spv_embed.cpp)
  set(spv_files)
  set(names)
  foreach(src ${sources})
    file(RELATIVE_PATH rel ${shader_root} ${src})
    string(REGEX REPLACE "\\.comp$" "" name ${rel})
    set(spv ${CMAKE_CURRENT_BINARY_DIR}/spv/${name}.spv)
    get_filename_component(spv_dir ${spv} DIRECTORY)
    add_custom_command(
      OUTPUT ${spv}
      COMMAND ${CMAKE_COMMAND} -E make_directory ${spv_dir}
      COMMAND ${CMAKE_COMMAND} -DGLSLC=${GLSLC} -DINCLUDE_DIR=${shader_root}/common -DSHADER=${src} -P ${DVS_SHADERS_CMAKE}
      COMMAND ${GLSLC} --target-env=vulkan1.2 -O -I ${shader_root}/common -o ${spv} ${src}
      DEPENDS ${src} ${includes} ${DVS_SHADERS_CMAKE}
      COMMENT "glslc ${rel}"
      VERBATIM)
    list(APPEND spv_files ${spv})
    list(APPEND names ${name})
  endforeach()
  set(out ${CMAKE_CURRENT_BINARY_DIR}/embedded_shaders.cpp)
  set(list_file ${CMAKE_CURRENT_BINARY_DIR}/embedded_shaders.list)
  set(lines "")
  list(LENGTH names count)
  if(count GREATER 0)
    math(EXPR last "${count} - 1")
    foreach(i RANGE ${last})
      list(GET names ${i} n)
      list(GET spv_files ${i} f)
      string(APPEND lines "${n} ${f}\n")
    endforeach()
  endif()
  file(GENERATE OUTPUT ${list_file} CONTENT "${lines}")
  add_custom_command(
    OUTPUT ${out}
    COMMAND dvs_spv_embed ${list_file} ${out}
    DEPENDS dvs_spv_embed ${spv_files} ${list_file}
    COMMENT "Embedding ${count} SPIR-V shaders"
    VERBATIM)
  add_library(${target} STATIC ${out})
endfunction()
