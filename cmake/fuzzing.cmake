# The libFuzzer harnesses (DVS_FUZZ, see cmake/sanitizers.cmake): one program per reader of outside input,
# tests/fuzz/fuzz_<name>.cpp, run by tests/run_sanitized.sh over the seed corpus tests/fuzz/corpus/<name>.
if(DVS_FUZZ)
  add_subdirectory(tests/fuzz)
endif()
