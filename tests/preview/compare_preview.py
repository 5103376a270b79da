"""Checks of the preview test (run_preview_test.sh), python3 without numpy.

  compare_preview.py panel SHOT.npy RENDER.npy MASK.npy FRAME
      the preview's render panel (u8 [H,W,4] RGBA) against `dvs render --save-npy`'s frame FRAME (f32 [F,3,H,W] in
      [-1,1]) quantised to 8 bits as dvs writes video, round((v+1)*127.5): every channel within 1 level (the
      scene may round on the device); alpha 255 exactly where mask.npy (f32 [F,H,W]) is > 0, and black (0)
      holes elsewhere (dvs/scene.hpp).
  compare_preview.py poses PREVIEW_LOG POSES.json TOLERANCE
      the poses the preview printed ("path frame I = key pose K: 16 numbers") against a trajectory JSON
      (dvs render's poses.json or the exported file): equal (TOLERANCE 0) or within TOLERANCE."""
import json
import math
import re
import sys

from npy_light import read_npy


def panel(shot_path, render_path, mask_path, frame):
    (h, w, four), shot = read_npy(shot_path)
    (f, three, rh, rw), render = read_npy(render_path)
    (mf, mh, mw), mask = read_npy(mask_path)
    if (four, three, rh, rw, mh, mw) != (4, 3, h, w, h, w) or frame >= f or mf != f:
        raise SystemExit(f"shapes differ: screenshot {h}x{w}x{four}, render {f}x{three}x{rh}x{rw}, mask {mf}x{mh}x{mw}")
    plane = h * w
    worst, over, mask_wrong, visible, exact = 0, 0, 0, 0, 0
    for i in range(plane):
        seen = mask[frame * plane + i] > 0
        for c in range(3):
            v = render[(frame * 3 + c) * plane + i]
            want = min(255, max(0, math.floor((v + 1.0) * 127.5 + 0.5))) if seen else 0
            d = abs(shot[i * 4 + c] - want)
            worst = max(worst, d)
            over += d > 1
            exact += d == 0
        visible += seen
        mask_wrong += (shot[i * 4 + 3] == 255) != seen
    print(f"panel vs dvs render frame {frame}: {visible} of {plane} pixels visible, largest difference {worst} "
          f"level(s), {exact} of {3 * plane} channel values equal, {over} off by more than 1, {mask_wrong} mask pixels "
          "differ")
    if visible < plane // 10:
        raise SystemExit("the pose shows almost nothing of the scene: the comparison would prove little")
    if over or mask_wrong:
        raise SystemExit("the preview's render panel differs from dvs render's frame")


def poses(log_path, json_path, tolerance):
    printed = {}
    with open(log_path) as f:
        for line in f:
            m = re.match(r"dvs-preview: path frame (\d+) = key pose \d+: (.*)$", line.strip())
            if m:
                printed[int(m.group(1))] = [float(x) for x in m.group(2).split()]
    with open(json_path) as f:
        doc = json.load(f)
    if doc.get("convention") != "world_to_camera" or doc.get("axes", "opencv") != "opencv":
        raise SystemExit(f"{json_path}: not world_to_camera / opencv")
    if not printed:
        raise SystemExit(f"{log_path}: the preview printed no path poses")
    worst = 0.0
    for frame, want in sorted(printed.items()):
        got = [v for row in doc["poses"][frame] for v in row]
        worst = max(worst, max(abs(a - b) for a, b in zip(got, want)))
        if tolerance == 0 and got != want:
            raise SystemExit(f"{json_path}: frame {frame} is {got}, the preview printed {want}")
    print(f"{json_path}: {len(printed)} key frames of {len(doc['poses'])} poses, largest difference {worst:.3g}")
    if worst > tolerance:
        raise SystemExit(f"{json_path}: poses differ from the preview's by {worst} > {tolerance}")


if __name__ == "__main__":
    if len(sys.argv) == 6 and sys.argv[1] == "panel":
        panel(sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5]))
    elif len(sys.argv) == 5 and sys.argv[1] == "poses":
        poses(sys.argv[2], sys.argv[3], float(sys.argv[4]))
    else:
        raise SystemExit(__doc__)
