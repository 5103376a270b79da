#!/usr/bin/env python3
"""The dvs C API (dvs/dvs.h) driven from Python's ctypes, as an application in another language would use it.

usage: test_c_api.py LIBDVS_SO DVS_PROGRAM [--vda VDA_CHECKPOINT] [--video-lib LIBDVS_VIDEO_SO]

A synthetic frame and disparity made here are built into a point-cloud scene and rendered at two poses:
  (a) at the identity pose every visible pixel equals the frame's f32 conversion, computed here (u8 / 127.5 - 1);
  (b) at another pose the mask equals mask.npy of `dvs render` (DVS_PROGRAM) run on the same frame and depth written
      as .npy files here, with a one-pose JSON trajectory: an independent path through the program.
A render job on the same inputs is polled to completion and its mask.npy equals the program's. Errors: a bad size
is DVS_ERROR_INVALID_ARGUMENT with dvs_last_error() naming the argument, a missing file is DVS_ERROR_FILE naming it.
--video-lib loads dvs's video component beside the core (it registers itself when loaded), which the render job
needs to write its .mp4 files. With --vda VDA_CHECKPOINT (the conformance pack's tiny Video-Depth-Anything), frames made here are estimated through
dvs_depth_estimator_estimate with a progress callback and compared bit for bit with `dvs depth` of the same frames
written as an .npy; a callback returning nonzero cancels (DVS_ERROR_CANCELLED) and the estimator stays usable.
Standard library only (ctypes, struct, array): numpy is not required.
"""
import array
import ast
import ctypes as C
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time

DVS_OK, DVS_ERROR_INVALID_ARGUMENT, DVS_ERROR_FILE = 0, 1, 2
DVS_F32, DVS_U8 = 0, 1
DVS_JOB_RUNNING, DVS_JOB_SUCCEEDED = 0, 1
H, W = 24, 40  # small and not square

failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL:", what)


class Intrinsics(C.Structure):
    _fields_ = [("fx", C.c_double), ("fy", C.c_double), ("cx", C.c_double), ("cy", C.c_double),
                ("width", C.c_int32), ("height", C.c_int32)]


class SceneOptions(C.Structure):
    _fields_ = [("depth_is_disparity", C.c_int32), ("hard_points", C.c_int32)]


class RenderOptions(C.Structure):
    _fields_ = [("video", C.c_char_p), ("depth", C.c_char_p), ("depth_model", C.c_char_p), ("out_dir", C.c_char_p),
                ("trajectory", C.c_char_p), ("device", C.c_char_p), ("frames", C.c_int32), ("height", C.c_int32),
                ("width", C.c_int32), ("metric_depth", C.c_int32), ("hard_points", C.c_int32),
                ("depth_input_size", C.c_int32)]


PROGRESS = C.CFUNCTYPE(C.c_int, C.c_char_p, C.c_int32, C.c_int32, C.c_char_p, C.c_void_p)


def bind(lib, sig):
    """Gives each function named in sig ({name: (restype, argtypes)}) its C signature; returns lib."""
    for name, (res, args) in sig.items():
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    return lib


