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
    """dvs_render_options (dvs/dvs.h), field for field."""
    _fields_ = [("struct_size", C.c_size_t), ("video", C.c_char_p), ("depth", C.c_char_p),
                ("depth_model", C.c_char_p), ("out_dir", C.c_char_p), ("trajectory", C.c_char_p),
                ("device", C.c_char_p), ("frames", C.c_int32), ("height", C.c_int32), ("width", C.c_int32),
                ("metric_depth", C.c_int32), ("hard_points", C.c_int32), ("depth_input_size", C.c_int32),
                ("squash", C.c_int32), ("trim_depth", C.c_int32), ("depth_fit", C.c_char_p), ("fx", C.c_double),
                ("fy", C.c_double), ("cx", C.c_double), ("cy", C.c_double), ("export_glb", C.c_int32),
                ("save_npy", C.c_int32), ("depth_cache_dir", C.c_char_p), ("depth_cache", C.c_int32)]


class PipelineOptions(C.Structure):
    """dvs_pipeline_options (dvs/dvs.h), field for field; render points at a RenderOptions."""
    _fields_ = [("struct_size", C.c_size_t), ("render", C.POINTER(RenderOptions)), ("model", C.c_char_p),
                ("prompt", C.c_char_p), ("negative_prompt", C.c_char_p), ("preset", C.c_char_p),
                ("cache_dir", C.c_char_p), ("lora", C.c_char_p), ("steps", C.c_int32), ("inversion_steps", C.c_int32),
                ("strength", C.c_double), ("k", C.c_double), ("delta", C.c_double), ("guidance", C.c_double),
                ("lora_scale", C.c_double), ("seed", C.c_uint64), ("use_cache", C.c_int32),
                ("dynamic_cfg", C.c_int32), ("preservation_scale", C.c_double), ("vae_tiling", C.c_int32),
                ("vae_tile_height", C.c_int32), ("vae_tile_width", C.c_int32), ("weights", C.c_char_p)]


class PlanRequest(C.Structure):
    """dvs_plan_request (dvs/dvs.h)."""
    _fields_ = [("struct_size", C.c_size_t), ("model", C.c_char_p), ("frames", C.c_int32), ("height", C.c_int32),
                ("width", C.c_int32), ("budget", C.c_uint64), ("alignment", C.c_uint64), ("device", C.c_char_p),
                ("limits", C.c_char_p), ("depth_model", C.c_char_p), ("depth_input_size", C.c_int32),
                ("depth_frame_height", C.c_int32), ("depth_frame_width", C.c_int32), ("weights", C.c_char_p),
                ("upload_bytes_per_second", C.c_double)]


class PlanResult(C.Structure):
    """dvs_plan_result (dvs/dvs.h)."""
    _fields_ = [("struct_size", C.c_size_t), ("checked", C.c_int32), ("runs", C.c_int32),
                ("weights_bytes", C.c_uint64), ("run_peak_bytes", C.c_uint64)]


PROGRESS = C.CFUNCTYPE(C.c_int, C.c_char_p, C.c_int32, C.c_int32, C.c_char_p, C.c_void_p)
LOG = C.CFUNCTYPE(None, C.c_int, C.c_char_p, C.c_void_p)


def text_call(lib, call, *args):
    """(status, count, text) of a C call that reports into a buffer: asked for its size first, then filled."""
    count, needed = C.c_int32(-1), C.c_size_t(0)
    status = call(*args, C.byref(count), None, 0, C.byref(needed))
    if status != DVS_OK:
        return status, count.value, lib.dvs_last_error().decode()
    buffer = C.create_string_buffer(needed.value)
    again = C.c_size_t(0)
    status = call(*args, C.byref(count), buffer, len(buffer), C.byref(again))
    check(again.value == needed.value and len(buffer.value) + 1 == needed.value,
          "the text needs %d bytes, then %d, and holds %d" % (needed.value, again.value, len(buffer.value)))
    return status, count.value, buffer.value.decode()


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
        "dvs_set_log_callback": (C.c_int, [LOG, P]),
        "dvs_trajectory_load": (C.c_int, [C.c_char_p, C.c_int32, C.c_double, C.POINTER(C.c_double), C.c_size_t]),
        "dvs_preflight_render": (C.c_int, [C.POINTER(RenderOptions), C.POINTER(C.c_int32), C.c_char_p, C.c_size_t,
                                           C.POINTER(C.c_size_t)]),
        "dvs_preflight_pipeline": (C.c_int, [C.POINTER(PipelineOptions), C.POINTER(C.c_int32), C.c_char_p,
                                             C.c_size_t, C.POINTER(C.c_size_t)]),
        "dvs_plan_request_default": (C.c_int, [C.POINTER(PlanRequest)]),
        "dvs_plan_run_memory": (C.c_int, [C.POINTER(PlanRequest), C.POINTER(PlanResult), C.c_int32, C.c_char_p,
                                          C.c_size_t, C.POINTER(C.c_size_t)]),
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
        # docs/c-api.md: the video component beside the core, enabled by its one C call.
        video = C.CDLL(options["--video-lib"], mode=C.RTLD_GLOBAL)
        video.dvs_enable_video_files.restype = C.c_int
        check(video.dvs_enable_video_files() == DVS_OK, "dvs_enable_video_files")
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
        trajectory_preflight_and_log(lib, program, radius.value, tmp, frame, disparity)
        memory_plan(lib, program)
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


