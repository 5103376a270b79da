#!/usr/bin/env bash
# The sanitizer step of CI (run once): builds build-sanitize with clang, AddressSanitizer + UndefinedBehaviorSanitizer
# (DVS_SANITIZE) and the libFuzzer harnesses (DVS_FUZZ), runs every harness of tests/fuzz for a fixed time over its
# seed corpus, then the unit tests under the sanitizers. Fails on any crash, hang, leak, out-of-memory or
# sanitizer report. Prints per harness the executions per second and libFuzzer's coverage (cov: edges, ft: features).
#
#   tests/run_sanitized.sh                 everything: about 4 minutes of fuzzing, then the tests labelled
#                                          "sanitize" (dvs_sanitize_tests, tests/CMakeLists.txt: every reader, the
#                                          dvs program on tiny models, the caches)
#   DVS_FUZZ_SECONDS=60                    a longer fuzzing budget per harness (default 15)
#   DVS_SANITIZE_TESTS=all                 the whole unit suite (builds dvs_tests: far slower), or 'none' to fuzz only
#   DVS_FUZZ_ONLY=fuzz_npy                 one harness (a name or a regular expression of names)
# Mesa (lavapipe runs inside the test processes), the Vulkan loader and OpenCV are not built with the sanitizers:
# their leaks are suppressed by library name in tests/sanitizers/lsan.supp; nothing of dvs's own is suppressed.
set -euo pipefail
cd "$(dirname "$0")/.."
SOURCE_DIR="$PWD"
BUILD="${DVS_SANITIZE_BUILD:-build-sanitize}"
FUZZ_SECONDS="${DVS_FUZZ_SECONDS:-15}"
TESTS="${DVS_SANITIZE_TESTS:-sanitize}"
ONLY="${DVS_FUZZ_ONLY:-.}"
JOBS="${DVS_SANITIZE_JOBS:-$(nproc)}"
start=$(date +%s)
elapsed() { echo "$(( $(date +%s) - start ))s"; }

for tool in clang++ cmake; do
  command -v "$tool" >/dev/null || { echo "run_sanitized.sh: $tool not found; bash .ci/deps installs clang and libclang-rt-14-dev" >&2; exit 1; }
done
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi

echo "== configure $BUILD (clang, ASan+UBSan, libFuzzer harnesses) [$(elapsed)]"
mkdir -p "$BUILD"
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ "${launcher[@]}" \
  -DDVS_SANITIZE=ON -DDVS_FUZZ=ON -DDVS_BUILD_BENCH=OFF >"$BUILD/configure.log" 2>&1 ||
  { cat "$BUILD/configure.log"; exit 1; }
targets=(dvs_fuzzers)
case "$TESTS" in
  none) ;;
  all) targets+=(dvs_tests dvs); ctest_selection=(-L unit) ;;
  sanitize) targets+=(dvs_sanitize_tests); ctest_selection=(-L sanitize) ;;
  *) echo "run_sanitized.sh: DVS_SANITIZE_TESTS must be sanitize (the default), all or none, got '$TESTS'" >&2; exit 2 ;;
esac
echo "== build ${targets[*]} [$(elapsed)]"
cmake --build "$BUILD" -j"$JOBS" --target "${targets[@]}"

export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:check_initialization_order=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$SOURCE_DIR/tests/sanitizers/ubsan.supp"
export LSAN_OPTIONS="suppressions=$SOURCE_DIR/tests/sanitizers/lsan.supp:print_suppressions=0"

echo "== fuzzing: ${FUZZ_SECONDS}s per harness [$(elapsed)]"
work="$BUILD/fuzz-run"
rm -rf "$work"
mkdir -p "$work"
failed=()
summary=()
for corpus in tests/fuzz/corpus/*/; do
  name="$(basename "$corpus")"
  harness="fuzz_$name"
  [[ "$harness" =~ $ONLY ]] || continue
  program="$BUILD/tests/fuzz/$harness"
  [ -x "$program" ] || { echo "run_sanitized.sh: no harness $program for $corpus (tests/fuzz/$harness.cpp)" >&2; failed+=("$harness (missing)"); continue; }
  # New inputs go to a scratch corpus; the committed seeds are only read.
  mkdir -p "$work/$name"
  log="$work/$name.log"
  set +e
  "$program" "$work/$name" "$corpus" -max_total_time="$FUZZ_SECONDS" -timeout=10 -rss_limit_mb=2048 \
    -malloc_limit_mb=2048 -detect_leaks=1 -print_final_stats=1 -artifact_prefix="$work/$name-" >"$log" 2>&1
  rc=$?
  set -e
  # A run that stopped on a finding has no DONE line: the last coverage line it printed stands in.
  cov="$(grep -oE 'cov: [0-9]+ ft: [0-9]+ corp: [0-9]+/[0-9]+[a-zA-Z]*' "$log" | tail -n1 || true)"
  runs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")"
  speed="$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")"
  line="$(printf '%-22s %9s execs %7s execs/s  %s' "$harness" "${runs:-?}" "${speed:-?}" "${cov:-no coverage line}")"
  summary+=("$line")
  if [ "$rc" -ne 0 ]; then
    echo "FAILED $line (exit $rc); the input that failed is $(ls "$work/$name"-* 2>/dev/null | head -n1)"
    grep -E 'ERROR: |SUMMARY: |runtime error|==ERROR|Test unit written|deadly signal|timeout|out-of-memory' "$log" | head -n 20
    echo "   (whole log: $log)"
    failed+=("$harness")
  else
    echo "ok     $line"
  fi
done

echo "== fuzzing done [$(elapsed)]"
printf '%s\n' "${summary[@]}"

if [ "$TESTS" != none ]; then
  echo "== tests under ASan+UBSan: ctest ${ctest_selection[*]} [$(elapsed)]"
  # The Vulkan loader unloads lavapipe at vkDestroyInstance, so by the time LeakSanitizer reports, the frames of
  # lavapipe's own one-time allocations belong to no module and lsan.supp cannot name them. Preloaded, lavapipe
  # stays mapped to the end and its frames keep its name (the slow unwinder would find the loader's frames too,
  # but makes every test several times slower).
  lavapipe="$(sed -n 's/.*"library_path": *"\([^"]*\)".*/\1/p' /usr/share/vulkan/icd.d/lvp_icd*.json 2>/dev/null | head -n1)"
  if [ -n "$lavapipe" ] && [ "${lavapipe#/}" = "$lavapipe" ]; then lavapipe="$(ldconfig -p | awk -v l="$lavapipe" '$1 == l {print $NF; exit}')"; fi
  [ -n "$lavapipe" ] && [ -f "$lavapipe" ] || { echo "run_sanitized.sh: lavapipe (mesa-vulkan-drivers) not found" >&2; exit 1; }
  export LD_PRELOAD="$lavapipe${LD_PRELOAD:+:$LD_PRELOAD}"
  if ! ctest --test-dir "$BUILD" --output-on-failure -j2 "${ctest_selection[@]}"; then failed+=("ctest ${ctest_selection[*]}"); fi
fi

echo "== run_sanitized.sh: $(elapsed) in all"
if [ ${#failed[@]} -gt 0 ]; then
  echo "run_sanitized.sh: FAILED: ${failed[*]}" >&2
  exit 1
fi
echo "run_sanitized.sh: every harness and test passed under ASan+UBSan"
