#!/usr/bin/env bash
# The tensor-core pass: the op, golden and whole-pipeline tests by value on Mesa 26.1's lavapipe, which has
# VK_KHR_cooperative_matrix (.ci/deps unpacks it; tests/run_on_mesa_coopmat.sh runs a program there), with the
# tuning entry of tensor-core GPUs forced (DVS_TUNING=gpu-coopmat): the very shader code a GPU runs, laid out by
# the tuning table for lavapipe's 8 lanes, 32 KiB and its listed 8x8x8 fragment (docs/devices.md).
#   tests/run_coopmat_pass.sh [BUILD_DIR]        (default: build)
# DVS_REQUIRE_COOPMAT=linear,attention,conv makes the test programs fail a test in which a call fell back from
# the tensor-core kernels for a reason of the device, and fail at the end when any of the three never ran on
# them (tests/support/gpu.cpp; the census is printed). First a planted misfit (a linear layout this lavapipe
# cannot hold) must fail that check, so the check is known to be live.
# Not run here: tests that start `dvs` as a process (the private dynamic loader does not reach child processes).
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
run=tests/run_on_mesa_coopmat.sh
for p in "$build/tests/dvs_tests" "$build/tests/dvs_golden_tests"; do
  [ -x "$p" ] || { echo "run_coopmat_pass.sh: no $p (build the tests first)" >&2; exit 2; }
done
export DVS_TUNING=gpu-coopmat
export DVS_REQUIRE_COOPMAT=linear,attention,conv
start=$(date +%s)

# 1. The check is live: a 128 x 128 linear tile of 4 x 4 subgroups needs 44 KiB at 8x8 fragments (lavapipe has 32).
echo "run_coopmat_pass.sh: a planted misfit must fail the tensor-core check"
if DVS_TUNING="gpu-coopmat,linear_coopmat=4x4x4x4x32" \
   "$run" "$build/tests/dvs_tests" --gtest_filter='Family/LinearTest.ZeroK/device' > "$build/coopmat_pass_planted.log" 2>&1; then
  echo "run_coopmat_pass.sh: the planted misfit passed: the tensor-core check is not live" >&2
  exit 1
fi
grep -q "fell back from tensor cores for a reason of the device" "$build/coopmat_pass_planted.log" ||
  { echo "run_coopmat_pass.sh: the planted misfit failed for another reason:" >&2; tail -20 "$build/coopmat_pass_planted.log" >&2; exit 1; }

# 2. The op tests (the suites of .ci/run's GPU-entry pass), the layouts, the tuning and the smoke test, in two
# shards at once (GoogleTest's GTEST_TOTAL_SHARDS), then 3. the golden tests, the whole-pipeline (PipelineE2e) tests
# among them, after the second shard. From a cold shader cache Mesa 26.1 spends most of this pass compiling (one
# process: 637 s of op tests and 101 s of goldens on 2 cores); each process is one compile at a time, so two use both
# cores. Each shard still holds linear, attention and conv tests, so DVS_REQUIRE_COOPMAT's census holds per process.
ops='Ops*:*Ops.*:*Ops/*:Split*:Paths/*:AttentionTest.*:Family/*:ConvFamilies.*:LinearCoopmatTest.*:Resize*'
ops+=':KernelTuning*:LinearTuning.*:AttentionFlashPlan.*:CoopmatLayout*:CoopmatSmoke.*:GemmWeights.*'
ops_shard() {
  GTEST_TOTAL_SHARDS=2 GTEST_SHARD_INDEX="$1" \
    "$run" "$build/tests/dvs_tests" --gtest_filter="$ops-KernelTuning.DvsInfoPrintsTheChoice"
}
# 4. (after the first shard) The VAE and whole-pipeline goldens with the convolutions through the GEMM kernel
# (conv_shifted_gemm) and their input repacked by the transpose through shared memory (conv_pack_tiled), both off by
# default until a device run times them, at a GEMM layout whose K of 8 takes the tiny VAE's 8- and 16-channel
# convolutions; the census must show that kernel ran.
shifted_goldens() {
  local log="$build/coopmat_pass_shifted.log" rc=0
  DVS_TUNING=gpu-coopmat,conv_shifted_gemm=on,conv_pack_tiled=on,linear_coopmat=2x2x4x4x8 \
    "$run" "$build/tests/dvs_golden_tests" --gtest_filter='VaeGolden.*:PipelineE2e.*' > "$log" 2>&1 || rc=1
  cat "$log"
  [ "$rc" -eq 0 ] || return 1
  grep -q "conv: nn/conv_shifted_coopmat (coopmat)" "$log" ||
    { echo "run_coopmat_pass.sh: the goldens under conv_shifted_gemm=on never ran nn/conv_shifted_coopmat" >&2; return 1; }
}
# 5. (then) The real-size calls at small scale (the real 3072-wide GEMMs, the 128- to 512-channel convolutions, the
# latter through the GEMM kernel with the transposing repack: real row widths) against their CPU references and plans
# (tests/check_realsize_small.sh).
realsize_small() {
  [ -x "$build/bench/dvs-bench" ] || { echo "run_coopmat_pass.sh: no $build/bench/dvs-bench" >&2; return 1; }
  DVS_TUNING=gpu-coopmat,conv_shifted_gemm=on,conv_pack_tiled=on tests/check_realsize_small.sh transformer,vae_encode,vae_decode \
    "$build/bench/dvs-bench" "$run"
}
{ ops_shard 0 && shifted_goldens && realsize_small; } > "$build/coopmat_pass_ops0.log" 2>&1 &
first=$!
{ ops_shard 1 && "$run" "$build/tests/dvs_golden_tests"; } > "$build/coopmat_pass_ops1_golden.log" 2>&1 &
second=$!
rc=0
wait "$first" || rc=1
echo "== run_coopmat_pass.sh: op tests, shard 1 of 2, then the goldens with conv_shifted_gemm and the real-size calls ($build/coopmat_pass_ops0.log)"
cat "$build/coopmat_pass_ops0.log"
wait "$second" || rc=1
echo "== run_coopmat_pass.sh: op tests, shard 2 of 2, then the golden tests ($build/coopmat_pass_ops1_golden.log)"
cat "$build/coopmat_pass_ops1_golden.log"
if [ "$rc" -ne 0 ]; then
  echo "run_coopmat_pass.sh: FAILED (the logs above say which test)" >&2
  exit 1
fi
echo "run_coopmat_pass.sh: passed in $(( $(date +%s) - start )) s"
