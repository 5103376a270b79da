# ctest public_api_views_constness (issue 34 §2.11): const_input.cpp (const memory as every kind of input) compiles
# against the public headers, const_output.cpp (const memory as an output) does not, for the reason of constness.
# cmake -DCXX=... -DSOURCE_DIR=... -DGENERATED_INCLUDE_DIR=... -P check_views_constness.cmake
set(here ${SOURCE_DIR}/tests/public_api)
set(flags -std=c++20 -fsyntax-only -I${SOURCE_DIR}/engine/include -I${GENERATED_INCLUDE_DIR})
execute_process(COMMAND ${CXX} ${flags} ${here}/const_input.cpp RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "const memory as an input does not compile:\n${err}")
endif()
execute_process(COMMAND ${CXX} ${flags} ${here}/const_output.cpp RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "const memory as a render's output compiles: outputs must take writable memory")
endif()
if(NOT err MATCHES "const")
  message(FATAL_ERROR "const_output.cpp fails for another reason than constness:\n${err}")
endif()
message(STATUS "inputs take const memory; outputs refuse it")
