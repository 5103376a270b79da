#!/usr/bin/env bash
# bench/gpu/e2e.sh: stage e of bench/gpu/run.sh (which sets DVS_GPU_BIN_DIR, DVS_GPU_RESULTS, DVS_GPU_SMOKE):
# the whole pipeline, `dvs run` itself, at the real size (49 x 480 x 720) on random real-size weights made here
# by `dvs-weights make-tiny --real-size`, on a synthetic clip handed over as frame arrays (.npy: the bundle has
# no video I/O; output.mp4 then holds the output frames as an .npy). Writes one JSON line per step: model made,
# `dvs plan`'s peak, then run.json's seconds per stage, total and measured peak device memory beside the plan.
# DVS_GPU_E2E_LAYERS and DVS_GPU_E2E_T5_LAYERS (2: T5 runs once per run, its 24 layers would only cost weight
# making) size the model; DVS_GPU_E2E_STEPS (3: the paper preset's strength 0.95 samples 2) and
# DVS_GPU_E2E_INVERSION_STEPS (2). make-tiny draws the weights on every CPU core (Box-Muller; about 2e7 values per
# core-second measured here), then writes them (about 11 GB for the 42 real blocks in bf16) and dvs loads them:
# that takes a good part of a minute before anything runs. So the layer count defaults to 42 only when the stage
# has DVS_GPU_E2E_BUDGET >= 480 s (run.sh passes its timeout; e.g. DVS_GPU_STAGES=e DVS_GPU_T_E=540 for a run of
# this stage alone), else 4 blocks at the real widths and token count: the transformer stages' seconds per step
# then scale by about 42 / layers.
# Smoke (DVS_GPU_SMOKE=1): the conformance pack's tiny sizes on a 9 x 64 x 64 clip.
set -u
BIN="${DVS_GPU_BIN_DIR:?run from bench/gpu/run.sh}"
RESULTS="${DVS_GPU_RESULTS:?run from bench/gpu/run.sh}"
W="$(mktemp -d /tmp/dvs-e2e.XXXXXX)"
note() { python3 -c 'import json,sys; d={"stage":"e","case":sys.argv[1]}; d.update(json.loads(sys.argv[2])); print(json.dumps(d))' "$1" "$2" | tee -a "$RESULTS"; }
since() { python3 -c "import time,sys; print(round(time.time()-float(sys.argv[1]),2))" "$1"; }

if [ "${DVS_GPU_SMOKE:-0}" = 1 ]; then
  F=9 H=64 Wd=64 make=(--sample 8x8x9 --text-len 16) steps=2 inv=1
else
  F=49 H=480 Wd=720 steps="${DVS_GPU_E2E_STEPS:-3}" inv="${DVS_GPU_E2E_INVERSION_STEPS:-2}"
  layers=4
  [ "${DVS_GPU_E2E_BUDGET:-0}" -ge 480 ] && layers=42
  make=(--real-size --layers "${DVS_GPU_E2E_LAYERS:-$layers}" --t5-layers "${DVS_GPU_E2E_T5_LAYERS:-2}")
fi

t0=$(date +%s.%N)
"$BIN/dvs-weights" make-tiny --out "$W/model" "${make[@]}" || { note make-model '{"rc":1}'; exit 1; }
note make-model "{\"rc\":0,\"seconds\":$(since "$t0"),\"bytes\":$(du -sb "$W/model" | cut -f1),\"args\":\"${make[*]}\"}"

# The clip and its depth as .npy, written without numpy: u8 RGB [F,H,W,3] moving stripes, depth f32 [F,H,W] metres.
python3 - "$W" "$F" "$H" "$Wd" <<'PY'
import struct, sys
d, F, H, W = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
def npy(path, descr, shape, payload):
    head = "{'descr': '%s', 'fortran_order': False, 'shape': (%s), }" % (descr, ", ".join(map(str, shape)) + ("," if len(shape) == 1 else ""))
    head += " " * ((64 - (10 + len(head) + 1) % 64) % 64) + "\n"
    with open(path, "wb") as f:
        f.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(head)) + head.encode() + payload)
frames = bytearray()
for t in range(F):
    row = bytes(v for x in range(W) for v in ((x * 3 + t * 4) % 256, (x + 2 * t) % 256, 128))
    for y in range(H):
        frames += row[(y % 7) * 3:] + row[:(y % 7) * 3]
npy(d + "/clip.npy", "|u1", (F, H, W, 3), bytes(frames))
plane = struct.pack("<%df" % (H * W), *[2.0 + (x % 97) / 97.0 for y in range(H) for x in range(W)])
npy(d + "/depth.npy", "<f4", (F, H, W), plane * F)
PY

"$BIN/dvs" plan --model "$W/model" --frames "$F" --height "$H" --width "$Wd" --json > "$W/plan.json" 2> "$W/plan.err"
plan_rc=$?
note plan "$(python3 - "$W/plan.json" "$plan_rc" <<'PY'
import json, sys
try:
    p = json.load(open(sys.argv[1]))
except Exception as e:
    print(json.dumps({"rc": int(sys.argv[2]), "error": str(e)[:300]})); sys.exit()
# The whole run's peak, wherever this plan version keeps it.
def find(o):
    if isinstance(o, dict):
        for k in ("run_peak_bytes", "run_peak"):
            if isinstance(o.get(k), (int, float)): return o[k]
        for v in o.values():
            r = find(v)
            if r is not None: return r
    return None
print(json.dumps({"rc": int(sys.argv[2]), "plan_peak_bytes": find(p)}))
PY
)"

t0=$(date +%s.%N)
"$BIN/dvs" run --video "$W/clip.npy" --depth "$W/depth.npy" --metric-depth --model "$W/model" \
  --prompt "a corridor of coloured stripes" --frames "$F" --size "${H}x${Wd}" --steps "$steps" \
  --inversion-steps "$inv" --no-cache --out "$W/out" --progress json | while IFS= read -r line; do
  echo "$line"
  # Each diffusion step's progress event (elapsed_s since its stage began) as it happens: a timeout keeps them.
  ev="${line#\{}"
  case "$line" in *'"step":'[1-9]*) echo "{\"stage\":\"e\",\"case\":\"step\",${ev//\"stage\":/\"pipeline_stage\":}" >> "$RESULTS" ;; esac
done
rc=${PIPESTATUS[0]}
note run "{\"rc\":$rc,\"seconds\":$(since "$t0")}"
[ -f "$W/out/run.json" ] && note run-json "$(python3 - "$W/out/run.json" "$W/plan.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
out = {k: r.get(k) for k in ("seconds", "seconds_total", "peak_device_bytes", "peak_host_bytes", "device", "driver")}
out["steps"] = r.get("settings", {}).get("steps")
try:
    plan = json.load(open(sys.argv[2]))["run_peak_bytes"]
    out["plan_peak_bytes"] = plan
    out["peak_over_plan"] = round(r["peak_device_bytes"] / plan, 4)
except Exception:
    pass
print(json.dumps(out))
PY
)"
rm -rf "$W"
exit $rc
