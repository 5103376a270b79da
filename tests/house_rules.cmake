# The house rules a reviewer would otherwise check by hand, run by ctest (test HouseRules) as
#   cmake -DDVS_SOURCE_DIR=<repository> -P tests/house_rules.cmake
# (a) no source file over 700 lines; (b) docs/layout.md names every folder of engine/src, engine/src/models and
# shaders, and every folder it names exists; (c) no source file cites a document that is not in the repository
# (the design notes and the notes on the authors' code that lived outside it: cite docs/ or the paper instead);
# (d) the README's test command is, byte for byte, the command .ci/run runs.
# Every problem is listed with what to do; the script fails when there is any.
cmake_minimum_required(VERSION 3.20)
if(NOT DVS_SOURCE_DIR)
  get_filename_component(DVS_SOURCE_DIR "${CMAKE_CURRENT_LIST_DIR}/.." ABSOLUTE)
endif()
set(root "${DVS_SOURCE_DIR}")
set(max_lines 700)
set(problems 0)

macro(problem text)
  message(SEND_ERROR "${text}")
  math(EXPR problems "${problems} + 1")
endmacro()

# (a) File length: one concept per file; a file over the limit is split along the seams it has.
file(GLOB_RECURSE sources RELATIVE "${root}"
  "${root}/engine/*.cpp" "${root}/engine/*.hpp" "${root}/shaders/*.comp" "${root}/shaders/*.glsl"
  "${root}/weights_tools/*.cpp" "${root}/weights_tools/*.hpp" "${root}/bench/*.cpp" "${root}/bench/*.hpp"
  "${root}/tests/*.cpp" "${root}/tests/*.hpp")
list(SORT sources)
list(LENGTH sources source_count)
if(source_count LESS 50)
  problem("house rules: found only ${source_count} source files under ${root}: is DVS_SOURCE_DIR the repository?")
endif()
foreach(f IN LISTS sources)
  file(READ "${root}/${f}" text)
  string(REGEX MATCHALL "\n" newlines "${text}")
  list(LENGTH newlines lines)
  if(lines GREATER max_lines)
    problem("${f}: ${lines} lines, over the ${max_lines}-line limit: split it along its seams")
  endif()
endforeach()

# (b) docs/layout.md and the tree agree. Folders are written there as `path/` (backticks, trailing slash).
set(layout_file "${root}/docs/layout.md")
if(NOT EXISTS "${layout_file}")
  problem("docs/layout.md: missing; it describes every folder of the source tree")
else()
  file(READ "${layout_file}" layout)
  string(REGEX MATCHALL "`[A-Za-z0-9_./-]+/`" named "${layout}")
  list(REMOVE_DUPLICATES named)
  foreach(token IN LISTS named)
    string(REGEX REPLACE "^`(.*)/`$" "\\1" dir "${token}")
    if(NOT IS_DIRECTORY "${root}/${dir}")
      problem("docs/layout.md names `${dir}/`, which is not a folder of the repository: remove or correct it")
    endif()
  endforeach()
  file(GLOB required LIST_DIRECTORIES true RELATIVE "${root}"
    "${root}/engine/src/*" "${root}/engine/src/models/*" "${root}/shaders/*")
  list(SORT required)
  foreach(dir IN LISTS required)
    string(FIND "${layout}" "`${dir}/`" described)
    if(IS_DIRECTORY "${root}/${dir}" AND described EQUAL -1)
      problem("${dir}/: not described in docs/layout.md: add a line `${dir}/` saying what lives there")
    endif()
  endforeach()
endif()

# (c) Citations a reader can follow. The design notes (DESIGN.md, "DESIGN §N") and the notes on the authors'
# code (official-code.md, anything under a top-level reference/ folder) were never part of the repository.
file(GLOB_RECURSE cited_in RELATIVE "${root}"
  "${root}/engine/*" "${root}/shaders/*" "${root}/weights_tools/*" "${root}/bench/*.cpp" "${root}/bench/*.hpp"
  "${root}/bench/*.sh" "${root}/bench/*.py" "${root}/tests/*.cpp" "${root}/tests/*.hpp" "${root}/tests/*.sh"
  "${root}/cmake/*" "${root}/.ci/*" "${root}/CMakeLists.txt")
list(FILTER cited_in EXCLUDE REGEX "^tests/golden/")
list(FILTER cited_in EXCLUDE REGEX "^tests/house_rules\\.cmake$")
list(SORT cited_in)
set(missing_doc "DESIGN( ?§|\\.md)|official-code\\.md|(^|[^A-Za-z0-9_./-])reference/[A-Za-z0-9_.-]+")
foreach(f IN LISTS cited_in)
  file(READ "${root}/${f}" text)
  string(REGEX MATCHALL "${missing_doc}" hits "${text}")
  foreach(hit IN LISTS hits)
    string(REGEX REPLACE "^[^A-Za-z]" "" hit "${hit}")
    if(hit MATCHES "^reference/" AND EXISTS "${root}/${hit}")
      continue()
    endif()
    problem("${f}: cites \"${hit}\", which is not in the repository: cite docs/design.md (or the paper's section) instead")
  endforeach()
endforeach()

# (d) One test command: CI runs exactly what the README tells a user to run.
set(ci_file "${root}/.ci/run")
set(marker "# --- the README's test command, verbatim ---\n")
file(READ "${ci_file}" ci)
string(FIND "${ci}" "${marker}" at)
if(at EQUAL -1)
  problem(".ci/run: no line \"${marker}\" before the test command: keep that marker above it")
else()
  string(LENGTH "${marker}" marker_length)
  math(EXPR start "${at} + ${marker_length}")
  string(SUBSTRING "${ci}" ${start} -1 rest)
  string(FIND "${rest}" "\n" end)
  string(SUBSTRING "${rest}" 0 ${end} command)
  file(READ "${root}/README.md" readme)
  string(FIND "${readme}" "\n${command}\n" in_readme)
  if(command STREQUAL "" OR in_readme EQUAL -1)
    problem("README.md: its test command differs from .ci/run's (the line after the marker): make them equal, byte for byte")
  endif()
endif()

if(problems GREATER 0)
  message(FATAL_ERROR "house rules: ${problems} problem(s)")
endif()
message(STATUS "house rules: ${source_count} source files checked, no problem")
