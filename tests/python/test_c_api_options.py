#!/usr/bin/env python3
"""Every `dvs run` option reachable from C (dvs_pipeline_options, dvs_render_options) is APPLIED, not only parsed.

usage: test_c_api_options.py LIBDVS_SO DVS_PROGRAM MODEL_DIR VDA_CHECKPOINT [--video-lib LIBDVS_VIDEO_SO]

Inputs made here: a 13-frame 40x72 clip (.npy), its disparity at another aspect ratio and with more frames (16 of
36x72, so the runs need trim_depth and a depth_fit), a copy of the pack's tiny model without its learned positional
table (so any size of 16-pixel multiples runs), and a LoRA for it. The baseline is a 9-frame 32x48 run.

For each option, one run through the C API (dvs_job_start_pipeline, a job of its own, in this process) with that
option changed and one through the program (`dvs run` with the flag that sets it, the C++ RunOptions path): the two
sampled latents (left in each run's own latent cache) must be equal float for float, and must differ from the run
the option is compared with (the baseline, or the option it refines: preservation_scale with dynamic_cfg on,
depth_input_size with a depth model, lora_scale with a LoRA), so an option mapped to nothing or to another field
fails. Options whose effect is not a different latent are checked by what they do: trim_depth and depth_fit "error"
refuse the clip (the C message names the C field, the program's its flag), a tile size without vae_tiling changes
nothing (and vae_tiling with the default tile, larger than the frame, equals `dvs run --vae-tiling`), use_cache = 0
leaves no cache, a device that does not exist is refused by name, weights "stream" and "resident" give the baseline's
latent (where the weights live changes no byte) and run.json records them alike on both sides, and a weights value
that is none of auto, resident, stream is refused naming the field. Standard library only.
"""
import ctypes as C
import glob
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_c_api import (DVS_OK, PipelineOptions, RenderOptions, bind, check, failures, f32,  # noqa: E402
                        read_npy_f32, write_npy)

VF, VH, VW = 13, 40, 72  # the video
DF, DH, DW = 16, 36, 72  # its depth: more frames, another aspect ratio


def load(path):
    lib = C.CDLL(path)
    P = C.c_void_p
    return bind(lib, {
        "dvs_last_error": (C.c_char_p, []),
        "dvs_render_options_default": (C.c_int, [C.POINTER(RenderOptions)]),
        "dvs_pipeline_options_default": (C.c_int, [C.POINTER(PipelineOptions)]),
        "dvs_job_start_pipeline": (C.c_int, [C.POINTER(PipelineOptions), C.POINTER(P)]),
        "dvs_job_result": (C.c_int, [P]),
        "dvs_job_destroy": (C.c_int, [P]),
    })


def write_safetensors(path, tensors):
    """tensors: {name: (shape, [floats])} as F32."""
    header, blob = {}, b""
    for name, (shape, values) in tensors.items():
        data = struct.pack("<%df" % len(values), *values)
        header[name] = {"dtype": "F32", "shape": list(shape), "data_offsets": [len(blob), len(blob) + len(data)]}
        blob += data
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(text)) + text + blob)


def drop_tensor(path, name):
    """Rewrites a safetensors file without one tensor (the learned positional table a sincos config does not have)."""
    with open(path, "rb") as f:
        data = f.read()
    n = struct.unpack("<Q", data[:8])[0]
    header, body = json.loads(data[8:8 + n]), data[8 + n:]
    del header[name]
    out, blob = {}, b""
    for key, t in header.items():
        if key == "__metadata__":
            out[key] = t
            continue
        begin, end = t["data_offsets"]
        out[key] = dict(t, data_offsets=[len(blob), len(blob) + end - begin])
        blob += body[begin:end]
    text = json.dumps(out).encode()
    text += b" " * (-len(text) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(text)) + text + blob)


