#!/usr/bin/env python3
"""dvs_run_pipeline_clip (dvs/dvs.h: a whole run on a clip in memory) driven from Python's ctypes.

usage: test_c_api_clip.py LIBDVS_SO DVS_PROGRAM MODEL_DIR

A 9-frame 64x64 clip (u8 frames with a different value per pixel, channel and frame; metric depth of a tilted plane)
made here is written as frame and depth arrays (.npy) and run through the program (`dvs run` on those files, with
its latent cache in a folder of its own); the same clip in memory through dvs_run_pipeline_clip must give the
latent the program left in its cache, float for float. The same run as a job (dvs_job_start_pipeline_clip) gives
the same latent; dvs_clip_latent_shape sizes the buffer; a wrong latent_floats is DVS_ERROR_INVALID_ARGUMENT naming
it and a clip option that cannot be (render->video set) is DVS_ERROR_INVALID_ARGUMENT naming it. The prompt is longer
than the model reads: the cut is said once through the log callback, naming dvs_pipeline_options.prompt; the job's
cache folder cannot be written, which its thread logs naming dvs_pipeline_options.cache_dir. Standard library only.
"""
import ctypes as C
import os
import shutil
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_c_api import (DVS_ERROR_INVALID_ARGUMENT, LOG, PROGRESS, PipelineOptions,  # noqa: E402
                        RenderOptions, bind, check, failures, f32, ok, read_npy_f32, run_program, write_npy)

F, H, W = 9, 64, 64
# Longer than the pack's model reads (8 tokens): the cut is a warning that must reach the library user's log callback.
STEPS, INVERSION_STEPS, PROMPT = 4, 3, "a red fox jumps over the lazy brown dog in the snow at dawn"


def load(path):
    lib = C.CDLL(path)
    P = C.c_void_p
    sig = {
        "dvs_last_error": (C.c_char_p, []),
        "dvs_context_create": (C.c_int, [C.c_char_p, C.c_int32, C.POINTER(P)]),
        "dvs_context_destroy": (C.c_int, [P]),
        "dvs_pipeline_options_default": (C.c_int, [C.POINTER(PipelineOptions)]),
        "dvs_render_options_default": (C.c_int, [C.POINTER(RenderOptions)]),
        "dvs_clip_latent_shape": (C.c_int, [C.POINTER(PipelineOptions), C.c_int32, C.c_int32, C.c_int32,
                                            C.POINTER(C.c_int64)]),
        "dvs_run_pipeline_clip": (C.c_int, [P, C.POINTER(PipelineOptions), P, C.c_int32, C.c_int32, C.c_int32, P, P,
                                            P, P, P, C.c_size_t, PROGRESS, P]),
        "dvs_job_start_pipeline_clip": (C.c_int, [P, C.POINTER(PipelineOptions), P, C.c_int32, C.c_int32, C.c_int32,
                                                  P, P, P, P, P, C.c_size_t, C.POINTER(P)]),
        "dvs_job_result": (C.c_int, [P]),
        "dvs_job_destroy": (C.c_int, [P]),
        "dvs_set_log_callback": (C.c_int, [LOG, P]),
    }
    return bind(lib, sig)


def synthetic_clip():
    """u8 [F,H,W,3] frames and metric depth [F,H,W] of a tilted plane 2..3 units away."""
    frames = [(5 * f + 11 * y + 7 * x + 50 * c + (x * y) % 13) % 256
              for f in range(F) for y in range(H) for x in range(W) for c in range(3)]
    depth = [f32(2.0 + 0.5 * (x + y) / (W + H) + 0.01 * f) for f in range(F) for y in range(H) for x in range(W)]
    return frames, depth


def file_run_latent(program, model, tmp):
    """The latent `dvs run` samples from the clip as files (left in its latent cache)."""
    cache = os.path.join(tmp, "file_cache")
    run_program(program, ["run", "--video", os.path.join(tmp, "frames.npy"), "--depth", os.path.join(tmp, "depth.npy"),
                          "--metric-depth", "--model", model, "--frames", str(F), "--size", "%dx%d" % (H, W),
                          "--steps", str(STEPS), "--inversion-steps", str(INVERSION_STEPS), "--prompt", PROMPT,
                          "--cache-dir", cache, "--out", os.path.join(tmp, "file_out")])
    entries = os.path.join(cache, "inversions")  # the cache folder's entries (dvs/cache.hpp)
    latents = [n for n in os.listdir(entries) if n.startswith("latent-") and n.endswith(".npy")]
    check(len(latents) == 1, "the file run left %d latents in its cache" % len(latents))
    return read_npy_f32(os.path.join(entries, latents[0]))


