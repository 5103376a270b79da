#!/usr/bin/env bash
# Runs a program built on Debian 12 (e.g. build/tests/dvs_tests) on Debian sid's lavapipe, which offers
# VK_KHR_cooperative_matrix, so the tensor-core kernels can be tested by value without a GPU:
#   tests/run_on_mesa_coopmat.sh build/tests/dvs_tests --gtest_filter='CoopmatSmoke.*'
#   DVS_MESA_COOPMAT_SHAPE=16x16x16 tests/run_on_mesa_coopmat.sh build/tests/dvs_tests --gtest_filter=...
# Set up once with DVS_MESA_COOPMAT=1 bash .ci/deps (unpacks it into /opt/dvs-mesa-coopmat, or
# DVS_MESA_COOPMAT_DIR). sid's Mesa needs glibc >= 2.43, and one process has one C library, so the program is
# started by the private root's dynamic loader with the private libraries ahead of the system's (Debian 12's
# libraries, built for glibc 2.36, load under 2.43). The Vulkan loader then sees that one driver only
# (VK_DRIVER_FILES). Before running, checks that the device really is that Mesa, so a mis-set path never
# passes on the system's 22.3 unnoticed. The program must be an ELF executable (not a shell script: the
# private loader would not pass on to the processes it starts).
set -euo pipefail
dir="${DVS_MESA_COOPMAT_DIR:-/opt/dvs-mesa-coopmat}"
if [ ! -f "$dir/lvp_icd.json" ] || [ ! -f "$dir/libdir" ] || [ ! -f "$dir/ld" ] ||
   [ ! -f "$dir/layers/VkLayer_khronos_validation.json" ]; then
  echo "run_on_mesa_coopmat.sh: no sid lavapipe in $dir: run 'DVS_MESA_COOPMAT=1 bash .ci/deps' (or set DVS_MESA_COOPMAT_DIR)" >&2
  exit 1
fi
if [ $# -eq 0 ]; then
  echo "usage: tests/run_on_mesa_coopmat.sh PROGRAM [ARGS...]" >&2
  exit 2
fi
export VK_DRIVER_FILES="$dir/lvp_icd.json"
unset VK_ICD_FILENAMES
# sid's validation layer: Debian 12's (1.3.239) predates VK_KHR_cooperative_matrix and reports its device
# structures and SPIR-V as errors. VK_LAYER_PATH replaces the system's explicit-layer folders.
export VK_LAYER_PATH="$dir/layers"
# The system's Mesa 22.3 device-select layer (implicit) is not needed with a single driver.
export NODEVICE_SELECT=1
# DVS_MESA_COOPMAT_SHAPE=16x16x16 (or 16x16x8): the coopmat kernels' shape, which this lavapipe computes
# correctly but does not list (it lists 8x8x8 only): forced through DVS_TUNING, and the validation layer's
# report of the unlisted shape (that one message id) is filtered out.
if [ -n "${DVS_MESA_COOPMAT_SHAPE:-}" ]; then
  export DVS_TUNING="${DVS_TUNING:+$DVS_TUNING,}coopmat=$DVS_MESA_COOPMAT_SHAPE"
  export VK_LAYER_MESSAGE_ID_FILTER="VUID-RuntimeSpirv-OpTypeCooperativeMatrixKHR-10163${VK_LAYER_MESSAGE_ID_FILTER:+,$VK_LAYER_MESSAGE_ID_FILTER}"
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
