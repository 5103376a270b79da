#!/usr/bin/env bash
# The device stage "dvs beside PyTorch": bench/gpu/run.sh calls it on the GPU machine with $OUT set (the folder
# whose files come back) and $DVS_BIN holding dvs-bench; ctest runs `stage_bench.sh --smoke` on lavapipe.
#
#   1. torch_ref.py    PyTorch baselines (GEMM, SDPA, conv3d, copy, matmul ceiling) + the 1-layer real-size
#                      transformer folder, inputs and torch's bf16 / fp32 outputs in $BLOCK   -> $OUT/torch.jsonl
#   2. dvs-bench       --filter gpu: the same cases per kernel family, checked by value, and the block from
#                      $BLOCK through the production loader                                   -> $OUT/dvs.jsonl
#   3. compare_block   dvs's block output(s) and torch bf16's vs the fp32 reference (relative L2) -> $OUT/dvs.jsonl
#   4. sweep           dvs-bench again per tuning variant (tiles, subgroups per workgroup, blocks) of one case and
#                      family, each line tagged "variant" (issue 35 C.3), within STAGE_T_SWEEP s  -> $OUT/dvs.jsonl
#   5. summarize       the table: each case, dvs per family, torch, ratio, goals; the sweep's  -> $OUT/summary.md
# Each step runs under its own timeout (env STAGE_T_TORCH / STAGE_T_DVS, seconds; STAGE_TORCH_ARGS adds torch_ref.py options); JSON lines are written
# as each case ends, so a timeout keeps what finished. Whole stage <= ~210 s on an H100 (60 s of it the sweep).
# --smoke: tiny shapes, no PyTorch (the python files are only byte-compiled); runs on lavapipe in seconds.
# Three files in $OUT: torch.jsonl, dvs.jsonl, summary.md (the device returns at most 8 in all); every line is
# also appended to $DVS_GPU_RESULTS when run.sh sets it. $DVS_BIN or $DVS_GPU_BIN_DIR: the folder of dvs-bench.
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
SMOKE=${DVS_GPU_SMOKE:-0}  # bench/gpu/run.sh exports DVS_GPU_SMOKE, DVS_GPU_OUT, DVS_GPU_BIN_DIR, DVS_GPU_BENCH
for a in "$@"; do
  case "$a" in
    --smoke) SMOKE=1 ;;
    *) echo "usage: stage_bench.sh [--smoke]" >&2; exit 2 ;;
  esac
done
OUT=${OUT:-${DVS_GPU_OUT:-$(mktemp -d)}}
mkdir -p "$OUT"
TMPD=${TMPDIR:-/tmp}
BIN=${DVS_BIN:-${DVS_GPU_BIN_DIR:-$ROOT/build/bench}}
BENCH=${DVS_GPU_BENCH:-$BIN/dvs-bench}
[ -x "$BENCH" ] || { echo "stage_bench: no dvs-bench at $BENCH (set DVS_BIN)" >&2; exit 1; }
PY=${PYTHON:-python3}
BLOCK=${STAGE_BLOCK_DIR:-$TMPD/dvs_gpu_block}
TJ=$OUT/torch.jsonl DJ=$OUT/dvs.jsonl
: > "$TJ"; : > "$DJ"
status=0
step() {  # step NAME SECONDS CMD...: runs under timeout, notes a timeout or failure, never stops the stage
  local name=$1 secs=$2; shift 2
  local t0=$SECONDS
  echo "== stage_bench: $name (timeout ${secs}s)"
  timeout --kill-after=5 "$secs" "$@"
  local rc=$?
  echo "== stage_bench: $name rc=$rc in $((SECONDS - t0)) s"
  [ $rc -eq 124 ] && echo "{\"source\":\"stage\",\"step\":\"$name\",\"timed_out\":true,\"limit_s\":$secs}" >> "$DJ"
  [ $rc -ne 0 ] && status=1
  return 0
}

# Byte-compile the python files first (cheap; a syntax error must not cost a device run).
PYTHONPYCACHEPREFIX=$TMPD/dvs_pycache "$PY" -m py_compile "$HERE/torch_ref.py" "$HERE/compare_block.py" \
  "$HERE/summarize.py" || { echo "stage_bench: python files do not compile" >&2; exit 1; }

if [ $SMOKE -eq 1 ]; then
  unset DVS_LIMITS  # the smoke checks the script; CI's forced-limits pass would stop the peak shaders
  export DVS_GPU_BENCH_SMOKE=1
  unset DVS_GPU_BENCH_DIR  # no torch: no block folder (set STAGE_SMOKE_BLOCK to a torch_ref.py --quick folder)
  [ -n "${STAGE_SMOKE_BLOCK:-}" ] && export DVS_GPU_BENCH_DIR=$STAGE_SMOKE_BLOCK BLOCK=$STAGE_SMOKE_BLOCK
