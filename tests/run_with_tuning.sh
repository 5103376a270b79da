#!/usr/bin/env bash
# Runs a command (e.g. ctest) with a kernel-tuning entry forced (DVS_TUNING, tensor/kernel_tuning.hpp), so the
# kernels another device class would run are checked by value here on lavapipe:
#   tests/run_with_tuning.sh gpu ctest --test-dir build --output-on-failure -j2 -L golden
# The first argument is the DVS_TUNING string (an entry and/or fields: "gpu", "gpu,linear=texel").
# "gpu": storage-buffer elementwise inputs, a workgroup per norm row, the tiled linear/attention/conv
# families where they exist; the coopmat families fall back to tiled (lavapipe has no cooperative matrix).
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: tests/run_with_tuning.sh TUNING COMMAND [ARGS...]" >&2
  exit 2
fi
export DVS_TUNING="$1"
shift
echo "run_with_tuning.sh: DVS_TUNING=$DVS_TUNING"
exec "$@"