def load(path):
    lib = C.CDLL(path)
    P = C.c_void_p
    sig = {
        "dvs_version": (C.c_char_p, []),
        "dvs_last_error": (C.c_char_p, []),
        "dvs_context_create": (C.c_int, [C.c_char_p, C.c_int32, C.POINTER(P)]),
        "dvs_context_destroy": (C.c_int, [P]),
        "dvs_context_device_name": (C.c_int, [P, C.c_char_p, C.c_size_t, C.POINTER(C.c_size_t)]),
        "dvs_intrinsics_default": (C.c_int, [C.c_int32, C.c_int32, C.c_int32, C.POINTER(Intrinsics)]),
        "dvs_scene_create": (C.c_int, [P, P, C.c_int, C.c_int32, C.c_int32, P, C.POINTER(Intrinsics),
                                       C.POINTER(SceneOptions), C.POINTER(P)]),
        "dvs_scene_render": (C.c_int, [P, C.POINTER(C.c_double), P, C.c_int, P]),
        "dvs_scene_orbit_radius": (C.c_int, [P, C.POINTER(C.c_double)]),
        "dvs_scene_destroy": (C.c_int, [P]),
        "dvs_depth_estimator_create": (C.c_int, [P, C.c_char_p, C.c_int32, C.c_int32, C.POINTER(P)]),
        "dvs_depth_estimator_estimate": (C.c_int, [P, P, C.c_int32, C.c_int32, C.c_int32, P, PROGRESS, P]),
        "dvs_depth_estimator_destroy": (C.c_int, [P]),
        "dvs_render_options_default": (C.c_int, [C.POINTER(RenderOptions)]),
        "dvs_job_start_render": (C.c_int, [C.POINTER(RenderOptions), C.POINTER(P)]),
        "dvs_job_poll": (C.c_int, [P, C.POINTER(C.c_int)]),
        "dvs_job_progress": (C.c_int, [P, C.c_char_p, C.c_size_t, C.POINTER(C.c_size_t), C.POINTER(C.c_int32),
                                       C.POINTER(C.c_int32)]),
        "dvs_job_error": (C.c_int, [P, C.c_char_p, C.c_size_t, C.POINTER(C.c_size_t)]),
        "dvs_job_result": (C.c_int, [P]),
        "dvs_job_destroy": (C.c_int, [P]),
    }
    return bind(lib, sig)


def ok(lib, status, call):
    if status != DVS_OK:
        raise RuntimeError("%s failed with status %d: %s" % (call, status, lib.dvs_last_error().decode()))


