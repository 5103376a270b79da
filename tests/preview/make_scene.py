"""A small synthetic RGB-D scene for the preview test and the example's README screenshot, ray-cast exactly:
a textured back wall (z = 6), a floor two units below the camera (y = +2, OpenCV axes) and a box (side 1, centre
(0.3, 0.5, 3)) seen by the source camera with dvs render's default intrinsics (f = 500 px at 1024x576, the frame
centre-cropped: square pixels). Writes frames.npy (u8 [F,H,W,3], F copies of the frame: a clip `dvs render`
reads as its video) and depth.npy (f32 [F,H,W] disparity 1/z).
With "moving": the box comes 0.25 closer each frame (so the clip's disparity range is not one frame's), and the
frames are also written as frames.rgb (raw u8, for make_video.cpp) and the depth as depth.npz (key "depths", as
`dvs depth` writes it).

usage: make_scene.py OUT_DIR H W F [moving]"""
import math
import os
import sys
import zipfile

from npy_light import write_npy


def shade(x, y, z, which):
    if which == "wall":
        r = 0.55 + 0.35 * math.sin(2.1 * x) * math.cos(1.7 * y)
        return (r, 0.45 + 0.3 * math.cos(1.3 * x + 0.5), 0.65 + 0.25 * math.sin(2.7 * y))
    if which == "floor":
        c = 0.5 + 0.4 * math.sin(3.0 * x) * math.sin(3.0 * z)
        return (0.35 + 0.3 * c, 0.55 * c + 0.2, 0.25)
    u = 0.5 + 0.45 * math.sin(9.0 * (x + y + z))
    return (0.9 * u + 0.1, 0.3, 0.9 - 0.7 * u)


def hit_box(d, lo, hi):
    t0, t1 = 0.0, 1e9
    for a in range(3):
        if abs(d[a]) < 1e-12:
            if not lo[a] <= 0 <= hi[a]:
                return None
            continue
        ta, tb = lo[a] / d[a], hi[a] / d[a]
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
    return t0 if t0 <= t1 and t0 > 0 else None


def main():
    out, H, W, F = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    moving = sys.argv[5:] == ["moving"]
    os.makedirs(out, exist_ok=True)
    if not moving:
        rgb, disparity = render(H, W, 0.0)
        write_npy(os.path.join(out, "frames.npy"), (F, H, W, 3), rgb * F, "u1")
        write_npy(os.path.join(out, "depth.npy"), (F, H, W), disparity * F, "f4")
        return
    rgb, disparity = [], []
    for frame in range(F):
        r, d = render(H, W, -0.25 * frame)
        rgb += r
        disparity += d
    write_npy(os.path.join(out, "frames.npy"), (F, H, W, 3), rgb, "u1")
    with open(os.path.join(out, "frames.rgb"), "wb") as f:
        f.write(bytes(rgb))
    write_npy(os.path.join(out, "depth.npy"), (F, H, W), disparity, "f4")
    with zipfile.ZipFile(os.path.join(out, "depth.npz"), "w") as z:
        z.write(os.path.join(out, "depth.npy"), "depths.npy")


def render(H, W, box_shift):
    """The frame (u8 RGB, row-major) and its disparity with the box moved by box_shift along z."""
    f = 500.0 * max(W / 1024.0, H / 576.0)
    cx, cy = W / 2.0, H / 2.0
    lo, hi = (-0.2, 0.0, 2.5 + box_shift), (0.8, 1.0, 3.5 + box_shift)
    rgb, disparity = [], []
    for row in range(H):
        for col in range(W):
            d = ((col - cx) / f, (row - cy) / f, 1.0)
            best, which = 6.0 / d[2], "wall"
            if d[1] > 0 and 2.0 / d[1] < best:
                best, which = 2.0 / d[1], "floor"
            t = hit_box(d, lo, hi)
            if t is not None and t < best:
                best, which = t, "box"
            p = (d[0] * best, d[1] * best, d[2] * best)
            rgb.extend(max(0, min(255, round(255 * c))) for c in shade(*p, which))
            disparity.append(1.0 / p[2])
    return rgb, disparity


if __name__ == "__main__":
    main()