def make_inputs(tmp, pack_model):
    model = os.path.join(tmp, "model")
    shutil.copytree(pack_model, model)
    config = os.path.join(model, "transformer", "config.json")
    with open(config) as f:
        c = json.load(f)
    c["use_learned_positional_embeddings"] = False  # sincos positions: any size of whole patches
    with open(config, "w") as f:
        json.dump(c, f)
    drop_tensor(os.path.join(model, "transformer", "diffusion_pytorch_model.safetensors"), "patch_embed.pos_embedding")
    video, depth, lora = (os.path.join(tmp, n) for n in ("video.npy", "depth.npy", "lora.safetensors"))
    write_npy(video, "B", (VF, VH, VW, 3), [(9 * f + 5 * y + 3 * x + 70 * c + (x * y) % 11) % 256
                                            for f in range(VF) for y in range(VH) for x in range(VW) for c in range(3)])
    write_npy(depth, "f", (DF, DH, DW), [f32(0.3 + 0.6 * (x + 2 * y) / (DW + 2 * DH) + 0.2 * ((x // 12 + y // 9) % 2)
                                             + 0.01 * f) for f in range(DF) for y in range(DH) for x in range(DW)])
    r, dim, q = 2, c["num_attention_heads"] * c["attention_head_dim"], "transformer.transformer_blocks.0.attn1.to_q"
    write_safetensors(lora, {q + ".lora_A.weight": ((r, dim), [0.05 * ((i % 7) - 3) for i in range(r * dim)]),
                             q + ".lora_B.weight": ((dim, r), [0.05 * ((i % 5) - 2) for i in range(r * dim)])})
    return model, video, depth, lora


class Runs:
    def __init__(self, lib, program, tmp, model, video, depth):
        self.lib, self.program, self.tmp, self.n = lib, program, tmp, 0
        self.pipeline = {"model": model, "prompt": "a red fox", "steps": 4, "inversion_steps": 3}
        self.render = {"video": video, "depth": depth, "frames": 9, "height": 32, "width": 48, "trim_depth": 1,
                       "depth_fit": "stretch"}

    def folders(self):
        self.n += 1
        return os.path.join(self.tmp, "cache%d" % self.n), os.path.join(self.tmp, "out%d" % self.n)

    def merged(self, p, r):
        pipeline, render = dict(self.pipeline), dict(self.render)
        pipeline.update(p)
        render.update(r)
        drop = lambda d: {k: v for k, v in d.items() if v is not None}  # None: not given (depth with a depth model)
        return drop(pipeline), drop(render)

    def c_run(self, p, r):
        """(latent values or None, error or None, cache folder) of dvs_job_start_pipeline."""
        pipeline, render = self.merged(p, r)
        cache, out = self.folders()
        ro, po = RenderOptions(), PipelineOptions()
        check(self.lib.dvs_render_options_default(C.byref(ro)) == DVS_OK, "render defaults")
        check(self.lib.dvs_pipeline_options_default(C.byref(po)) == DVS_OK, "pipeline defaults")
        for struct_, values in ((po, pipeline), (ro, render)):
            for k, v in values.items():
                setattr(struct_, k, v.encode() if isinstance(v, str) else v)
        po.cache_dir, ro.out_dir = cache.encode(), out.encode()
        po.render = C.pointer(ro)
        self.last_out = out
        job = C.c_void_p()
        status = self.lib.dvs_job_start_pipeline(C.byref(po), C.byref(job))
        if status == DVS_OK:
            status = self.lib.dvs_job_result(job)
        error = self.lib.dvs_last_error().decode() if status != DVS_OK else None
        self.lib.dvs_job_destroy(job)
        return latent_in(cache) if error is None else None, error, cache

    def cli_run(self, p, r):
        pipeline, render = self.merged(p, r)
        cache, out = self.folders()
        self.last_out = out
        args = ["run", "--out", out, "--cache-dir", cache, "--progress", "none"] + flags(pipeline, render)
        res = subprocess.run([self.program] + args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        error = res.stdout if res.returncode != 0 else None
        return latent_in(cache) if error is None else None, error, cache


def flags(p, r):
    """The command line that sets what the C structs' fields set (the independent spelling of each option)."""
    a = []
    simple = {"model": "--model", "prompt": "--prompt", "negative_prompt": "--negative-prompt", "preset": "--preset",
              "steps": "--steps", "inversion_steps": "--inversion-steps", "strength": "--strength", "k": "--k",
              "delta": "--delta", "guidance": "--guidance", "seed": "--seed",
              "preservation_scale": "--preservation-scale", "weights": "--weights"}
    for k, flag in simple.items():
        if k in p:
            a += [flag, str(p[k])]
    if "lora" in p:
        a += ["--lora", p["lora"] + (":%s" % p["lora_scale"] if "lora_scale" in p else "")]
    if p.get("use_cache") == 0:
        a.append("--no-cache")
    if "dynamic_cfg" in p:
        a += ["--dynamic-cfg", "on" if p["dynamic_cfg"] == 1 else "off"]
    if p.get("vae_tiling"):
        a += ["--vae-tile", "%dx%d" % (p["vae_tile_height"], p["vae_tile_width"])] if p.get("vae_tile_height") \
            else ["--vae-tiling"]
    simple = {"video": "--video", "depth": "--depth", "depth_model": "--depth-model",
              "depth_input_size": "--depth-input-size", "trajectory": "--trajectory", "frames": "--frames",
              "depth_fit": "--depth-fit", "device": "--device"}
    for k, flag in simple.items():
        if k in r:
            a += [flag, str(r[k])]
    a += ["--size", "%dx%d" % (r["height"], r["width"])]
    for k, flag in (("metric_depth", "--metric-depth"), ("hard_points", "--points"), ("trim_depth", "--trim-depth")):
        if r.get(k):
            a.append(flag)
    if r.get("squash"):
        a += ["--resize", "squash"]
    if "fx" in r:
        a += ["--intrinsics", "%g,%g,%g,%g" % (r["fx"], r["fy"], r["cx"], r["cy"])]
    return a


def latent_in(cache):
    files = glob.glob(os.path.join(cache, "**", "latent-*.npy"), recursive=True)
    if len(files) != 1:
        return None
    return list(read_npy_f32(files[0])[1])


def largest_difference(a, b):
    return max(abs(x - y) for x, y in zip(a, b)) if a and b and len(a) == len(b) else float("inf")


def main():
    args = sys.argv[1:]
    options = dict(zip(args[4::2], args[5::2]))
    if len(args) < 4 or set(options) - {"--video-lib"}:
        sys.exit(__doc__)
    lib = load(args[0])
    if "--video-lib" in options:
        C.CDLL(options["--video-lib"], mode=C.RTLD_GLOBAL).dvs_enable_video_files()
    program, vda = args[1], args[3]
    tmp = tempfile.mkdtemp(prefix="dvs_c_api_options_")
    try:
        model, video, depth, lora = make_inputs(tmp, args[2])
        runs = Runs(lib, program, tmp, model, video, depth)
        results = {}

        def applied(name, p, r, compare_to="baseline"):
            c, c_error, _ = runs.c_run(p, r)
            cli, cli_error, _ = runs.cli_run(p, r)
            check(c_error is None and cli_error is None, "%s: C %s / dvs run %s" % (name, c_error, cli_error))
            check(c is not None and c == cli, "%s: the C run's latent differs from dvs run's (largest %g)" %
                  (name, largest_difference(c, cli)))
            if compare_to:
                d = largest_difference(c, results[compare_to])
                check(d > 1e-5, "%s: the latent equals %s's (largest difference %g): not applied" % (name, compare_to, d))
                how = "by up to %.3g" % d if d != float("inf") else "in shape"
                print("%-20s C = dvs run (%d values); differs from %s %s" % (name, len(c or []), compare_to, how))
            results[name] = c

        applied("baseline", {}, {}, None)
        # Tiles join when their strides (5/6 of the height, 4/5 of the width) are whole 8-pixel cells: 48x40 splits
        # the 48-pixel-wide frame in two; the default tile (240x360) is larger than the frame.
        tiled = {"vae_tiling": 1, "vae_tile_height": 48, "vae_tile_width": 40}
        for name, p, r, compare_to in [
                ("steps", {"steps": 5}, {}, "baseline"),
                ("inversion_steps", {"inversion_steps": 4}, {}, "baseline"),
                ("strength", {"strength": 0.5}, {}, "baseline"),
                ("k", {"k": 3.5}, {}, "baseline"),
                ("delta", {"delta": 1.5}, {}, "baseline"),
                ("guidance", {"guidance": 2.5}, {}, "baseline"),
                ("seed", {"seed": 7}, {}, "baseline"),
                ("prompt", {"prompt": "a blue bird"}, {}, "baseline"),
                ("negative_prompt", {"negative_prompt": "blurry"}, {}, "baseline"),
                ("preset", {"preset": "official"}, {}, "baseline"),
                ("dynamic_cfg", {"dynamic_cfg": 1}, {}, "baseline"),
                ("preservation_scale", {"dynamic_cfg": 1, "preservation_scale": 0.25}, {}, "dynamic_cfg"),
                ("vae_tiling", tiled, {}, "baseline"),
                ("vae_tiling, default tile", {"vae_tiling": 1}, {}, None),
                ("lora", {"lora": lora}, {}, "baseline"),
                ("lora_scale", {"lora": lora, "lora_scale": 3.0}, {}, "lora"),
                ("trajectory", {}, {"trajectory": "pan_left:10"}, "baseline"),
                ("frames", {}, {"frames": 5}, "baseline"),
                ("size", {}, {"height": 32, "width": 64}, "baseline"),
                ("squash", {}, {"squash": 1}, "baseline"),
                ("intrinsics", {}, {"fx": 40.0, "fy": 45.0, "cx": 23.0, "cy": 17.0}, "baseline"),
                ("metric_depth", {}, {"metric_depth": 1}, "baseline"),
                ("hard_points", {}, {"hard_points": 1}, "baseline"),
                ("depth_fit", {}, {"depth_fit": "crop"}, "baseline"),
                ("depth_model", {}, {"depth": None, "depth_model": vda, "depth_input_size": 28}, "baseline"),
                ("depth_input_size", {}, {"depth": None, "depth_model": vda, "depth_input_size": 42}, "depth_model")]:
            applied(name, p, r, compare_to)

        # A tile size without vae_tiling is not tiling (the program has no such spelling: --vae-tile implies it).
        c, error, _ = runs.c_run({"vae_tile_height": 48, "vae_tile_width": 40}, {})
        check(error is None and c == results["baseline"], "a tile size alone changed the run: %s" % error)
        print("vae tile, no tiling  equals the baseline")

        # weights: where the block weights live changes no byte of the result; run.json records it on both sides.
        for residency in ("stream", "resident"):
            records = []
            for run in (runs.c_run, runs.cli_run):
                latent, error, _ = run({"weights": residency}, {})
                record = error
                if error is None:
                    with open(os.path.join(runs.last_out, "run.json")) as f:
                        record = json.load(f).get("weights")
                records.append(record)
                check(error is None and latent == results["baseline"],
                      "weights %s: the latent differs from the baseline's or failed: %s" % (residency, error))
            want = {"requested": residency, "transformer": residency, "text_encoder": residency}
            check(records == [want, want], "weights %s: run.json records %s" % (residency, records))
        _, c_error, _ = runs.c_run({"weights": "sometimes"}, {})
        _, cli_error, _ = runs.cli_run({"weights": "sometimes"}, {})
        check(c_error is not None and "dvs_pipeline_options.weights must be resident, stream or auto" in c_error,
              "weights sometimes: the C run's error: %s" % c_error)
        check(cli_error is not None and "--weights must be resident, stream or auto" in cli_error,
              "weights sometimes: dvs run's error: %s" % cli_error)
        print("weights             stream and resident: the baseline's latent, recorded in run.json; others refused")

        # Options that refuse the clip when they are not given: the message names the option as each side spells it.
        for name, r, c_name, flag in [("trim_depth", {"trim_depth": 0}, "dvs_render_options.trim_depth", "--trim-depth"),
                                      ("depth_fit error", {"depth_fit": "error"}, "dvs_render_options.depth_fit",
                                       "--depth-fit"),
                                      ("device", {"device": "no-such-device"}, "no-such-device", "no-such-device")]:
            _, c_error, _ = runs.c_run({}, r)
            _, cli_error, _ = runs.cli_run({}, r)
            check(c_error is not None and c_name in c_error, "%s: the C run's error: %s" % (name, c_error))
            check(cli_error is not None and flag in cli_error, "%s: dvs run's error: %s" % (name, cli_error))
            print("%-20s refused by both, named (%s / %s)" % (name, c_name, flag))

        # use_cache = 0: neither side leaves a cache (the baseline left its latent there).
        for run in (runs.c_run, runs.cli_run):
            latent, error, cache = run({"use_cache": 0}, {})
            check(error is None and not glob.glob(os.path.join(cache, "**", "*.npy"), recursive=True),
                  "use_cache 0 left a cache or failed: %s" % error)
        print("use_cache = 0       neither run wrote a cache")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        sys.exit("%d check(s) failed" % len(failures))
    print("all option checks passed: every option of the C structs is applied as dvs run applies its flag")


if __name__ == "__main__":
    main()
