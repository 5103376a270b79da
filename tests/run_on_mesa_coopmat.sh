#!/usr/bin/env bash
# Runs a program built on Debian 12 (e.g. build/tests/dvs_tests) on Mesa 26.1's lavapipe from Debian
# trixie-backports, which offers VK_KHR_cooperative_matrix, so the tensor-core kernels can be tested by value
# without a GPU (tests/run_coopmat_pass.sh, the CI pass, uses it):
#   tests/run_on_mesa_coopmat.sh build/tests/dvs_tests --gtest_filter='CoopmatSmoke.*'
#   DVS_MESA_COOPMAT_SHAPE=16x16x16 tests/run_on_mesa_coopmat.sh build/tests/dvs_tests --gtest_filter=...
# .ci/deps unpacks it into /opt/dvs-mesa-coopmat (or DVS_MESA_COOPMAT_DIR) with Debian 13's validation layer
# (1.4.309) and every newer library it needs. That Mesa needs trixie's glibc (2.41), and one process has one C
# library, so the program is started by the private root's dynamic loader with the private libraries ahead of the
# system's (Debian 12's libraries, built for glibc 2.36, load under 2.41). The Vulkan loader then sees that one
# driver only (VK_DRIVER_FILES). Before running, checks that the device really is that Mesa, so a mis-set path
# never passes on the system's 22.3 unnoticed. The program must be an ELF executable (not a shell script: the
# private loader would not pass on to the processes it starts; tests that run `dvs` as a process cannot run here).
# What 26.1's lavapipe offers: subgroups of 8 (size control 8..8, at most 32 per workgroup), 32 KiB of shared
# memory; VK_KHR_cooperative_matrix lists 8x8x8 at subgroup scope only (fp16 x fp16 + fp16 or fp32, u8/s8 into
# 32 bits); VK_NV_cooperative_matrix2 with flexible dimensions (granularity 8x8x8, subgroup scope), reductions,
# conversions and per-element operations, but no workgroup scope, tensor addressing or block loads.
set -euo pipefail
dir="${DVS_MESA_COOPMAT_DIR:-/opt/dvs-mesa-coopmat}"
if [ ! -f "$dir/lvp_icd.json" ] || [ ! -f "$dir/libdir" ] || [ ! -f "$dir/ld" ] ||
   [ ! -f "$dir/layers/VkLayer_khronos_validation.json" ]; then
  echo "run_on_mesa_coopmat.sh: no Mesa 26.1 lavapipe in $dir: run 'bash .ci/deps' (or set DVS_MESA_COOPMAT_DIR)" >&2
  exit 1
fi
if [ $# -eq 0 ]; then
  echo "usage: tests/run_on_mesa_coopmat.sh PROGRAM [ARGS...]" >&2
  exit 2
fi
export VK_DRIVER_FILES="$dir/lvp_icd.json"
unset VK_ICD_FILENAMES
# Debian 13's validation layer: Debian 12's (1.3.239) predates VK_KHR_cooperative_matrix and reports its device
# structures and SPIR-V as errors. VK_LAYER_PATH replaces the system's explicit-layer folders.
export VK_LAYER_PATH="$dir/layers"
# The system's Mesa 22.3 device-select layer (implicit) is not needed with a single driver.
export NODEVICE_SELECT=1
# DVS_MESA_COOPMAT_SHAPE=16x16x16 (or 16x16x8): the GPUs' fragment for the coopmat kernels, which this lavapipe
# computes correctly but does not list (it lists 8x8x8 only): forced through DVS_TUNING, and the validation
# layer's report of the unlisted shape is filtered out (1.4.309 reports it on the multiply-add, 10060; later
# layers on the matrix type, 10163).
if [ -n "${DVS_MESA_COOPMAT_SHAPE:-}" ]; then
  export DVS_TUNING="${DVS_TUNING:+$DVS_TUNING,}coopmat=$DVS_MESA_COOPMAT_SHAPE"
  unlisted="VUID-RuntimeSpirv-OpCooperativeMatrixMulAddKHR-10060,VUID-RuntimeSpirv-OpTypeCooperativeMatrixKHR-10163"
  export VK_LAYER_MESSAGE_ID_FILTER="$unlisted${VK_LAYER_MESSAGE_ID_FILTER:+,$VK_LAYER_MESSAGE_ID_FILTER}"
  echo "run_on_mesa_coopmat.sh: DVS_TUNING=$DVS_TUNING (unlisted-shape validation report filtered)" >&2
fi
ld="$(cat "$dir/ld")"
libpath="$(cat "$dir/libdir"):/usr/lib/x86_64-linux-gnu:/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
driver="$("$ld" --library-path "$libpath" "$(command -v vulkaninfo)" --summary 2>/dev/null |
          sed -n 's/^[[:space:]]*driverInfo *= *//p' | head -n1)"
case "$driver" in
  "Mesa $(cut -d- -f1 "$dir/version")"*) echo "run_on_mesa_coopmat.sh: driver $driver ($VK_DRIVER_FILES)" >&2 ;;
  *) echo "run_on_mesa_coopmat.sh: expected Mesa $(cat "$dir/version") from $VK_DRIVER_FILES, the loader reports '${driver:-no device}'" >&2
     exit 1 ;;
esac
prog="$1"; shift
case "$prog" in */*) ;; *) prog="$(command -v "$prog")" ;; esac
exec "$ld" --library-path "$libpath" "$prog" "$@"
