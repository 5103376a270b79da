# Compiles every compute shader under a folder to SPIR-V with glslc and embeds the words in a static
# library. A shader is looked up at run time by its path below shaders/ without the extension,
# e.g. "nn/groupnorm", or by the name its row gives in the variants table (shaders/variants.cmake: one more
# shader from a .comp and preprocessor defines, e.g. "nn/eltwise_binary_tex4"). No shader file is read at
# run time.

# Script mode (cmake -DSHADER=... -P shaders.cmake, run before each shader is compiled): fails the build when
# the shader, with its includes and defines expanded by glslc -E, names a combined texel-buffer sampler type
# (samplerBuffer, isamplerBuffer, usamplerBuffer). SPIR-V 1.6 forbids OpTypeSampledImage with Dim Buffer, so
# current driver stacks (Mesa 25, Vulkan 1.3+ validation) reject it; use textureBuffer +
# GL_EXT_samplerless_texture_functions + texelFetch(tex, i) (same uniform-texel-buffer descriptor).
# DEFINES: the variant's defines (space-separated names), expanded as the compiler sees them.
if(CMAKE_SCRIPT_MODE_FILE)
  separate_arguments(define_flags UNIX_COMMAND "${DEFINES}")
  list(TRANSFORM define_flags PREPEND -D)
  if(PREPROCESSOR)  # the cooperative-matrix compiler (glslangValidator -E) for the shaders it compiles
    set(preprocess ${PREPROCESSOR} -E -I${INCLUDE_DIR} ${define_flags} ${SHADER})
  else()
    set(preprocess ${GLSLC} -E -I ${INCLUDE_DIR} ${define_flags} ${SHADER})
  endif()
  execute_process(COMMAND ${preprocess}
                  OUTPUT_VARIABLE expanded ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "glslc -E ${define_flags} ${SHADER} failed:\n${err}")
  endif()
  string(REGEX MATCH "(^|[^A-Za-z0-9_])[iu]?samplerBuffer([^A-Za-z0-9_]|$)" hit "${expanded}")
  if(hit)
    message(FATAL_ERROR "${SHADER} ${define_flags}: declares or uses a combined sampler buffer (${hit}), which "
      "SPIR-V 1.6 drivers reject. Declare the input as textureBuffer/utextureBuffer/itextureBuffer, add "
      "'#extension GL_EXT_samplerless_texture_functions : require' and read it with texelFetch(tex, i).")
  endif()
  return()
endif()

set(DVS_SHADERS_CMAKE ${CMAKE_CURRENT_LIST_FILE})

# Shaders that enable GL_KHR_cooperative_matrix or GL_NV_cooperative_matrix2 (tensor cores) need a newer
# glslang than Debian 12's: .ci/deps unpacks Debian 13's into /opt/dvs-glslang15 (DVS_GLSLANG_DIR), whose
# spirv-val then checks each such module for Vulkan 1.3. Every other shader keeps the system's glslc.
set(DVS_GLSLANG_DIR "$ENV{DVS_GLSLANG_DIR}")
if(NOT DVS_GLSLANG_DIR)
  set(DVS_GLSLANG_DIR /opt/dvs-glslang15)
endif()
# A build tree configured before against another folder (CI unpacks the tools afresh into a temporary one on
# each run) looks again instead of keeping a cached path that may be gone.
if(NOT "${DVS_GLSLANG_DIR}" STREQUAL "${DVS_GLSLANG_DIR_FOUND_IN}")
  unset(DVS_COOPMAT_GLSLANG CACHE)
  unset(DVS_COOPMAT_SPIRV_VAL CACHE)
  set(DVS_GLSLANG_DIR_FOUND_IN "${DVS_GLSLANG_DIR}" CACHE INTERNAL "the DVS_GLSLANG_DIR the tools were found in")
endif()
find_program(DVS_COOPMAT_GLSLANG glslangValidator PATHS ${DVS_GLSLANG_DIR}/bin NO_DEFAULT_PATH)
find_program(DVS_COOPMAT_SPIRV_VAL spirv-val PATHS ${DVS_GLSLANG_DIR}/bin NO_DEFAULT_PATH)

include(${CMAKE_CURRENT_LIST_DIR}/shader_variants.cmake)

