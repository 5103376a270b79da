#!/usr/bin/env python3
"""The C API under careless use (issue 34 §2), driven from Python's ctypes.

usage: test_c_api_careless.py LIBDIR MODEL_DIR [--one-run]

LIBDIR holds libdvs.so.0 (and libdvs_video.so.0 when the video component is built): the build folder, or an installed
prefix's library folder (tests/install/run_install_test.sh). The clip is test_c_api_clip.py's (9 frames of 64x64 and
the conformance pack's tiny model). Checks: libdvs_video loads alone in a fresh process (it finds libdvs.so.0 beside
itself); two Python threads running dvs_run_pipeline_clip on one context both give the run's output (ctypes lets go
of the GIL during the calls, so they do run at once); a render on the context of a running job is refused naming
the job, while a render on a second context beside it gives the render alone; a scene outlives its context;
dvs_context_destroy under a running job cancels it; argument errors are DVS_ERROR_INVALID_ARGUMENT, a string call with a
small buffer says the size it needs, and a lost device or device memory running out in a stage of the run (injected
with DVS_FAULTS in a process of its own, --one-run: one run, its status printed) keeps its own status through the
stage's message. Standard library only.
"""
import ctypes as C
import os
import shutil
import subprocess
import sys
import tempfile
import threading

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_c_api import (DVS_ERROR_INVALID_ARGUMENT, DVS_OK, DVS_U8, PROGRESS, Intrinsics, RenderOptions,  # noqa: E402
                        SceneOptions, bind, check, failures, ok)
from test_c_api_clip import F, H, W, INVERSION_STEPS, PROMPT, STEPS, PipelineOptions, synthetic_clip  # noqa: E402

DVS_ERROR_CANCELLED, DVS_ERROR_OUT_OF_MEMORY, DVS_ERROR_DEVICE_LOST = 4, 5, 7
DVS_JOB_RUNNING, DVS_JOB_SUCCEEDED, DVS_JOB_CANCELLED = 0, 1, 3


def load(path):
    lib = C.CDLL(path)
    P = C.c_void_p
    return bind(lib, {
        "dvs_last_error": (C.c_char_p, []),
        "dvs_context_create": (C.c_int, [C.c_char_p, C.c_int32, C.POINTER(P)]),
        "dvs_context_destroy": (C.c_int, [P]),
        "dvs_context_wait": (C.c_int, [P, C.c_uint64, C.c_uint64, C.POINTER(C.c_int32)]),
        "dvs_context_requirements": (C.c_int, [C.c_int32, C.c_char_p, C.c_size_t, C.POINTER(C.c_size_t)]),
        "dvs_intrinsics_default": (C.c_int, [C.c_int32, C.c_int32, C.c_int32, C.POINTER(Intrinsics)]),
        "dvs_scene_create": (C.c_int, [P, P, C.c_int, C.c_int32, C.c_int32, P, C.POINTER(Intrinsics),
                                       C.POINTER(SceneOptions), C.POINTER(P)]),
        "dvs_scene_render": (C.c_int, [P, C.POINTER(C.c_double), P, C.c_int, P]),
        "dvs_scene_destroy": (C.c_int, [P]),
        "dvs_pipeline_options_default": (C.c_int, [C.POINTER(PipelineOptions)]),
        "dvs_render_options_default": (C.c_int, [C.POINTER(RenderOptions)]),
        "dvs_run_pipeline_clip": (C.c_int, [P, C.POINTER(PipelineOptions), P, C.c_int32, C.c_int32, C.c_int32, P, P,
                                            P, P, P, C.c_size_t, PROGRESS, P]),
        "dvs_job_start_pipeline_clip": (C.c_int, [P, C.POINTER(PipelineOptions), P, C.c_int32, C.c_int32, C.c_int32,
                                                  P, P, P, P, P, C.c_size_t, C.POINTER(P)]),
        "dvs_job_poll": (C.c_int, [P, C.POINTER(C.c_int)]),
        "dvs_job_result": (C.c_int, [P]),
        "dvs_job_destroy": (C.c_int, [P]),
    })


