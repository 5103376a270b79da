#!/usr/bin/env bash
# Runs a command (e.g. ctest) on the Mesa 25.0 lavapipe that .ci/deps unpacked into a private folder
# (default /opt/dvs-mesa25, or DVS_MESA25_DIR), instead of the system's Mesa 22.3:
#   tests/run_on_mesa25.sh ctest --test-dir build --output-on-failure -j2
# The Vulkan loader then sees that one driver only (VK_DRIVER_FILES); its newer libdrm comes first on
# LD_LIBRARY_PATH. Before running, checks with vulkaninfo that the device really is Mesa 25.0, so a
# mis-set path can never pass the suite on 22.3 (or on no driver) unnoticed.
set -euo pipefail
dir="${DVS_MESA25_DIR:-/opt/dvs-mesa25}"
if [ ! -f "$dir/lvp_icd.json" ] || [ ! -f "$dir/libdir" ]; then
  echo "run_on_mesa25.sh: no Mesa 25 lavapipe in $dir: run 'bash .ci/deps' (or set DVS_MESA25_DIR)" >&2
  exit 1
fi
export VK_DRIVER_FILES="$dir/lvp_icd.json"
unset VK_ICD_FILENAMES  # older name of the same setting; it would override VK_DRIVER_FILES' intent
export LD_LIBRARY_PATH="$(cat "$dir/libdir")${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
driver="$(vulkaninfo --summary 2>/dev/null | sed -n 's/^[[:space:]]*driverInfo *= *//p' | head -n1)"
case "$driver" in
  "Mesa 25.0"*) echo "run_on_mesa25.sh: driver $driver ($VK_DRIVER_FILES)" ;;
  *) echo "run_on_mesa25.sh: expected Mesa 25.0 from $VK_DRIVER_FILES, the loader reports '${driver:-no device}'" >&2
     exit 1 ;;
esac
exec "$@"