# One shader: ${src} compiled with -D<NAME> for each name in row_defines (space-separated; empty for a .comp as
# itself) to spv/<name>.spv; the .spv path is appended to the caller's spv_files.
function(dvs_compile_shader shader_root name src row_defines includes)
  separate_arguments(define_flags UNIX_COMMAND "${row_defines}")
  list(TRANSFORM define_flags PREPEND -D)
  set(spv ${CMAKE_CURRENT_BINARY_DIR}/spv/${name}.spv)
  get_filename_component(spv_dir ${spv} DIRECTORY)
  # Cooperative-matrix shaders enable GL_KHR_cooperative_matrix or GL_NV_cooperative_matrix2; a source that
  # mentions one is preprocessed with the shader's defines to see whether this shader does (nn/conv_coopmat
  # does, its variant nn/conv_coopmat_twin does not).
  file(STRINGS ${src} coopmat REGEX "^#extension +GL_(KHR_cooperative_matrix|NV_cooperative_matrix2)")
  if(coopmat)
    execute_process(COMMAND ${GLSLC} -E -I ${shader_root}/common ${define_flags} ${src}
                    OUTPUT_VARIABLE expanded ERROR_VARIABLE err RESULT_VARIABLE rc)
    if(NOT rc EQUAL 0)
      message(FATAL_ERROR "glslc -E ${define_flags} ${src} failed:\n${err}")
    endif()
    string(REGEX MATCH "#extension +GL_(KHR_cooperative_matrix|NV_cooperative_matrix2)" coopmat "${expanded}")
  endif()
  if(coopmat)
    if(NOT DVS_COOPMAT_GLSLANG OR NOT DVS_COOPMAT_SPIRV_VAL)
      message(FATAL_ERROR "${name} uses cooperative matrices, which Debian 12's glslc cannot compile: run "
        "bash .ci/deps (it unpacks Debian 13's glslang into ${DVS_GLSLANG_DIR}; DVS_GLSLANG_DIR moves it)")
    endif()
    set(check -DPREPROCESSOR=${DVS_COOPMAT_GLSLANG})
    set(compile ${DVS_COOPMAT_GLSLANG} -V --quiet --target-env vulkan1.3 -I${shader_root}/common ${define_flags}
        -o ${spv} ${src}
        COMMAND ${DVS_COOPMAT_SPIRV_VAL} --target-env vulkan1.3 ${spv})
    set(tool "glslangValidator (cooperative matrix)")
  else()
    set(check -DGLSLC=${GLSLC})
    set(compile ${GLSLC} --target-env=vulkan1.2 -O -I ${shader_root}/common ${define_flags} -o ${spv} ${src})
    set(tool glslc)
  endif()
  file(RELATIVE_PATH rel ${shader_root} ${src})
  if(define_flags)
    list(JOIN define_flags " " shown)
    set(rel "${rel} ${shown}")
  endif()
  add_custom_command(
    OUTPUT ${spv}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${spv_dir}
    COMMAND ${CMAKE_COMMAND} ${check} -DINCLUDE_DIR=${shader_root}/common -DSHADER=${src}
            "-DDEFINES=${row_defines}" -P ${DVS_SHADERS_CMAKE}
    COMMAND ${compile}
    DEPENDS ${src} ${includes} ${DVS_SHADERS_CMAKE}
    COMMENT "${tool} ${name} (${rel})"
    VERBATIM)
  set(spv_files ${spv_files} ${spv} PARENT_SCOPE)
endfunction()

function(dvs_embed_shaders target shader_root)
  file(GLOB_RECURSE sources CONFIGURE_DEPENDS ${shader_root}/*.comp)
  file(GLOB_RECURSE includes CONFIGURE_DEPENDS ${shader_root}/*.glsl)
  add_executable(dvs_spv_embed ${CMAKE_SOURCE_DIR}/cmake/spv_embed.cpp)
  set(spv_files)
  set(names)
  foreach(src ${sources})  # every .comp as itself
    file(RELATIVE_PATH rel ${shader_root} ${src})
    string(REGEX REPLACE "\\.comp$" "" name ${rel})
    dvs_compile_shader(${shader_root} ${name} ${src} "" "${includes}")
    list(APPEND names ${name})
  endforeach()
  dvs_read_shader_variants(${shader_root} variant_names variant_sources variant_defines)
  list(LENGTH variant_names variant_count)
  if(variant_count GREATER 0)
    math(EXPR last "${variant_count} - 1")
    foreach(i RANGE ${last})  # then the variants table's rows
      list(GET variant_names ${i} name)
      list(GET variant_sources ${i} src)
      list(GET variant_defines ${i} row_defines)
      if(name IN_LIST names)
        message(FATAL_ERROR "${shader_root}/variants.cmake: the variant ${name} has the name of another shader "
          "(${name}.comp or an earlier row); give it a name of its own")
      endif()
      dvs_compile_shader(${shader_root} ${name} ${src} "${row_defines}" "${includes}")
      list(APPEND names ${name})
    endforeach()
  endif()
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