def main():
    args = sys.argv[1:]
    if len(args) != 3:
        sys.exit(__doc__)
    lib = load(args[0])
    program, model = args[1], args[2]
    frames, depth = synthetic_clip()
    tmp = tempfile.mkdtemp(prefix="dvs_c_api_clip_")
    try:
        write_npy(os.path.join(tmp, "frames.npy"), "B", (F, H, W, 3), frames)
        write_npy(os.path.join(tmp, "depth.npy"), "f", (F, H, W), depth)
        shape, expected = file_run_latent(program, model, tmp)

        ctx = C.c_void_p()
        ok(lib, lib.dvs_context_create(None, 0, C.byref(ctx)), "dvs_context_create")
        o = PipelineOptions()
        ok(lib, lib.dvs_pipeline_options_default(C.byref(o)), "dvs_pipeline_options_default")
        o.model, o.prompt = model.encode(), PROMPT.encode()
        o.cache_dir = os.path.join(tmp, "clip_cache").encode()
        o.steps, o.inversion_steps = STEPS, INVERSION_STEPS
        r = RenderOptions()
        ok(lib, lib.dvs_render_options_default(C.byref(r)), "dvs_render_options_default")
        r.frames, r.height, r.width, r.metric_depth = 0, H, W, 1
        o.render = C.pointer(r)
        s = (C.c_int64 * 4)()
        ok(lib, lib.dvs_clip_latent_shape(C.byref(o), F, H, W, s), "dvs_clip_latent_shape")
        check(tuple(s) == shape, "dvs_clip_latent_shape gives %r, the file run's latent is %r" % (tuple(s), shape))
        n = s[0] * s[1] * s[2] * s[3]

        frames_c = (C.c_uint8 * len(frames))(*frames)
        depth_c = (C.c_float * len(depth))(*depth)
        output = (C.c_uint8 * (F * H * W * 3))()
        mask = (C.c_float * (F * H * W))()
        latent = (C.c_float * n)()
        stages = []

        def on_progress(stage, step, total, note, user):
            if not stages or stages[-1] != stage.decode():
                stages.append(stage.decode())
            return 0

        warnings = []
        log = LOG(lambda level, message, user: warnings.append(message.decode()))
        ok(lib, lib.dvs_set_log_callback(log, None), "dvs_set_log_callback")
        ok(lib, lib.dvs_run_pipeline_clip(ctx, C.byref(o), frames_c, F, H, W, depth_c, None, output, mask, latent, n,
                                          PROGRESS(on_progress), None), "dvs_run_pipeline_clip")
        cut = [w for w in warnings if w.startswith("dvs_pipeline_options.prompt is ")]
        check(len(cut) == 1 and "tokens but this model reads 8" in cut[0], "the prompt's cut, logged: %r" % warnings)
        differ = sum(1 for a, b in zip(latent, expected) if a != b)
        check(differ == 0, "dvs_run_pipeline_clip: %d of %d latent values differ from the file run's" % (differ, n))
        check("sample" in stages and "decode" in stages, "progress stages: %r" % stages)
        check(any(v > 0 for v in mask), "the mask shows nothing")
        print("blocking run: latent equals the file run's (%d values); stages %s" % (n, " ".join(stages)))

        # The job form, with a cache folder that cannot be written (under a file): it samples again, uncached, and
        # says so through the callback, from the job's own thread, naming the fields that fix it.
        not_a_folder = os.path.join(tmp, "a_file")
        with open(not_a_folder, "w") as f:
            f.write("x")
        o.cache_dir = os.path.join(not_a_folder, "cache").encode()
        del warnings[:]
        job = C.c_void_p()
        job_latent = (C.c_float * n)()
        ok(lib, lib.dvs_job_start_pipeline_clip(ctx, C.byref(o), frames_c, F, H, W, depth_c, None, output, None,
                                                job_latent, n, C.byref(job)), "dvs_job_start_pipeline_clip")
        ok(lib, lib.dvs_job_result(job), "dvs_job_result")
        ok(lib, lib.dvs_job_destroy(job), "dvs_job_destroy")
        ok(lib, lib.dvs_set_log_callback(LOG(), None), "dvs_set_log_callback(NULL)")
        unwritable = [w for w in warnings if w.startswith("the cache cannot be written, so this run is not cached")]
        check(len(unwritable) == 1 and "dvs_pipeline_options.cache_dir" in unwritable[0] and
              "dvs_pipeline_options.use_cache" in unwritable[0], "the unwritable cache, logged: %r" % warnings)
        check(list(job_latent) == list(expected), "the job's latent differs from the file run's")

        # Refusals: the buffer's size, and a file option the clip replaces.
        status = lib.dvs_run_pipeline_clip(ctx, C.byref(o), frames_c, F, H, W, depth_c, None, output, None, latent,
                                           n - 1, PROGRESS(0), None)
        message = lib.dvs_last_error().decode()
        check(status == DVS_ERROR_INVALID_ARGUMENT and "latent_floats" in message,
              "wrong latent_floats: status %d, %s" % (status, message))
        r.video = b"clip.mp4"
        status = lib.dvs_run_pipeline_clip(ctx, C.byref(o), frames_c, F, H, W, depth_c, None, output, None, None, 0,
                                           PROGRESS(0), None)
        message = lib.dvs_last_error().decode()
        check(status == DVS_ERROR_INVALID_ARGUMENT and "dvs_pipeline_options.render->video" in message,
              "render.video set: status %d, %s" % (status, message))
        ok(lib, lib.dvs_context_destroy(ctx), "dvs_context_destroy")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        sys.exit("%d check(s) failed" % len(failures))
    print("all clip-run C API checks passed")


if __name__ == "__main__":
    main()
