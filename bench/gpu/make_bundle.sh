#!/usr/bin/env bash
# bench/gpu/make_bundle.sh [--no-check]: builds the relocatable GPU bundle, .gpu/bundle.tar.xz, the one file the
# device run carries (bench/gpu/run.sh unpacks it). A separate build (build-gpu) with DVS_VIDEO_IO=OFF (no
# OpenCV: its video stack pulls GDAL and FFmpeg, its core OpenBLAS and X11), static libstdc++/libgcc and an
# $ORIGIN/../lib DT_RPATH (not RUNPATH: RPATH also serves the copied libraries' own dependencies, e.g.
# libblas -> libopenblas). Holds bin/ (dvs, dvs-bench, dvs-weights, dvs_tests, dvs_golden_tests, stripped),
# lib/ (every library they load except glibc, libstdc++/libgcc, the Vulkan loader and driver/GL libraries),
# debs/ (Debian 12's libvulkan1 loader and Khronos validation layer: the device image has no loader) and
# MANIFEST.txt. The repository travels anyway, so the golden packs are not in the bundle: the tests find them
# through DVS_SOURCE_DIR / DVS_GOLDEN_DIR / DVS_VDA_GOLDEN_DIR and the programs through DVS_BIN_DIR (run.sh
# sets them). Then it checks the bundle: unpacked into a temporary folder, run with an empty environment (no
# build tree, no LD_LIBRARY_PATH) on this machine's Vulkan device, and ldd resolves nothing into the build.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="${DVS_GPU_BUILD_DIR:-$ROOT/build-gpu}"
DEST="$ROOT/.gpu"
JOBS="${JOBS:-2}"
CHECK=1
[ "${1:-}" = "--no-check" ] && CHECK=0

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# Test discovery at test time: the build never runs the test programs.
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DDVS_VIDEO_IO=OFF "${launcher[@]}" \
  -DCMAKE_EXE_LINKER_FLAGS="-static-libstdc++ -static-libgcc -Wl,--disable-new-dtags" \
  -DCMAKE_BUILD_WITH_INSTALL_RPATH=ON -DCMAKE_INSTALL_RPATH='$ORIGIN/../lib' \
  -DCMAKE_GTEST_DISCOVER_TESTS_DISCOVERY_MODE=PRE_TEST >/dev/null
nice cmake --build "$BUILD" -j"$JOBS" --target dvs dvs-bench dvs-weights dvs_tests dvs_golden_tests

stage="$DEST/stage"
rm -rf "$stage" "$DEST/bundle.tar.xz" "$DEST/debs"
mkdir -p "$stage/bin" "$stage/lib" "$stage/debs"
programs=(dvs bench/dvs-bench dvs-weights tests/dvs_tests tests/dvs_golden_tests)
for p in "${programs[@]}"; do strip -s -o "$stage/bin/$(basename "$p")" "$BUILD/$p"; done

