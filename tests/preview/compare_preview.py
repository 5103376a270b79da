"""Checks of the preview test (run_preview_test.sh), python3 without numpy.

  compare_preview.py panel SHOT.npy RENDER.npy MASK.npy FRAME
      the preview's render panel (u8 [H,W,4] RGBA) against `dvs render --save-npy`'s frame FRAME (f32 [F,3,H,W] in
      [-1,1]) quantised to 8 bits as dvs writes video, round((v+1)*127.5): every channel within 1 level (the
      scene may round on the device); alpha 255 exactly where mask.npy (f32 [F,H,W]) is > 0, and black (0)
      holes elsewhere (dvs/scene.hpp).
  compare_preview.py poses PREVIEW_LOG POSES.json TOLERANCE
      the poses the preview printed ("path frame I = key pose K: 16 numbers") against a trajectory JSON
      (dvs render's poses.json or the exported file): equal (TOLERANCE 0) or within TOLERANCE.
  compare_preview.py travel PREVIEW_LOG FRAMES FPS
      the preview held W for FRAMES frames under --max-fps FPS, then placed key pose 1 (printed "key pose 1: 16
      numbers", a world-to-camera T): its distance |t| from the input view, in orbit radii (printed "orbit radius
      R"), is 0.6 a second of the frames' wall time: at least 0.6·FRAMES/FPS (a frame lasts at least 1/FPS), and
      within 40% of 0.6·FRAMES/rate, the rate the run printed (frames shown a second); per displayed frame it would
      be 0.01·FRAMES whatever the rate.
  compare_preview.py rate PREVIEW_LOG MAX
      the frames shown a second (printed "... frames/s shown") are at most MAX."""
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


def travel(log_path, frames, fps):
    radius, pose, shown = None, None, None
    with open(log_path) as f:
        for line in f:
            m = re.search(r"orbit radius ([0-9.eE+-]+)", line)
            if m:
                radius = float(m.group(1))
            m = re.match(r"dvs-preview: key pose 1: (.*)$", line.strip())
            if m:
                pose = [float(x) for x in m.group(1).split()]
            m = re.search(r"([0-9.]+) frames/s shown", line)
            if m:
                shown = float(m.group(1))
    if radius is None or pose is None or len(pose) != 16 or shown is None:
        raise SystemExit(f"{log_path}: no orbit radius, key pose 1 or frame rate printed")
    radii = math.sqrt(pose[3] ** 2 + pose[7] ** 2 + pose[11] ** 2) / radius
    least, expected = 0.6 * frames / fps, 0.6 * frames / shown
    print(f"W held {frames} frames at --max-fps {fps} ({shown} frames/s shown): {radii:.4f} orbit radii "
          f"(at least {least:.4f}, expected {expected:.4f}; per frame it would be {0.01 * frames:.4f})")
    if radii < least * 0.98 or abs(radii - expected) > 0.4 * expected:
        raise SystemExit(f"{log_path}: the camera did not move 0.6 orbit radii a second of wall time")


def rate(log_path, most):
    with open(log_path) as f:
        m = re.search(r"([0-9.]+) frames/s shown", f.read())
    if not m:
        raise SystemExit(f"{log_path}: the preview printed no frame rate")
    print(f"{float(m.group(1))} frames/s shown (at most {most})")
    if float(m.group(1)) > most:
        raise SystemExit(f"{log_path}: {m.group(1)} frames/s shown, more than {most}: presents are not throttled")


if __name__ == "__main__":
    if len(sys.argv) == 6 and sys.argv[1] == "panel":
        panel(sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5]))
    elif len(sys.argv) == 5 and sys.argv[1] == "poses":
        poses(sys.argv[2], sys.argv[3], float(sys.argv[4]))
    elif len(sys.argv) == 5 and sys.argv[1] == "travel":
        travel(sys.argv[2], int(sys.argv[3]), float(sys.argv[4]))
    elif len(sys.argv) == 4 and sys.argv[1] == "rate":
        rate(sys.argv[2], float(sys.argv[3]))
    else:
        raise SystemExit(__doc__)
