#!/usr/bin/env bash
# The C API's tests against the installed package (issue 34: the library's findings are tested as an application
# sees the library): tests/test_c_api.c compiled with `cc -std=c99 $(pkg-config --cflags --libs dvs)` and run, and
# the ctypes tests (tests/python/test_c_api*.py, including every option of the C structs applied as `dvs run`
# applies its flag) on the prefix's libdvs.so, libdvs_video.so and bin/dvs. Called by run_install_test.sh.
# Usage: run_c_api_tests.sh PREFIX LIBDIR WORK   (LIBDIR relative to PREFIX; PKG_CONFIG_PATH set by the caller)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
tests="$(cd "$here/.." && pwd)"
prefix="${1:?usage: run_c_api_tests.sh PREFIX LIBDIR WORK}" libdir="${2:?}" work="${3:?}"
fail() { echo "install test (C API): $*" >&2; exit 1; }
lib="$prefix/$libdir/libdvs.so" video_lib="$prefix/$libdir/libdvs_video.so" program="$prefix/bin/dvs"
video=()
[ -f "$video_lib" ] && video=(--video-lib "$video_lib")

echo "--- tests/test_c_api.c against the installed dvs.h and libdvs.so"
# shellcheck disable=SC2046
cc -std=c99 -Wall -Werror -o "$work/c_api_test" "$tests/test_c_api.c" $(pkg-config --cflags --libs dvs) \
  -Wl,-rpath,"$prefix/$libdir" || fail "building tests/test_c_api.c against the prefix failed"
"$work/c_api_test" "$work/c_api_c" || fail "tests/test_c_api.c failed on the installed library"

echo "--- tests/python/test_c_api.py, test_c_api_clip.py and test_c_api_options.py on the installed libraries"
python3 "$tests/python/test_c_api.py" "$lib" "$program" --vda "$tests/golden/vda-A/model/video_depth_anything_tiny.pth" \
  "${video[@]}" || fail "test_c_api.py failed on the installed library"
python3 "$tests/python/test_c_api_clip.py" "$lib" "$program" "$tests/golden/A/model" ||
  fail "test_c_api_clip.py failed on the installed library"
python3 "$tests/python/test_c_api_options.py" "$lib" "$program" "$tests/golden/A/model" \
  "$tests/golden/vda-A/model/video_depth_anything_tiny.pth" "${video[@]}" ||
  fail "test_c_api_options.py failed on the installed library"
