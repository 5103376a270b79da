#!/usr/bin/env bash
# The installed library as an application sees it (issue 22): installs BUILD_DIR into a fresh prefix, checks the
# installed files, what libdvs.so exports and links, then builds tests/install/consumer/ against the prefix twice
# (CMake's find_package, and plain c++ with pkg-config) and runs both; then the library under careless use (issue 34
# §2: tests/install/careless/ in C++ and C, tests/python/test_c_api_careless.py through ctypes, with the conformance
# pack's tiny model) and libdvs_video needed alone.
# Usage: run_install_test.sh BUILD_DIR [PREFIX]
#   PREFIX: where to install (must be empty or absent); default a temporary folder, removed at the end unless
#   DVS_KEEP_PREFIX=1. The prefix is printed ("installed to ..."), so a later step (examples/preview) can reuse it.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
build="$(cd "${1:?usage: run_install_test.sh BUILD_DIR [PREFIX]}" && pwd)"
work="$(mktemp -d "${TMPDIR:-/tmp}/dvs-install-test.XXXXXX")"
prefix="${2:-$work/prefix}"
if [ -e "$prefix" ] && [ -n "$(ls -A "$prefix" 2>/dev/null)" ]; then
  echo "run_install_test.sh: $prefix is not empty; give an empty or new folder" >&2
  exit 2
fi
cleanup() { if [ "${DVS_KEEP_PREFIX:-0}" != 1 ]; then rm -rf "$work"; fi; }
trap cleanup EXIT
fail() { echo "install test: $*" >&2; exit 1; }
step() { echo "--- $*"; }

step "cmake --install $build --prefix $prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log" || { cat "$work/install.log" >&2; fail "cmake --install failed"; }
echo "installed to $prefix"
(cd "$prefix" && find . \( -type f -o -type l \) | sed 's|^\./||' | sort) >"$work/files.txt"
echo "installed files:"
sed 's/^/  /' "$work/files.txt"

step "the installed file list"
libdir="$(dirname "$(grep -E '(^|/)libdvs\.so$' "$work/files.txt" | head -n1)")"
[ "$libdir" != "." ] && [ -n "$libdir" ] || fail "no libdvs.so under $prefix"
expected=(bin/dvs include/dvs/api.hpp include/dvs/api.h include/dvs/version.h include/dvs/context.hpp
          include/dvs/error.hpp include/dvs/pipeline.hpp include/dvs/scene.hpp include/dvs/views.hpp
          "$libdir/libdvs.so" "$libdir/libdvs.so.0" "$libdir/cmake/dvs/dvsConfig.cmake"
          "$libdir/cmake/dvs/dvsConfigVersion.cmake" "$libdir/cmake/dvs/dvsTargets.cmake" "$libdir/pkgconfig/dvs.pc")
for f in "${expected[@]}"; do grep -Fxq "$f" "$work/files.txt" || fail "$f is not installed"; done
for f in $(cd "$here/../../engine/include" && find dvs -name '*.hpp' -o -name '*.h'); do
  grep -Fxq "include/$f" "$work/files.txt" || fail "the public header $f is not installed"
done
if grep -Eq 'include/(io|vk|tensor|pipeline|models)/|nlohmann|\.a$' "$work/files.txt"; then
  fail "internal headers or static libraries are installed: $(grep -E 'include/(io|vk|tensor|pipeline|models)/|nlohmann|\.a$' "$work/files.txt" | head -n3)"
fi
lib="$prefix/$libdir/libdvs.so"

step "exported symbols of libdvs.so"
bash "$here/check_exports.sh" "$lib" "dvs::version()" "typeinfo for dvs::Error" "typeinfo for dvs::UsageError" \
  "typeinfo for dvs::Cancelled" "dvs::Context::Context(dvs::ContextOptions const&)"

step "what libdvs.so links: no OpenCV videoio/imgcodecs, FFmpeg or GDAL"
readelf -d "$lib" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/  NEEDED \1/p'
if readelf -d "$lib" | grep -E '\(NEEDED\).*(videoio|imgcodecs|avcodec|avformat|gdal)'; then fail "libdvs.so needs a video library"; fi
if ldd "$lib" | grep -E 'videoio|imgcodecs|avcodec|avformat|gdal'; then fail "libdvs.so's closure (ldd) holds a video library"; fi
if grep -q 'not found' <<<"$(ldd "$lib")"; then ldd "$lib" >&2; fail "libdvs.so needs a library that is not found"; fi

