# Compiles every compute shader under a folder to SPIR-V with glslc and embeds the words in a static
# library. A shader is looked up at run time by its path below shaders/ without the extension,
# e.g. "nn/groupnorm". No shader file is read at run time.
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
      COMMAND ${GLSLC} --target-env=vulkan1.2 -O -I ${shader_root}/common -o ${spv} ${src}
      DEPENDS ${src} ${includes}
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
