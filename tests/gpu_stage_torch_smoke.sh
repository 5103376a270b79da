#!/usr/bin/env bash
# The device stage's smoke run WITH PyTorch (ctest gpu_stage_torch_smoke, registered only where a Python with torch
# exists): torch_ref.py --quick measures its baselines at the smoke shapes (on the CPU here) and writes a tiny
# 1-layer transformer folder with torch's bf16 and fp32 outputs; stage_bench.sh --smoke runs dvs-bench on the same
# shapes and the block through the production loader (every kernel family), compare_block.py and summarize.py;
# then summarize.py joins both sides, and every case must have a torch figure and a ratio. So the torch half of
# the device stage, and the table the device run commits, are exercised here too.
# Usage: gpu_stage_torch_smoke.sh PYTHON BIN_DIR
set -eu
PY=$1 BIN=$2
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
"$PY" "$ROOT/bench/gpu/torch_ref.py" --quick --seed 0 --out "$WORK/block" --json "$WORK/torch.jsonl"
OUT=$WORK/out STAGE_SMOKE_BLOCK=$WORK/block PYTHON=$PY DVS_BIN=$BIN bash "$ROOT/bench/gpu/stage_bench.sh" --smoke
"$PY" "$ROOT/bench/gpu/summarize.py" "$WORK/torch.jsonl" "$WORK/out/dvs.jsonl" > "$WORK/summary.md"
cat "$WORK/summary.md"
# Table rows: | case | shape | dvs texel | dvs tiled | dvs default | torch | ratio | first light | tuned |
awk -F'|' '/^\| [a-z]/ && $2 !~ /case/ { rows++; if ($7 ~ /^ *$/ || $8 ~ /^ *$/) { print "no torch figure or ratio: " $0; bad++ } }
           END { if (rows < 5) { print "only " rows " cases in the table"; exit 1 } exit bad > 0 }' "$WORK/summary.md"