video_lib="$prefix/$libdir/libdvs_video.so"
if [ -f "$video_lib" ]; then
  step "libdvs_video.so: exports, and registers with libdvs.so's own video registry"
  bash "$here/check_exports.sh" "$video_lib" "dvs::enable_video_files()" \
    "dvs::read_video_frames(std::filesystem::__cxx11::path const&, int, int, int, int, bool)" \
    "dvs::read_video_frames_for_depth(std::filesystem::__cxx11::path const&, int, int)" "dvs_enable_video_files"
  [ "$(nm -D --defined-only "$video_lib" | grep -c ' [TDBRVW] ')" = 4 ] ||
    fail "libdvs_video.so exports more than dvs::enable_video_files(), dvs::read_video_frames, read_video_frames_for_depth and dvs_enable_video_files"
  grep -q ' U dvs::detail::set_video_backend' <<<"$(nm -D -C "$video_lib")" ||
    fail "libdvs_video.so does not take dvs::detail::set_video_backend from libdvs.so (it would register with a copy)"
  for f in "$libdir/libdvs_video.so" "$libdir/libdvs_video.so.0" "$libdir/cmake/dvs/dvsVideoTargets.cmake" "$libdir/pkgconfig/dvs-video.pc"; do
    grep -Fxq "$f" "$work/files.txt" || fail "$f is not installed"
  done
fi

step "the consumer, with find_package(dvs 0.1 CONFIG REQUIRED)"
cmake -S "$here/consumer" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release >"$work/consumer.log" 2>&1 ||
  { cat "$work/consumer.log" >&2; fail "configuring the consumer failed"; }
cmake --build "$work/consumer" >>"$work/consumer.log" 2>&1 || { cat "$work/consumer.log" >&2; fail "building the consumer failed"; }
"$work/consumer/consumer" || fail "the consumer (CMake) failed"
grep -q 'NEEDED.*libdvs\.so\.0' <<<"$(readelf -d "$work/consumer/consumer")" || fail "the consumer does not link libdvs.so.0"

step "the consumer, with c++ \$(pkg-config --cflags --libs dvs)"
export PKG_CONFIG_PATH="$prefix/$libdir/pkgconfig"
[ "$(pkg-config --modversion dvs)" = "$(sed -n 's/^Version: //p' "$prefix/$libdir/pkgconfig/dvs.pc")" ] || fail "pkg-config cannot read dvs.pc"
# shellcheck disable=SC2046
c++ -std=c++20 -o "$work/consumer-pc" "$here/consumer/main.cpp" $(pkg-config --cflags --libs dvs) \
  -Wl,-rpath,"$(pkg-config --variable=libdir dvs)" || fail "building the consumer with pkg-config failed"
"$work/consumer-pc" || fail "the consumer (pkg-config) failed"

if [ -f "$video_lib" ]; then
  step "reading a video: linked with dvs::video it works, with dvs::core alone the error names the component"
  # shellcheck disable=SC2046
  c++ -std=c++17 -o "$work/make_video" "$here/make_video.cpp" $(pkg-config --cflags --libs opencv4) || fail "building make_video failed"
  "$work/make_video" "$work/clip.mp4" || fail "make_video could not write a test video"
  cmake -S "$here/video_consumer" -B "$work/video_consumer" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release \
    >"$work/video_consumer.log" 2>&1 || { cat "$work/video_consumer.log" >&2; fail "configuring the video consumers failed"; }
  cmake --build "$work/video_consumer" >>"$work/video_consumer.log" 2>&1 || { cat "$work/video_consumer.log" >&2; fail "building the video consumers failed"; }
  grep -q 'NEEDED.*libdvs_video\.so\.0' <<<"$(readelf -d "$work/video_consumer/read_video_file")" || fail "read_video_file does not link libdvs_video"
  if grep -q 'NEEDED.*libdvs_video' <<<"$(readelf -d "$work/video_consumer/read_video_core_only")"; then fail "read_video_core_only links libdvs_video"; fi
  "$work/video_consumer/read_video_file" "$work/clip.mp4" "5 frames of 48x64" || fail "the consumer with dvs::video cannot read the video"
  "$work/video_consumer/read_video_core_only" "$work/clip.mp4" "needs dvs's video component" ||
    fail "the consumer with dvs::core alone does not get the 'needs dvs's video component' error"
  # pkg-config's dvs-video, as an application without CMake links it
  # shellcheck disable=SC2046
  c++ -std=c++20 -DCONSUMER_LINKS_VIDEO=1 -o "$work/read_video_pc" "$here/video_consumer/main.cpp" \
    $(pkg-config --cflags --libs dvs-video) -Wl,-rpath,"$(pkg-config --variable=libdir dvs)" || fail "building with pkg-config dvs-video failed"
  "$work/read_video_pc" "$work/clip.mp4" "5 frames of 48x64" || fail "the pkg-config dvs-video consumer cannot read the video"

  step "a program that calls only dvs::read_video_frames finds libdvs.so.0 through libdvs_video's RUNPATH"
  readelf -d "$video_lib" | grep -q 'R.*PATH.*\$ORIGIN' || fail "libdvs_video.so has no \$ORIGIN RUNPATH: $(readelf -d "$video_lib" | grep PATH)"
  # shellcheck disable=SC2046
  c++ -std=c++20 -o "$work/read_frames_only" "$here/video_consumer/read_frames_only.cpp" -Wl,--as-needed \
    $(pkg-config --cflags --libs dvs-video) -Wl,-rpath,"$(pkg-config --variable=libdir dvs)" || fail "building read_frames_only failed"
  if grep -q 'NEEDED.*libdvs\.so' <<<"$(readelf -d "$work/read_frames_only")"; then
    fail "read_frames_only needs libdvs.so itself: it no longer tests that libdvs_video finds it"
  fi
  "$work/read_frames_only" "$work/clip.mp4" || fail "read_frames_only (libdvs_video alone) cannot run or read the video"
  step "reading a video from C (issue 34): pkg-config dvs-video with --as-needed needs dvs_enable_video_files()"
  for calls in 1 0; do
    # shellcheck disable=SC2046
    cc -std=c99 -Wall -Werror -DCALLS_ENABLE=$calls -o "$work/c_video_$calls" "$here/c_video_consumer.c" \
      $(pkg-config --cflags --libs dvs-video) -Wl,--as-needed -Wl,-rpath,"$(pkg-config --variable=libdir dvs)" ||
      fail "building the C video consumer (CALLS_ENABLE=$calls) failed"
  done
  grep -q 'NEEDED.*libdvs_video\.so\.0' <<<"$(readelf -d "$work/c_video_1")" || fail "the C consumer that calls dvs_enable_video_files does not link libdvs_video"
  if grep -q 'NEEDED.*libdvs_video' <<<"$(readelf -d "$work/c_video_0")"; then
    fail "--as-needed kept libdvs_video in a C program that calls nothing of it: the check below proves nothing"
  fi
  "$work/c_video_1" "$work/clip.mp4" "5 frames of 48x64" "$work/c_render" || fail "the C consumer with dvs_enable_video_files cannot read the video"
  "$work/c_video_0" "$work/clip.mp4" "needs dvs's video component" "$work/c_render" >"$work/c_video_0.log" &&
    grep -q "and call dvs_enable_video_files() (dvs/dvs_video.h)" "$work/c_video_0.log" ||
    fail "the C consumer without dvs_enable_video_files does not get the video component's problem naming that call"

  step "reading a video from Python's ctypes: libdvs.so, then libdvs_video.so and dvs_enable_video_files()"
  python3 "$here/c_video_ctypes.py" "$prefix/$libdir" "$work/clip.mp4" "5 frames of 48x64" "$work/ctypes_render" ||
    fail "ctypes on the installed libraries cannot read the video"
