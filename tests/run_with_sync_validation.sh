#!/usr/bin/env bash
# Runs a command (e.g. ctest) with the Khronos layer's synchronization validation on for every Vulkan instance
# that loads the layer (every test context does: tests/support/gpu.cpp), across submissions too, and with the
# GPU kernel entry forced (DVS_TUNING=gpu: the kernels a GPU runs), so that a missing barrier in any command
# buffer dvs records fails the test that recorded it, although lavapipe, which runs commands one after the
# other, computes the right values anyway:
#   tests/run_with_sync_validation.sh ctest --test-dir build --output-on-failure -j2 -R '...'
# CI's pass `syncval` (tests/run_all.sh) runs the goldens and a selection of the unit tests so; why that selection,
# and how to reproduce one failure: docs/testing.md ("Synchronization validation").
# Debian 12's layer (1.3.239) reads its enables from VK_LAYER_ENABLES at vkCreateInstance, ':'-separated
# (',' is ignored); QueueSubmit validation has no VkValidationFeatureEnableEXT of its own in that version, only
# the name below. DVS_VALIDATION=1 puts the layer into the programs the tests start (dvs run, ...) too; the
# tests that start them fail on any message those print (tests/support/process.cpp).
set -euo pipefail
if [ $# -lt 1 ]; then
  echo "usage: tests/run_with_sync_validation.sh COMMAND [ARGS...]" >&2
  exit 2
fi
enables="VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT:VALIDATION_CHECK_ENABLE_SYNCHRONIZATION_VALIDATION_QUEUE_SUBMIT"
# The layer must know both names, or it would ignore them silently and the pass would check nothing.
manifest=""
IFS=: read -ra data_dirs <<< "${XDG_DATA_DIRS:-/usr/local/share:/usr/share}"
for d in "${data_dirs[@]}" /etc; do
  f="$d/vulkan/explicit_layer.d/VkLayer_khronos_validation.json"
  if [ -f "$f" ]; then manifest="$f"; break; fi
done
if [ -z "$manifest" ]; then
  echo "run_with_sync_validation.sh: no VK_LAYER_KHRONOS_validation manifest (apt-get install vulkan-validationlayers)" >&2
  exit 1
fi
for name in ${enables//:/ }; do
  if ! grep -q "\"$name\"" "$manifest"; then
    echo "run_with_sync_validation.sh: the validation layer ($manifest) does not know $name" >&2
    exit 1
  fi
done
export VK_LAYER_ENABLES="$enables"
# The layer reports a message ID at most this often per instance (default 10): a test process must never run
# out, or a later hazard of the same kind would pass silently.
export VK_LAYER_DUPLICATE_MESSAGE_LIMIT="${VK_LAYER_DUPLICATE_MESSAGE_LIMIT:-1000000}"
export DVS_VALIDATION=1
export DVS_TUNING="${DVS_TUNING:-gpu}"
echo "run_with_sync_validation.sh: VK_LAYER_ENABLES=$VK_LAYER_ENABLES DVS_TUNING=$DVS_TUNING ($manifest)"
exec "$@"
