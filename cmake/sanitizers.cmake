# The sanitizer and fuzzing builds (tests/run_sanitized.sh configures both in build-sanitize; CI runs it once).
#
# DVS_SANITIZE: every target (libraries, programs, test programs) built with AddressSanitizer and
# UndefinedBehaviorSanitizer; the first report ends the process (-fno-sanitize-recover), so a test or fuzz run
# cannot pass over one. Included before any target is declared: add_compile_options only reaches targets made after.
# DVS_FUZZ (clang only): libFuzzer's coverage instrumentation on every target, so a harness sees the edges of
# the readers it drives; cmake/fuzzing.cmake then adds the harnesses of tests/fuzz.
option(DVS_SANITIZE "Build with AddressSanitizer + UndefinedBehaviorSanitizer" OFF)
option(DVS_FUZZ "Build the libFuzzer harnesses of tests/fuzz (clang only)" OFF)

if(DVS_SANITIZE)
  set(DVS_SANITIZER_FLAGS -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_compile_options(${DVS_SANITIZER_FLAGS})
  add_link_options(${DVS_SANITIZER_FLAGS})
endif()

if(DVS_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "DVS_FUZZ needs clang's libFuzzer, but the C++ compiler is ${CMAKE_CXX_COMPILER_ID} "
      "(${CMAKE_CXX_COMPILER}). Configure a separate build folder with -DCMAKE_CXX_COMPILER=clang++ "
      "(Debian: clang and libclang-rt-14-dev), as tests/run_sanitized.sh does.")
  endif()
  if(NOT DVS_SANITIZE)
    message(FATAL_ERROR "DVS_FUZZ needs DVS_SANITIZE=ON: a harness that runs without AddressSanitizer and "
      "UndefinedBehaviorSanitizer misses the out-of-bounds reads and overflows it is there to find.")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()