class Clip:
    """The clip in C memory, the options of a run on it, and what a run or a render needs."""

    def __init__(self, lib, model, cache):
        self.lib = lib
        frames, depth = synthetic_clip()
        self.frames = (C.c_uint8 * len(frames))(*frames)
        self.depth = (C.c_float * len(depth))(*depth)
        self.options = PipelineOptions()
        ok(lib, lib.dvs_pipeline_options_default(C.byref(self.options)), "dvs_pipeline_options_default")
        o = self.options
        o.model, o.prompt, o.cache_dir = model.encode(), PROMPT.encode(), cache.encode()
        o.steps, o.inversion_steps, o.use_cache = STEPS, INVERSION_STEPS, 0
        self.render_options = RenderOptions()  # kept alive beside the options that point at it
        r = self.render_options
        ok(lib, lib.dvs_render_options_default(C.byref(r)), "dvs_render_options_default")
        r.frames, r.height, r.width, r.metric_depth = 0, H, W, 1
        o.render = C.pointer(r)

    def output(self):
        return (C.c_uint8 * (F * H * W * 3))()

    def run(self, ctx, output, progress=None, frames=F, height=H, width=W, latent=None, latent_floats=0):
        return self.lib.dvs_run_pipeline_clip(ctx, C.byref(self.options), self.frames, frames, height, width,
                                              self.depth, None, output, None, latent, latent_floats,
                                              progress or PROGRESS(0), None)

    def start(self, ctx, output):
        job = C.c_void_p()
        ok(self.lib, self.lib.dvs_job_start_pipeline_clip(ctx, C.byref(self.options), self.frames, F, H, W, self.depth,
                                                          None, output, None, None, 0, C.byref(job)),
           "dvs_job_start_pipeline_clip")
        return job

    def scene(self, ctx):
        K, so, scene = Intrinsics(), SceneOptions(0, 0), C.c_void_p()
        ok(self.lib, self.lib.dvs_intrinsics_default(W, H, 0, C.byref(K)), "dvs_intrinsics_default")
        ok(self.lib, self.lib.dvs_scene_create(ctx, self.frames, DVS_U8, H, W, self.depth, C.byref(K), C.byref(so),
                                               C.byref(scene)), "dvs_scene_create")
        return scene

    def render(self, scene, i):
        """(status, RGBA bytes) of the render at pose i (two poses, alternating)."""
        pose = (C.c_double * 16)(*[1.0 if k % 5 == 0 else 0.0 for k in range(16)])
        pose[3] = 0.05 if i % 2 else -0.03
        rgba = (C.c_uint8 * (H * W * 4))()
        return self.lib.dvs_scene_render(scene, pose, rgba, DVS_U8, None), bytes(rgba)


def context(lib):
    ctx = C.c_void_p()
    ok(lib, lib.dvs_context_create(None, 0, C.byref(ctx)), "dvs_context_create")
    return ctx


def poll(lib, job):
    state = C.c_int()
    ok(lib, lib.dvs_job_poll(job, C.byref(state)), "dvs_job_poll")
    return state.value


def one_run(libdir, model):
    """--one-run: a run on a fresh context; prints its status and message."""
    lib = load(os.path.join(libdir, "libdvs.so.0"))
    tmp = tempfile.mkdtemp(prefix="dvs_c_api_one_run_")
    try:
        clip = Clip(lib, model, os.path.join(tmp, "cache"))
        status = clip.run(context(lib), clip.output())
        print(status, lib.dvs_last_error().decode())
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def status_under_fault(libdir, model, faults):
    """(status, message) of --one-run in a process of its own with DVS_FAULTS=faults."""
    env = dict(os.environ, DVS_FAULTS=faults)
    r = subprocess.run([sys.executable, os.path.abspath(__file__), libdir, model, "--one-run"], env=env,
                       capture_output=True, text=True)
    status, _, message = r.stdout.strip().partition(" ")
    return (int(status) if status.isdigit() else None), message or r.stderr.strip()