def f32(x):
    """x rounded to float32, as C's float arithmetic rounds each result."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def write_npy(path, typecode, shape, values):
    descr = {"B": "|u1", "f": "<f4"}[typecode]
    header = "{'descr': '%s', 'fortran_order': False, 'shape': (%s), }" % (descr, "".join("%d, " % d for d in shape))
    header += " " * (63 - (10 + len(header)) % 64) + "\n"
    with open(path, "wb") as out:
        out.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode("latin1"))
        out.write(array.array(typecode, values).tobytes())


def read_npy_f32(path):
    """(shape, values) of a little-endian float32 .npy, C order (what dvs writes)."""
    with open(path, "rb") as f:
        data = f.read()
    assert data[:6] == b"\x93NUMPY", path + ": not an .npy file"
    major = data[6]
    size_len = 2 if major == 1 else 4
    header_len = struct.unpack("<H" if major == 1 else "<I", data[8:8 + size_len])[0]
    start = 8 + size_len
    header = ast.literal_eval(data[start:start + header_len].decode("latin1"))
    assert header["descr"] == "<f4" and not header["fortran_order"], "%s: %r" % (path, header)
    values = array.array("f")
    values.frombytes(data[start + header_len:])
    return tuple(header["shape"]), values


def synthetic_inputs():
    """u8 [H,W,3] RGB with a different value per pixel and channel; disparity [H,W] of a tilted plane, in (0.4, 1)."""
    frame = [(7 * y + 3 * x + 60 * c) % 256 for y in range(H) for x in range(W) for c in range(3)]
    disparity = [f32(0.4 + 0.5 * (x + 2 * y) / (W + 2 * H)) for y in range(H) for x in range(W)]
    return frame, disparity


def pose_matrix():
    """A rigid world-to-camera transform: a small rotation about y and a shift to the right and back."""
    import math
    a = math.radians(3.0)
    return [math.cos(a), 0.0, math.sin(a), -0.05,
            0.0, 1.0, 0.0, 0.02,
            -math.sin(a), 0.0, math.cos(a), 0.1,
            0.0, 0.0, 0.0, 1.0]


def render(lib, scene, pose):
    image = (C.c_float * (3 * H * W))()
    mask = (C.c_float * (H * W))()
    ok(lib, lib.dvs_scene_render(scene, (C.c_double * 16)(*pose), image, DVS_F32, mask), "dvs_scene_render")
    return image, mask


def run_program(program, args):
    r = subprocess.run([program] + args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        raise RuntimeError("%s %s exited with %d:\n%s" % (program, " ".join(args), r.returncode, r.stdout))


def main():
    args = sys.argv[1:]
    options = dict(zip(args[2::2], args[3::2]))
    if len(args) < 2 or len(args) % 2 or set(options) - {"--vda", "--video-lib"}:
        sys.exit(__doc__)
    lib = load(args[0])
    program = args[1]
    if "--video-lib" in options:
        C.CDLL(options["--video-lib"], mode=C.RTLD_GLOBAL)
    print("dvs", lib.dvs_version().decode())
    frame, disparity = synthetic_inputs()
    identity = [1.0 if i % 5 == 0 else 0.0 for i in range(16)]
    pose = pose_matrix()

    ctx = C.c_void_p()
    ok(lib, lib.dvs_context_create(None, 0, C.byref(ctx)), "dvs_context_create")
    name = C.create_string_buffer(256)
    ok(lib, lib.dvs_context_device_name(ctx, name, len(name), None), "dvs_context_device_name")
    print("device:", name.value.decode())

    K = Intrinsics()
    ok(lib, lib.dvs_intrinsics_default(W, H, 0, C.byref(K)), "dvs_intrinsics_default")
    frame_c = (C.c_uint8 * len(frame))(*frame)
    depth_c = (C.c_float * len(disparity))(*disparity)
    scene = C.c_void_p()
    ok(lib, lib.dvs_scene_create(ctx, frame_c, DVS_U8, H, W, depth_c, C.byref(K), None, C.byref(scene)),
       "dvs_scene_create")
    radius = C.c_double()
    ok(lib, lib.dvs_scene_orbit_radius(scene, C.byref(radius)), "dvs_scene_orbit_radius")
    check(0 < radius.value <= 5, "orbit radius %g outside (0, 5]" % radius.value)

    # (a) identity: each point lands back on its own pixel (up to the float32 rounding of unprojecting and projecting
    # it, a small fraction of a pixel), so every visible pixel is the frame's value: within 1e-3 (an eighth of one
    # 8-bit step) of u8 / 127.5 - 1, and exactly the input byte when quantised back to 8 bits.
    image, mask = render(lib, scene, identity)
    visible = sum(1 for v in mask if v > 0)
    check(visible > H * W * 9 // 10, "identity pose: only %d of %d pixels visible" % (visible, H * W))
    worst, wrong_bytes = 0.0, 0
    for y in range(H):
        for x in range(W):
            if mask[y * W + x] <= 0:
                continue
            for c in range(3):
                byte = frame[(y * W + x) * 3 + c]
                got = image[(c * H + y) * W + x]
                worst = max(worst, abs(got - f32(f32(byte / 127.5) - 1.0)))
                wrong_bytes += int(round((got + 1.0) * 127.5)) != byte
    check(worst <= 1e-3, "identity pose: visible pixels differ from the frame by up to %g" % worst)
    check(wrong_bytes == 0, "identity pose: %d values do not quantise back to the input byte" % wrong_bytes)
    print("identity pose: %d visible pixels, largest difference from the frame %.3g" % (visible, worst))

    # The same render as RGBA8 (the display path): the input bytes where visible, alpha 255 there and 0 elsewhere.
    rgba = (C.c_uint8 * (H * W * 4))()
    ok(lib, lib.dvs_scene_render(scene, (C.c_double * 16)(*identity), rgba, DVS_U8, None), "dvs_scene_render RGBA8")
    wrong = sum(1 for i in range(H * W)
                if rgba[4 * i + 3] != (255 if mask[i] > 0 else 0)
                or (mask[i] > 0 and list(rgba[4 * i:4 * i + 3]) != frame[3 * i:3 * i + 3]))
    check(wrong == 0, "identity pose, RGBA8: %d pixels are not the input bytes with the mask as alpha" % wrong)

    # (b) another pose: the program's mask of the same frame, depth and pose.
    _, moved_mask = render(lib, scene, pose)
    moved_visible = sum(1 for v in moved_mask if v > 0)
    check(0 < moved_visible < H * W, "moved pose: %d visible pixels (want some, not all)" % moved_visible)
    tmp = tempfile.mkdtemp(prefix="dvs_c_api_")
    try:
        compare_with_program_and_jobs(lib, program, ctx, scene, frame_c, depth_c, K, tmp, frame, disparity, pose,
                                      moved_mask)
        if "--vda" in options:
            depth_of_frames(lib, program, ctx, options["--vda"], tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    ok(lib, lib.dvs_scene_destroy(scene), "dvs_scene_destroy")
    ok(lib, lib.dvs_context_destroy(ctx), "dvs_context_destroy")
    if failures:
        sys.exit("%d check(s) failed" % len(failures))
    print("all C API checks passed (%d visible pixels at the identity, %d at the moved pose)" % (visible, moved_visible))


def depth_of_frames(lib, program, ctx, checkpoint, tmp):
    F, h, w, input_size = 3, 30, 44, 28
    frames = [(5 * f + 11 * y + 7 * x + 50 * c + (x * y) % 13) % 256
              for f in range(F) for y in range(h) for x in range(w) for c in range(3)]
    video, expected_file = os.path.join(tmp, "frames.npy"), os.path.join(tmp, "depth_program.npy")
    write_npy(video, "B", (F, h, w, 3), frames)
    run_program(program, ["depth", "--video", video, "--depth-model", checkpoint, "--input-size", str(input_size),
                          "--cache-dir", os.path.join(tmp, "cache"), "--quiet", "--out", expected_file])
    shape, expected = read_npy_f32(expected_file)
    check(shape == (F, h, w), "dvs depth wrote shape %s" % (shape,))

    estimator = C.c_void_p()
    ok(lib, lib.dvs_depth_estimator_create(ctx, checkpoint.encode(), input_size, -1, C.byref(estimator)),
       "dvs_depth_estimator_create")
    frames_c = (C.c_uint8 * len(frames))(*frames)
    out = (C.c_float * (F * h * w))()
    events = []

    def record(stage, step, total, note, user):
        events.append((stage.decode(), step, total))
        return 0

    callback = PROGRESS(record)
    ok(lib, lib.dvs_depth_estimator_estimate(estimator, frames_c, F, h, w, out, callback, None),
       "dvs_depth_estimator_estimate")
    check(list(out) == list(expected), "depth of frames: differs from dvs depth at %d of %d values" %
          (sum(1 for a, b in zip(out, expected) if a != b), len(expected)))
    check(len(events) > 1 and all(e[0] == "depth" for e in events) and events[-1][1] == events[-1][2],
          "depth progress events: %r" % events[:3])

    def cancel_at_second_step(stage, step, total, note, user):
        return 1 if step >= 2 else 0

    cancel = PROGRESS(cancel_at_second_step)
    status = lib.dvs_depth_estimator_estimate(estimator, frames_c, F, h, w, out, cancel, None)
    check(status == 4, "cancelled estimate: status %d (%s)" % (status, lib.dvs_last_error().decode()))
    status = lib.dvs_depth_estimator_estimate(estimator, frames_c, 0, h, w, out, PROGRESS(), None)
    message = lib.dvs_last_error().decode()
    check(status == DVS_ERROR_INVALID_ARGUMENT and "count" in message, "0 frames: %d %s" % (status, message))
    again = (C.c_float * (F * h * w))()
    ok(lib, lib.dvs_depth_estimator_estimate(estimator, frames_c, F, h, w, again, PROGRESS(), None),
       "dvs_depth_estimator_estimate after a cancellation")
    check(list(again) == list(expected), "depth of frames after a cancellation differs")
    ok(lib, lib.dvs_depth_estimator_destroy(estimator), "dvs_depth_estimator_destroy")
    print("depth of frames: %d progress events, equal to dvs depth" % len(events))


def compare_with_program_and_jobs(lib, program, ctx, scene, frame_c, depth_c, K, tmp, frame, disparity, pose,
                                  moved_mask):
    video, depth, trajectory = (os.path.join(tmp, n) for n in ("frame.npy", "depth.npy", "pose.json"))
    write_npy(video, "B", (1, H, W, 3), frame)
    write_npy(depth, "f", (1, H, W), disparity)
    with open(trajectory, "w") as f:
        json.dump({"convention": "world_to_camera", "axes": "opencv", "poses": [pose]}, f)
    out = os.path.join(tmp, "program")
    run_program(program, ["render", "--video", video, "--depth", depth, "--trajectory", trajectory, "--frames", "1",
                          "--size", "%dx%d" % (H, W), "--no-glb", "--out", out])
    shape, expected = read_npy_f32(os.path.join(out, "mask.npy"))
    check(shape == (1, H, W), "dvs render's mask.npy has shape %s" % (shape,))
    check(list(moved_mask) == list(expected),
          "moved pose: the mask differs from dvs render's at %d pixels" %
          sum(1 for a, b in zip(moved_mask, expected) if a != b))

    # Errors: a bad size names the argument; a missing file names the file.
    bad = C.c_void_p()
    status = lib.dvs_scene_create(ctx, frame_c, DVS_U8, 0, W, depth_c, C.byref(K), None, C.byref(bad))
    message = lib.dvs_last_error().decode()
    check(status == DVS_ERROR_INVALID_ARGUMENT, "height 0: status %d" % status)
    check("height" in message, "height 0: the message does not name it: " + message)
    check(not bad.value, "height 0: a scene was returned")
    estimator = C.c_void_p()
    status = lib.dvs_depth_estimator_create(ctx, os.path.join(tmp, "none.pth").encode(), 0, -1, C.byref(estimator))
    message = lib.dvs_last_error().decode()
    check(status == DVS_ERROR_FILE, "missing depth model: status %d" % status)
    check("none.pth" in message, "missing depth model: the message does not name the file: " + message)

    # A render job on the same inputs, polled to completion as a render loop would.
    options = RenderOptions()
    ok(lib, lib.dvs_render_options_default(C.byref(options)), "dvs_render_options_default")
    check(options.frames == 49 and options.trajectory == b"loop1", "render defaults: %d, %r" %
          (options.frames, options.trajectory))
    job_out = os.path.join(tmp, "job")
    options.video, options.depth, options.trajectory = video.encode(), depth.encode(), trajectory.encode()
    options.out_dir, options.frames, options.height, options.width = job_out.encode(), 1, H, W
    job = C.c_void_p()
    ok(lib, lib.dvs_job_start_render(C.byref(options), C.byref(job)), "dvs_job_start_render")
    state, polls, stage = C.c_int(DVS_JOB_RUNNING), 0, C.create_string_buffer(64)
    deadline = time.monotonic() + 300
    while state.value == DVS_JOB_RUNNING and time.monotonic() < deadline:
        ok(lib, lib.dvs_job_poll(job, C.byref(state)), "dvs_job_poll")
        ok(lib, lib.dvs_job_progress(job, stage, len(stage), None, None, None), "dvs_job_progress")
        polls += 1
        time.sleep(0.01)
    error = C.create_string_buffer(1024)
    ok(lib, lib.dvs_job_error(job, error, len(error), None), "dvs_job_error")
    check(state.value == DVS_JOB_SUCCEEDED, "render job: state %d after %d polls: %s" %
          (state.value, polls, error.value.decode()))
    check(lib.dvs_job_result(job) == DVS_OK, "render job: result " + lib.dvs_last_error().decode())
    check(stage.value == b"render", "render job: last progress stage %r" % stage.value)
    _, job_mask = read_npy_f32(os.path.join(job_out, "mask.npy"))
    check(list(job_mask) == list(expected), "render job: mask.npy differs from dvs render's")
    ok(lib, lib.dvs_job_destroy(job), "dvs_job_destroy")

    # A failing job: the status and message of its work.
    options.video = os.path.join(tmp, "missing.npy").encode()
    ok(lib, lib.dvs_job_start_render(C.byref(options), C.byref(job)), "dvs_job_start_render")
    status = lib.dvs_job_result(job)
    message = lib.dvs_last_error().decode()
    check(status == DVS_ERROR_FILE, "failing job: status %d" % status)
    check("missing.npy" in message, "failing job: the message does not name the file: " + message)
    ok(lib, lib.dvs_job_destroy(job), "dvs_job_destroy")
    print("render job: %d polls" % polls)


if __name__ == "__main__":
    main()
