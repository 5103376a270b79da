#!/usr/bin/env bash
# Second device call of 2026-11-29: the op tests by value under the device's own entry (the first call's 27 s ran
# out inside AttentionTest.EveryHeadDimUpTo256, left out here), then a sweep around the GEMM layout the first call
# found best (2x2x4x4x32) and more attention/conv layouts. Setup as bench/gpu/run.sh does it.
set -u
B=$(mktemp -d /tmp/dvs-gpu2.XXXXXX)
tar -C "$B" -xJf .gpu/bundle.tar.xz
for d in "$B"/debs/lib*.deb; do dpkg -x "$d" /; done
dpkg -x "$(ls "$B"/debs/vulkan-validationlayers_1.4.*.deb | head -n1)" /
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
export DVS_SOURCE_DIR=$PWD DVS_GOLDEN_DIR=$PWD/tests/golden/A DVS_VDA_GOLDEN_DIR=$PWD/tests/golden/vda-A
export DVS_BIN_DIR=$B/bin VK_LOADER_DEBUG=none
OPS="AttentionTest.*:OpsCheck*:ConvOps.*:ElementwiseOps*:LayoutOps*:LinearTest.*:GpuTest.*:RowMappingTest.*"
OPS+=":RopeTables.*:RandomOps.*:ResizeBilinear.*:Split*:TinyModel.*:Kernel*:Tuning*:Coopmat*:Tiled*"
OPS+=":PackedConvOps.*:HalfInputConvOps.*:ConvFamilies.*-AttentionTest.EveryHeadDimUpTo256"
echo "=== ops (device entry), timeout 110 s"
timeout 110 "$B/bin/dvs_tests" --gtest_filter="$OPS" --gtest_brief=1 > "$OUT/ops.txt" 2>&1
echo "ops rc=$?" | tee -a "$OUT/ops.txt"
grep -E "FAILED|PASSED|SKIPPED|tests ran" "$OUT/ops.txt" | tail -20
t0=$SECONDS
for v in "gemm|linear_coopmat=2x2x4x4x32" "gemm|linear_coopmat=2x2x4x4x16" "gemm|linear_coopmat=2x2x4x4x64" \
         "gemm|linear_coopmat=4x2x4x4x32" "gemm|linear_coopmat=2x4x4x4x32" "gemm|linear_coopmat=1x1x4x4x32" \
         "gemm|linear_coopmat=2x2x2x4x32" "gemm|linear_coopmat=2x2x4x2x32" \
         "gemm|linear_coopmat=2x2x4x4x32,linear_coopmat_group_m=1" \
         "gemm|linear_coopmat=2x2x4x4x32,linear_coopmat_ablation=no_global_loads" \
         "gemm|linear_coopmat=2x2x4x4x32,linear_coopmat_ablation=no_mma" \
         "gemm|linear_coopmat=2x2x4x4x32,linear_weights_fp16=off" \
         "attention|attention_coopmat_subgroups=4" "attention|attention_coopmat_subgroups=16" \
         "conv3d|conv_coopmat=2x2x4x4x32" "conv3d|conv_coopmat=2x2x2x2x32" "conv3d|conv_coopmat=2x4x4x2x32"; do
  [ $((SECONDS - t0)) -gt 150 ] && { echo "sweep: skipped $v (150 s spent)"; continue; }
  c=${v%%|*} tn=${v#*|}
  echo "=== sweep $c $tn"
  DVS_TUNING="$tn" DVS_GPU_BENCH_VARIANT="$tn" DVS_GPU_BENCH_CASES="$c" DVS_GPU_BENCH_FAMILIES=coopmat \
    DVS_GPU_BENCH_JSON="$OUT/sweep.jsonl" timeout 30 "$B/bin/dvs-bench" --filter gpu 2>&1 | grep -E "^gpu_|error|Error" | head -8
done
echo "done in $SECONDS s"