def main():
    args = sys.argv[1:]
    if len(args) == 3 and args[2] == "--one-run":
        return one_run(args[0], args[1])
    if len(args) != 2:
        sys.exit(__doc__)
    libdir, model = args
    video = os.path.join(libdir, "libdvs_video.so.0")
    if os.path.exists(video):  # §2.12: alone, in a process that loaded nothing of dvs before
        loaded = subprocess.run([sys.executable, "-c", "import ctypes, sys; ctypes.CDLL(sys.argv[1])", video],
                                capture_output=True, text=True)
        check(loaded.returncode == 0, "libdvs_video.so.0 loads alone: " + loaded.stderr.strip())
    lib = load(os.path.join(libdir, "libdvs.so.0"))
    tmp = tempfile.mkdtemp(prefix="dvs_c_api_careless_")
    try:
        clip = Clip(lib, model, os.path.join(tmp, "cache"))
        ctx = context(lib)
        alone = clip.output()
        ok(lib, clip.run(ctx, alone), "the run alone")
        scene = clip.scene(ctx)
        renders = [clip.render(scene, i)[1] for i in (0, 1)]
        ok(lib, lib.dvs_scene_destroy(scene), "dvs_scene_destroy")

        # §2.1: two threads on one context (segfaulted at once): serialised, both right.
        outputs, statuses = [clip.output(), clip.output()], [None, None]

        def run_into(i):
            statuses[i] = clip.run(ctx, outputs[i])
        threads = [threading.Thread(target=run_into, args=(i,)) for i in (0, 1)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        check(statuses == [DVS_OK, DVS_OK] and all(bytes(o) == bytes(alone) for o in outputs),
              "two threads on one context: statuses %r, outputs equal to the run alone" % statuses)

        # §2.1: a render on the context of a running job is refused naming it; a second context renders beside it.
        scene = clip.scene(ctx)
        preview = context(lib)
        preview_scene = clip.scene(preview)
        job_output = clip.output()
        job = clip.start(ctx, job_output)
        status, _ = clip.render(scene, 0)
        message = lib.dvs_last_error().decode()
        check(status == DVS_ERROR_INVALID_ARGUMENT and "pipeline job" in message and "second" in message,
              "a render on the job's context: status %d, %s" % (status, message))
        beside = [clip.render(preview_scene, i) for i in range(4)]
        still_running = poll(lib, job) == DVS_JOB_RUNNING
        check(all(s == DVS_OK and r == renders[i % 2] for i, (s, r) in enumerate(beside)),
              "renders on a second context beside the job equal the renders alone (job still running after them: %s)"
              % still_running)
        check(lib.dvs_job_result(job) == DVS_OK and bytes(job_output) == bytes(alone),
              "the job beside them: " + lib.dvs_last_error().decode())
        ok(lib, lib.dvs_job_destroy(job), "dvs_job_destroy")
        check(clip.render(scene, 1) == (DVS_OK, renders[1]), "the scene renders once the job has ended")

        # §2.2: the context destroyed first (the render aborted) and under a running job (segfaulted).
        ok(lib, lib.dvs_context_destroy(preview), "dvs_context_destroy with a scene alive")
        check(clip.render(preview_scene, 0) == (DVS_OK, renders[0]), "a scene renders after its context was destroyed")
        ok(lib, lib.dvs_scene_destroy(preview_scene), "dvs_scene_destroy after its context")
        ok(lib, lib.dvs_scene_destroy(scene), "dvs_scene_destroy")
        job = clip.start(ctx, clip.output())
        ok(lib, lib.dvs_context_destroy(ctx), "dvs_context_destroy under a running job")
        check(poll(lib, job) == DVS_JOB_CANCELLED and lib.dvs_job_result(job) == DVS_ERROR_CANCELLED,
              "destroying the context cancelled its job and waited for its end")
        ok(lib, lib.dvs_job_destroy(job), "dvs_job_destroy")

        # §2.9: statuses.
        ctx = context(lib)
        reached = C.c_int32()
        status = lib.dvs_context_wait(ctx, 1000, 0, C.byref(reached))
        check(status == DVS_ERROR_INVALID_ARGUMENT, "a wait on a ticket never submitted: status %d" % status)
        five, needed, want = C.create_string_buffer(5), C.c_size_t(), C.c_size_t()
        ok(lib, lib.dvs_context_requirements(0, None, 0, C.byref(want)), "the size query")
        status = lib.dvs_context_requirements(0, five, 5, C.byref(needed))
        check(status == DVS_ERROR_INVALID_ARGUMENT and needed.value == want.value > 5 and len(five.value) == 4,
              "5 bytes for the requirements: status %d, needed %d of %d" % (status, needed.value, want.value))
        latent = (C.c_float * 1000)()
        status = clip.run(ctx, clip.output(), frames=8, latent=latent, latent_floats=1000)
        message = lib.dvs_last_error().decode()
        check(status == DVS_ERROR_INVALID_ARGUMENT and "8 is not 4k+1" in message, "8 frames: %d %s" % (status, message))
        clip.options.preset = b"fancy"
        status = clip.run(ctx, clip.output())
        message = lib.dvs_last_error().decode()
        check(status == DVS_ERROR_INVALID_ARGUMENT and "fancy" in message, "a bad preset: %d %s" % (status, message))
        ok(lib, lib.dvs_context_destroy(ctx), "dvs_context_destroy")

        # §2.10: the kind survives the stage's message (the 3rd submission and the 12th allocation fall in the encode
        # stage of this run; a DVS_FAULTS_TRACE of it lists them).
        for faults, want, word in (("submit=3", DVS_ERROR_DEVICE_LOST, "VK_ERROR_DEVICE_LOST"),
                                   ("alloc=12", DVS_ERROR_OUT_OF_MEMORY, "Out of device memory")):
            status, message = status_under_fault(libdir, model, faults)
            check(status == want and "stage" in message and word in message,
                  "DVS_FAULTS=%s: status %r (want %d), %s" % (faults, status, want, message[:200]))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        sys.exit("%d check(s) failed" % len(failures))
    print("all careless-use C API checks passed")


if __name__ == "__main__":
    main()