# Libraries: what ldd resolves, less what the device has or must supply itself (glibc, the compiler runtime,
# the Vulkan loader, GPU driver and GL dispatch libraries; AppImage's excludelist is the model).
system='^(linux-vdso|ld-linux|libc|libm|libdl|libpthread|librt|libresolv|libutil|libgcc_s|libstdc\+\+|libvulkan|libGL|libGLX|libGLdispatch|libEGL|libOpenGL|libnvidia|libcuda|libdrm)\.so'
for p in "$stage"/bin/*; do
  ldd "$p" | awk '/=> \//{print $1, $3}'
done | sort -u | while read -r soname path; do
  [[ "$soname" =~ $system ]] && continue
  cp -L "$path" "$stage/lib/$soname"
done
strip --strip-unneeded "$stage"/lib/*.so* 2>/dev/null || true

# The loader and the validation layer as Debian packages, fetched with private amd64 apt states (cached in
# ~/.cache/dvs/gpu-debs, outside .gpu so that .gpu holds only what travels): Debian 12's libvulkan1 and vulkan-validationlayers 1.3.239, and Debian 13's validation layer
# 1.4.309 (glibc >= 2.38, libstdc++ 14: the device's Ubuntu 24.04 has them, this Debian 12 does not), which knows
# VK_KHR_cooperative_matrix (1.3.255) where 1.3.239 would report the tensor-core shaders as unknown. run.sh uses
# trixie's layer and falls back to bookworm's when it does not load.
debs="${XDG_CACHE_HOME:-$HOME/.cache}/dvs/gpu-debs"
mkdir -p "$debs"
fetch() {  # fetch SUITE PACKAGE...
  local suite="$1" state archive
  shift
  state="$(mktemp -d)"
  mkdir -p "$state/lists/partial" "$state/cache/archives/partial"
  archive="$( { grep -hE '^URIs:' /etc/apt/sources.list.d/*.sources 2>/dev/null || true
                grep -hE '^deb ' /etc/apt/sources.list /etc/apt/sources.list.d/*.list 2>/dev/null || true
              } | awk '{print $2}' | { grep -v -- '-security' || true; } | head -n1)"
  echo "deb ${archive:-http://deb.debian.org/debian} $suite main" > "$state/sources.list"
  local o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 "-oDir::Etc::SourceList=$state/sources.list"
           -oDir::Etc::SourceParts=/dev/null "-oDir::State::Lists=$state/lists" "-oDir::Cache=$state/cache")
  apt-get "${o[@]}" update -qq
  (cd "$debs" && apt-get "${o[@]}" download -qq "$@" 2>&1 | { grep -v unsandboxed || true; })
  rm -rf "$state"
}
# libglvnd's dispatch libraries: NVIDIA's Vulkan ICD (libGLX_nvidia) needs them and the device image has none
# (the device README's recipe; without them the loader finds no driver).
GLVND=(libglvnd0 libegl1 libgl1 libglx0 libopengl0 libgles2)
ls "$debs"/libvulkan1_1.3.*.deb "$debs"/vulkan-validationlayers_1.3.*.deb "$debs"/libglvnd0_*.deb >/dev/null 2>&1 ||
  fetch bookworm libvulkan1 vulkan-validationlayers "${GLVND[@]}"
ls "$debs"/vulkan-validationlayers_1.4.*.deb >/dev/null 2>&1 || fetch trixie vulkan-validationlayers
cp "$debs"/libvulkan1_1.3.*.deb "$debs"/vulkan-validationlayers_1.3.*.deb "$debs"/vulkan-validationlayers_1.4.*.deb \
  "$stage/debs/"
for p in "${GLVND[@]}"; do cp "$debs"/"${p}"_*.deb "$stage/debs/"; done

{
  echo "dvs GPU bundle, made $(date -u +%Y-%m-%dT%H:%M:%SZ) on $(uname -n)"
  echo "commit $(git -C "$ROOT" rev-parse HEAD)$(git -C "$ROOT" diff --quiet HEAD -- . ':!.gpu' || echo ' (with uncommitted changes)')"
  echo "cmake: -DDVS_VIDEO_IO=OFF, static libstdc++/libgcc, RPATH \$ORIGIN/../lib, Release"
  (cd "$stage" && find . -type f ! -name MANIFEST.txt -printf '%s\t%p\n' | sort -k2)
} > "$stage/MANIFEST.txt"

tar -C "$stage" -cf - . | xz -T"$JOBS" -6 > "$DEST/bundle.tar.xz"
packed=$(stat -c %s "$DEST/bundle.tar.xz")
unpacked=$(du -sb "$stage" | cut -f1)
echo "bundle: $DEST/bundle.tar.xz $((packed / 1024)) KiB packed ($(awk "BEGIN{printf \"%.1f\", $packed/1048576}") MiB)," \
     "$(awk "BEGIN{printf \"%.1f\", $unpacked/1048576}") MiB unpacked"
(cd "$stage" && du -sh bin lib debs | tr '\n' ' '; echo)
rm -rf "$stage"  # only bundle.tar.xz travels (carry .gpu or .gpu/bundle.tar.xz)

[ "$CHECK" = 1 ] || exit 0
# The check: from a temporary copy, with an empty environment.
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
tar -C "$tmp" -xJf "$DEST/bundle.tar.xz"
bad=0
for p in "$tmp"/bin/*; do
  while read -r soname path; do
    case "$path" in
      "$tmp"/*) ;;
      "$BUILD"/*|"$ROOT"/*|"not") echo "check: $(basename "$p"): $soname resolves to $path" >&2; bad=1 ;;
      *) [[ "$soname" =~ $system ]] || { echo "check: $(basename "$p"): $soname from the system ($path)" >&2; bad=1; } ;;
    esac
  done < <(env -i PATH=/usr/bin:/bin ldd "$p" | awk '/=>/{print $1, $3}')
done
[ "$bad" = 0 ] || { echo "check: the bundle is not self-contained" >&2; exit 1; }
clean=(env -i PATH=/usr/bin:/bin HOME="$HOME" DVS_SOURCE_DIR="$ROOT" DVS_BIN_DIR="$tmp/bin")
"${clean[@]}" "$tmp/bin/dvs" info | head -n 40
"${clean[@]}" "$tmp/bin/dvs-bench" --filter limits >/dev/null
echo "check: dvs-bench --filter limits ran from the bundle"
"${clean[@]}" "$tmp/bin/dvs_tests" --gtest_brief=1 \
  --gtest_filter='T5Tokenizer.*:GeometryTrajectory.OfficialPresetsMatchTsv:IoWeightsTool.*:VideoIoOff.*:LinearTest.OddShapesF32'
"${clean[@]}" "$tmp/bin/dvs_golden_tests" --gtest_brief=1 --gtest_filter='GoldenT5.*:VdaGolden.Preprocessing*'
echo "check: passed (bundle unpacked in $tmp, empty environment)"
