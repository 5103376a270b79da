#!/usr/bin/env bash
# The device stage's smoke run WITH PyTorch (ctest gpu_stage_torch_smoke, registered only where a Python with torch
# exists): torch_ref.py --quick writes a tiny 1-layer transformer folder with torch's bf16 and fp32 outputs, then
# stage_bench.sh --smoke runs dvs-bench's block case on it through the production loader (every kernel family),
# compare_block.py and summarize.py, so the torch half of the device stage is exercised here too.
# Usage: gpu_stage_torch_smoke.sh PYTHON BIN_DIR
set -eu
PY=$1 BIN=$2
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
"$PY" "$ROOT/bench/gpu/torch_ref.py" --quick --no-baselines --seed 0 --out "$WORK/block" --json "$WORK/torch.jsonl"
OUT=$WORK/out STAGE_SMOKE_BLOCK=$WORK/block PYTHON=$PY DVS_BIN=$BIN bash "$ROOT/bench/gpu/stage_bench.sh" --smoke