else
  step "no libdvs_video.so (a DVS_VIDEO_IO=OFF build): find_package(dvs COMPONENTS video) fails, saying so"
  if cmake -S "$here/video_consumer" -B "$work/video_consumer" -DCMAKE_PREFIX_PATH="$prefix" >"$work/video_consumer.log" 2>&1; then
    fail "find_package(dvs COMPONENTS video) succeeded without a video component"
  fi
  # CMake wraps the message's lines: compare with the line breaks and indentation folded into single spaces
  grep -q "built without its video component" <<<"$(tr -s ' \n' '  ' <"$work/video_consumer.log")" ||
    { cat "$work/video_consumer.log" >&2; fail "the missing video component's message does not say so"; }
fi

step "careless use (issue 34 §2): the installed dvs/dvs.h includes only C headers"
includes="$(grep -h '^#include' "$prefix/include/dvs/dvs.h" "$prefix/include/dvs/api.h" "$prefix/include/dvs/version.h" || true)"
echo "$includes" | sed 's/^/  /'
if grep -Ev '^#include [<"][A-Za-z0-9_/]+\.h[>"]' <<<"$includes" | grep -q .; then fail "dvs/dvs.h includes a header that is not C"; fi

step "careless use: C++ and C programs against the installed package"
model="$here/../golden/A/model"
cmake -S "$here/careless" -B "$work/careless" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release >"$work/careless.log" 2>&1 ||
  { cat "$work/careless.log" >&2; fail "configuring the careless-use programs failed"; }
cmake --build "$work/careless" >>"$work/careless.log" 2>&1 || { cat "$work/careless.log" >&2; fail "building the careless-use programs failed"; }
"$work/careless/careless" "$model" "$work/careless-cache" || fail "careless use in C++ (see the FAIL lines above)"
"$work/careless/careless_c" "$model" "$work/careless-cache" || fail "careless use in C (see the FAIL lines above)"

step "careless use: Python ctypes against the installed libraries"
python3 "$here/../python/test_c_api_careless.py" "$prefix/$libdir" "$model" || fail "careless use through ctypes"

step "an unknown component is refused by name"
mkdir -p "$work/badcomp"
printf 'cmake_minimum_required(VERSION 3.22)\nproject(b LANGUAGES CXX)\nfind_package(dvs CONFIG REQUIRED COMPONENTS teleport)\n' \
  >"$work/badcomp/CMakeLists.txt"
if cmake -S "$work/badcomp" -B "$work/badcomp/build" -DCMAKE_PREFIX_PATH="$prefix" >"$work/badcomp.log" 2>&1; then
  fail "find_package(dvs COMPONENTS teleport) succeeded"
fi
grep -q "no component 'teleport'" <<<"$(tr -s ' \n' '  ' <"$work/badcomp.log")" || { cat "$work/badcomp.log" >&2; fail "the unknown component's message does not name it"; }

step "the C API's tests on the installed package (tests/install/run_c_api_tests.sh)"
bash "$here/run_c_api_tests.sh" "$prefix" "$libdir" "$work"

echo "install test: all checks passed (prefix $prefix)"