else
  rm -rf "$BLOCK"
  # torch first, so both see the same clocks.
  # STAGE_TORCH_ARGS: extra torch_ref.py options (e.g. --no-block for a short device run)
  # shellcheck disable=SC2086
  step torch_ref "${STAGE_T_TORCH:-55}" "$PY" "$HERE/torch_ref.py" --seed 0 --out "$BLOCK" --json "$TJ" ${STAGE_TORCH_ARGS:-}
  if [ -f "$BLOCK/transformer/config.json" ] && [ -f "$BLOCK/out_torch_fp32.npy" ]; then
    export DVS_GPU_BENCH_DIR=$BLOCK
  else
    echo "stage_bench: no block folder from torch_ref.py: dvs skips the block case"
  fi
fi

export DVS_GPU_BENCH_JSON=$DJ
step dvs_bench "${STAGE_T_DVS:-75}" "$BENCH" --filter gpu
if [ -n "${DVS_GPU_BENCH_DIR:-}" ]; then
  step compare_block 10 "$PY" "$HERE/compare_block.py" "$DVS_GPU_BENCH_DIR" --json "$DJ"
fi
# The sweep: "case|family|DVS_TUNING" per variant, most telling first (the defaults first, so each family's row in
# the sweep is comparable with the main table's); a variant the device cannot run errors or falls back, and says so
# in its line. STAGE_SWEEP replaces the list (space-separated); every variant gets at most 30 s, the whole sweep
# STAGE_T_SWEEP s (what is left when it ends is skipped, and said).
if [ $SMOKE -eq 1 ]; then
  default_sweep="gemm|tiled|linear_tile_m=32,linear_tile_n=32 attention|tiled|attention_block_q=32,attention_block_k=32"
else
  # Round 1, each family's default (as the H200 run of 2026-11-29 set them) and the one change per family most worth
  # timing: conv as the GEMM kernel itself (conv_shifted_gemm: off by default, unmeasured) at the GEMM's tile, with and
  # without its input repack transposed through shared memory (conv_pack_tiled: off by default, unmeasured; also
  # under the implicit-GEMM kernel), and at 2x4x4x2, conv's 16-byte gathers off (the kernel that run measured), at the GEMM's best tile (2x2 subgroups of
  # 4x4 fragments) and 2x4x4x2, its input repack in the former channel-major order, and through
  # VK_NV_cooperative_matrix2 (off by default: unmeasured) at four tiles, GEMM with the former 2x4 subgroups of 4x2 fragments, attention at the former 8
  # subgroups and its KHR kernel, the GEMM through VK_NV_cooperative_matrix2 (off by default: unmeasured) at its
  # default tile and four others, conv with one operand stage, with its input repacked f32 instead of fp16, with bf16 weights instead of fp16. Round 2: what each GEMM feed
  # change contributes (16-byte loads off, banded order off, W bf16 and X f32 converted in the loads instead of kept fp16) and the design study's ablations (no global loads, no MMA: where the time goes; their by-value check
  # fails by design); attention at 4 subgroups. Then other tiles.
  default_sweep="gemm|coopmat|linear_coopmat=2x2x4x4x32 attention|coopmat|attention_coopmat_subgroups=16
    conv3d|coopmat|conv_coopmat=4x2x2x4x32 conv3d|coopmat|conv_shifted_gemm=on
    conv3d|coopmat|conv_shifted_gemm=on,conv_pack_tiled=on conv3d|coopmat|conv_pack_tiled=on
    conv3d|coopmat|conv_shifted_gemm=on,linear_coopmat=2x4x4x2x32
    conv3d|coopmat|conv_coopmat_vector_loads=off conv3d|coopmat|conv_coopmat=2x2x4x4x32
    conv3d|coopmat|conv_pack_pixel_major=off conv3d|coopmat|conv_coopmat2=on
    conv3d|coopmat|conv_coopmat2=on,conv_coopmat2_tile=2x64x128x32x256 conv3d|coopmat|conv_coopmat2=on,conv_coopmat2_tile=4x32x256x32x256
    conv3d|coopmat|conv_coopmat2=on,conv_coopmat2_tile=4x32x128x64x256
    conv3d|coopmat|conv_coopmat=2x4x4x2x32 gemm|coopmat|linear_coopmat2=on gemm|coopmat|linear_coopmat2=on,linear_coopmat2_tile=256x128x32x256
    gemm|coopmat|linear_coopmat2=on,linear_coopmat2_tile=128x256x32x256 gemm|coopmat|linear_coopmat2=on,linear_coopmat2_tile=128x128x64x256
    gemm|coopmat|linear_coopmat2=on,linear_coopmat2_tile=128x128x32x128 gemm|coopmat|linear_coopmat=2x4x4x2x32 attention|coopmat|attention_coopmat_subgroups=8
    attention|coopmat|attention_coopmat2=off
    conv3d|coopmat|conv_coopmat_double_buffer=off conv3d|coopmat|conv_activations_fp16=off conv3d|coopmat|conv_weights_fp16=off
    gemm|coopmat|linear_coopmat_vector_loads=off gemm|coopmat|linear_coopmat_group_m=1 gemm|coopmat|linear_weights_fp16=off
    gemm|coopmat|linear_activations_fp16=off
    gemm|coopmat|linear_coopmat_ablation=no_global_loads gemm|coopmat|linear_coopmat_ablation=no_mma
    attention|coopmat|attention_coopmat_subgroups=4
    gemm|coopmat|linear_coopmat=2x2x2x2x32 gemm|coopmat|linear_coopmat=1x1x2x2x32 gemm|coopmat|linear_coopmat=4x2x2x4x32
    gemm|coopmat|linear_coopmat=2x4x4x2x16 attention|coopmat|attention_coopmat_subgroups=2
    attention|coopmat|attention_coopmat_subgroups=1 conv3d|coopmat|conv_coopmat=2x2x2x2x32
    conv3d|coopmat|conv_coopmat=1x1x2x2x32 gemm|tiled|linear_tile_m=128,linear_tile_n=128
    attention|tiled|attention_block_q=128,attention_block_k=64 conv3d|tiled|conv_tile_m=128,conv_tile_n=128"