def trajectory_preflight_and_log(lib, program, radius, tmp, frame, disparity):
    """Issue 34's C calls against the program: a preset's poses equal the poses.json `dvs render` writes for the
    same clip; the render's preflight finds no problem and notes the video; a path that leaves the scene in some
    frames is a warning that reaches the log callback, naming the C field and the mask file."""
    F = 9
    video, depth = os.path.join(tmp, "clip9.npy"), os.path.join(tmp, "depth9.npy")
    write_npy(video, "B", (F, H, W, 3), frame * F)
    write_npy(depth, "f", (F, H, W), disparity * F)
    out = os.path.join(tmp, "dolly")
    run_program(program, ["render", "--video", video, "--depth", depth, "--trajectory", "dolly_in:0.3", "--frames",
                          str(F), "--size", "%dx%d" % (H, W), "--no-glb", "--out", out])
    with open(os.path.join(out, "poses.json")) as f:
        expected = [v for pose in json.load(f)["poses"] for row in pose for v in row]
    poses = (C.c_double * (16 * F))()
    ok(lib, lib.dvs_trajectory_load(b"dolly_in:0.3", F, radius, poses, len(poses)), "dvs_trajectory_load")
    check(list(poses) == expected, "dolly_in:0.3 at radius %g: the poses differ from dvs render's poses.json" % radius)

    options = RenderOptions()
    ok(lib, lib.dvs_render_options_default(C.byref(options)), "dvs_render_options_default")
    options.video, options.depth, options.out_dir = video.encode(), depth.encode(), os.path.join(tmp, "pan").encode()
    options.frames, options.height, options.width, options.export_glb = F, H, W, 0
    options.trajectory = b"pan_left:180"
    status, problems, report = text_call(lib, lib.dvs_preflight_render, C.byref(options))
    check(status == DVS_OK and problems == 0, "preflight of the render: %d, %d problems: %s" % (status, problems, report))
    check("note: video %s: %d frames of %dx%d" % (video, F, H, W) in report, "preflight notes: " + report)

    messages = []
    log = LOG(lambda level, message, user: messages.append((level, message.decode())))
    ok(lib, lib.dvs_set_log_callback(log, None), "dvs_set_log_callback")
    job = C.c_void_p()
    ok(lib, lib.dvs_job_start_render(C.byref(options), C.byref(job)), "dvs_job_start_render")
    ok(lib, lib.dvs_job_result(job), "dvs_job_result")
    ok(lib, lib.dvs_job_destroy(job), "dvs_job_destroy")
    ok(lib, lib.dvs_set_log_callback(LOG(), None), "dvs_set_log_callback(NULL)")
    shown = [m for level, m in messages if level == 1 and "show nothing of the scene" in m]
    check(len(shown) == 1 and shown[0].startswith("dvs_render_options.trajectory pan_left:180: frames ") and
          "Look at mask.mp4" in shown[0], "the visibility warning through the log callback: %r" % messages)

    # A program that sets no callback: the same warning on its stderr, in the C names too.
    child = ("import ctypes as C, sys; sys.path.insert(0, %r); from test_c_api import RenderOptions, load\n"
             "lib = load(%r); o = RenderOptions(); lib.dvs_render_options_default(C.byref(o))\n"
             "o.video, o.depth, o.out_dir, o.frames, o.height, o.width, o.export_glb = %r, %r, %r, %d, %d, %d, 0\n"
             "o.trajectory = b'pan_left:180'; job = C.c_void_p()\n"
             "lib.dvs_job_start_render(C.byref(o), C.byref(job)); sys.exit(lib.dvs_job_result(job))\n") % (
        os.path.dirname(os.path.abspath(__file__)), lib._name, video.encode(), depth.encode(),
        os.path.join(tmp, "pan_child").encode(), F, H, W)
    r = subprocess.run([sys.executable, "-c", child], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    check(r.returncode == 0 and "dvs: warning: dvs_render_options.trajectory pan_left:180: frames " in r.stderr,
          "no callback: the default line on stderr (exit %d): %s" % (r.returncode, r.stderr))
    print("trajectory, preflight and log: %d poses equal dvs render's; warning: %s" % (F, shown[0][:60] if shown else "-"))


def memory_plan(lib, program):
    """dvs_plan_run_memory of the built-in model equals `dvs plan --json` of the program, and the figures agree."""
    q = PlanRequest()
    ok(lib, lib.dvs_plan_request_default(C.byref(q)), "dvs_plan_request_default")
    q.model, q.frames = b"cogvideox-5b-i2v", 13
    result = PlanResult()
    result.struct_size = C.sizeof(PlanResult)
    needed = C.c_size_t(0)
    ok(lib, lib.dvs_plan_run_memory(C.byref(q), C.byref(result), 1, None, 0, C.byref(needed)), "dvs_plan_run_memory")
    buffer = C.create_string_buffer(needed.value)
    ok(lib, lib.dvs_plan_run_memory(C.byref(q), None, 1, buffer, len(buffer), None), "dvs_plan_run_memory")
    text = buffer.value.decode()
    check(len(text) + 1 == needed.value, "the plan needs %d bytes and holds %d" % (needed.value, len(text)))
    r = subprocess.run([program, "plan", "--model", "cogvideox-5b-i2v", "--frames", "13", "--json"],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    check(r.returncode == 0 and json.loads(text) == json.loads(r.stdout), "the plan differs from dvs plan --json")
    figures = json.loads(text)
    check(result.weights_bytes > 0 and result.run_peak_bytes > result.weights_bytes and result.runs == 1,
          "plan figures: %d %d %d" % (result.weights_bytes, result.run_peak_bytes, result.runs))
    # weights and upload_bytes_per_second: the plan of `dvs plan --weights stream --upload-rate`, whose streams are
    # streamed and timed at that rate (the default plan's are resident).
    q.weights, q.upload_bytes_per_second = b"stream", 3e9
    buffer = C.create_string_buffer(1 << 16)
    ok(lib, lib.dvs_plan_run_memory(C.byref(q), None, 1, buffer, len(buffer), None), "dvs_plan_run_memory, streamed")
    r = subprocess.run([program, "plan", "--model", "cogvideox-5b-i2v", "--frames", "13", "--weights", "stream",
                        "--upload-rate", "3GB", "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    streamed = json.loads(buffer.value.decode())
    check(r.returncode == 0 and streamed == json.loads(r.stdout), "the streamed plan differs from dvs plan --json")
    tr = streamed["streams"][0]
    check(tr["streamed"] and not figures["streams"][0]["streamed"] and
          tr["call_upload_seconds"] == tr["host_bytes"] / 3e9, "streamed plan: %s" % tr)
    for field, value, text_ in (("weights", b"sometimes", "dvs_plan_request.weights must be resident, stream or auto"),
                                ("upload_bytes_per_second", -1.0, "dvs_plan_request.upload_bytes_per_second is -1")):
        bad = PlanRequest()
        ok(lib, lib.dvs_plan_request_default(C.byref(bad)), "dvs_plan_request_default")
        bad.model = b"cogvideox-5b-i2v"
        setattr(bad, field, value)
        status = lib.dvs_plan_run_memory(C.byref(bad), None, 0, None, 0, None)
        error = lib.dvs_last_error().decode()
        check(status == DVS_ERROR_INVALID_ARGUMENT and text_ in error, "%s %r: %d %s" % (field, value, status, error))
    print("memory plan: equals dvs plan --json (%d keys), weights %.2f GiB; streamed at 3 GB/s: %.2f s a call" %
          (len(figures), result.weights_bytes / 2**30, tr["call_upload_seconds"]))


if __name__ == "__main__":
    main()