fi
sweep_t=${STAGE_T_SWEEP:-$([ $SMOKE -eq 1 ] && echo 120 || echo 60)}
sweep_start=$SECONDS
for v in ${STAGE_SWEEP:-$default_sweep}; do
  IFS='|' read -r vcase vfam vtuning <<< "$v"
  left=$((sweep_t - (SECONDS - sweep_start)))
  if [ $left -le 0 ]; then
    echo "{\"source\":\"stage\",\"step\":\"sweep\",\"variant\":\"$vtuning\",\"case\":\"$vcase\",\"skipped\":\"the sweep's ${sweep_t} s were spent\"}" >> "$DJ"
    continue
  fi
  kept=$status  # a variant the device refuses is a figure of the sweep, not a failure of the stage
  status=0
  DVS_TUNING="$vtuning" DVS_GPU_BENCH_VARIANT="$vtuning" DVS_GPU_BENCH_CASES="$vcase" DVS_GPU_BENCH_FAMILIES="$vfam" \
    step "sweep $vcase $vfam $vtuning" "$(( left < 30 ? left : 30 ))" "$BENCH" --filter gpu
  [ $status -ne 0 ] &&
    echo "{\"source\":\"stage\",\"step\":\"sweep\",\"variant\":\"$vtuning\",\"case\":\"$vcase\",\"skipped\":\"dvs-bench failed or timed out (the log says why)\"}" >> "$DJ"
  status=$kept
done
timeout 5 "$PY" "$HERE/summarize.py" "$TJ" "$DJ" > "$OUT/summary.md" || status=1
cat "$OUT/summary.md"
# run.sh's results file gets every line too (its own copy of the stage, beside the three files here).
[ -n "${DVS_GPU_RESULTS:-}" ] && cat "$TJ" "$DJ" >> "$DVS_GPU_RESULTS"
# A wrong kernel is a failure of the stage (smoke: of the ctest), not a timing.
# (The sweep's variants may error or fall back on a device that cannot run them: a figure, not a failure.)
if grep -v '"variant"' "$DJ" | grep -q '"check": *"FAIL"\|"error":'; then
  echo "stage_bench: some dvs cases failed their check or errored (see $DJ)"
  status=1
fi
# Smoke with a torch block folder (STAGE_SMOKE_BLOCK): every dvs family's block must have been compared, and at these
# tiny shapes its error against torch's fp32 reference must be fp32-sized (below 1e-3 relative L2; torch bf16's is
# ~7e-3, so a relative goal alone would let a 1 % error pass). On the device the comparison is a figure, not a verdict.
if [ $SMOKE -eq 1 ] && [ -n "${STAGE_SMOKE_BLOCK:-}" ]; then
  "$PY" - "$DJ" <<'PYEOF' || status=1
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
blocks = [l for l in lines if l.get("source") == "dvs" and l.get("case") == "block"]
errors = {l["impl"]: l["rel_l2_vs_fp32"] for l in lines if l.get("case") == "block_error" and l["impl"].startswith("dvs_")}
bad = [f"{k} {v:.3g}" for k, v in errors.items() if not v < 1e-3]
if not blocks or len(errors) != len(blocks) or bad:
    sys.exit(f"stage_bench: {len(blocks)} dvs block cases, {len(errors)} compared with torch's fp32; over 1e-3: {bad}")
print(f"stage_bench: the dvs block agrees with torch's fp32 reference: {errors}")
PYEOF
fi
exit $status
