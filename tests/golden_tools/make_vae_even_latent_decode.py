#!/usr/bin/python3
"""Adds the case `vae_decode_even_latent` to a CogVideoX conformance pack (tests/golden/A format).

The decode of an EVEN number of latent frames, computed by diffusers' own AutoencoderKLCogVideoX
(autoencoder_kl_cogvideox.py, upsampling.py, activations.py of the given diffusers source tree) on the pack's
VAE weights, float32 on the CPU, exactly as the pack's `vae_decode` case was made: vae.decode(scaled / scaling).

Why: with an even latent count every decode batch is even, so diffusers' time upsampling doubles latent frame
0 like the others and 4*Fl frames come out for a 4*Fl - 3 frame video. dvs keeps the last 4*Fl - 3. The test
tests/golden_vae.cpp (VaeGolden.EvenLatentCountDecode) checks dvs's whole decode and the frames it keeps
against this golden, so the choice is proven by the library's output, not argued.

Not run by the build or the tests (they read the files it wrote). To remake the files:
    git -C <diffusers clone> archive 58eb52c0803ea9af3abec60841c2a093bdf1f951 src/diffusers | tar -x -C /tmp/d
    /usr/bin/python3 tests/golden_tools/make_vae_even_latent_decode.py --diffusers /tmp/d/src --pack tests/golden/A
Needs numpy and torch (Debian python3-torch 1.13 is what made the committed files). Only modules without model
math are stubbed (config registration, logging, the model base class, output containers, imports the VAE
never calls); every layer the decode runs is diffusers' own code. The stubs are listed in the case's "shims".
"""
import argparse
import importlib
import json
import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "bench", "gpu"))
from torch_ref import st_read  # noqa: E402  (the project's safetensors reader: the package may be absent)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import library_stubs  # noqa: E402  (diffusers' model modules from the source tree, non-math modules stubbed)
import torch_bf16  # noqa: E402  (the pack's cases.json writer)

CASE = "vae_decode_even_latent"
# (name, latent frames, latent height, latent width, seed): two decode batches [0:2],[2:4]; one batch of 2.
LATENTS = [("even4", 4, 3, 5, 4), ("even2", 2, 4, 3, 2)]

SHIMS = library_stubs.TORCH_SHIMS + library_stubs.DIFFUSERS_SHIMS


def stats(a):
    return {
        "min": float(a.min()),
        "max": float(a.max()),
        "mean": float(a.mean()),
        "std": float(a.std()),
        "absmax": float(np.abs(a).max()),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--diffusers", required=True, help="the src/ folder of a diffusers source tree")
    ap.add_argument("--pack", required=True, help="the pack folder (its model/vae and cases.json)")
    ap.add_argument("--commit", default="58eb52c0803ea9af3abec60841c2a093bdf1f951", help="recorded as provenance")
    args = ap.parse_args()

    library_stubs.install_diffusers(args.diffusers)
    akl = importlib.import_module("diffusers.models.autoencoders.autoencoder_kl_cogvideox")
    vae_dir = os.path.join(args.pack, "model", "vae")
    cfg = json.load(open(os.path.join(vae_dir, "config.json")))
    init = {k: v for k, v in cfg.items() if not k.startswith("_")}
    vae = akl.AutoencoderKLCogVideoX(**init)
    vae.load_state_dict(st_read(os.path.join(vae_dir, "diffusion_pytorch_model.safetensors")), strict=True)
    vae.eval()
    vae64 = akl.AutoencoderKLCogVideoX(**init)
    vae64.load_state_dict(vae.state_dict(), strict=True)
    vae64.double().eval()
    cases_path = os.path.join(args.pack, "cases.json")
    pack = json.load(open(cases_path))
    scaling = cfg["scaling_factor"]
    cl = cfg["latent_channels"]

    reproduced = {}
    # The stubs must not change the math: the pack's own decode goldens are reproduced first.
    for case_name, latent, frames_file, divide in [("vae_decode", "vae/encode_scaled_latent.npy", "vae/decode_frames.npy", True),
                                                   ("vae_frame_batching", "vae/chunk17_encode_mean.npy",
                                                    "vae/chunk17_decode_frames.npy", False)]:
        # Bit-exactness across machines is not expected (CPU kernels and threads reorder fp32 sums): the bar is the
        # pack's tolerance, and the float64 run shows the fp32 noise already inside the golden.
        z = torch.from_numpy(np.load(os.path.join(args.pack, latent)))
        with torch.no_grad():
            got = vae.decode(z / scaling if divide else z).sample.numpy()
            got64 = vae64.decode(z.double() / scaling if divide else z.double()).sample.numpy()
        want = np.load(os.path.join(args.pack, frames_file))
        tol = next(c for c in pack["cases"] if c["name"] == case_name)["tolerance"]
        tol = tol.get("decode", tol)
        ok = got.shape == want.shape and bool(np.all(np.abs(got - want) <= tol["atol"] + tol["rtol"] * np.abs(want)))
        print(f"reproduces the pack's {case_name}: max |fp32 - golden| = {np.abs(got - want).max():.3g}, "
              f"max |fp64 - golden| = {np.abs(got64 - want).max():.3g} (tolerance {tol})")
        reproduced[case_name] = {"max_abs_diff_fp32": float(np.abs(got - want).max()),
                                 "max_abs_diff_fp64": float(np.abs(got64 - want).max())}
        if not ok:
            sys.exit(f"the stubbed diffusers does not reproduce the pack's {case_name} ({frames_file}); nothing written")

    files, deviation = [], {}
    for name, fl, h, w, seed in LATENTS:
        g = torch.Generator().manual_seed(seed)
        scaled = (scaling * torch.randn(1, cl, fl, h, w, generator=g)).float()
        with torch.no_grad():
            frames = vae.decode(scaled / scaling).sample
            frames64 = vae64.decode(scaled.double() / scaling).sample
        assert frames.shape[2] == 4 * fl, f"diffusers decoded {frames.shape[2]} frames for {fl} latent frames"
        deviation[name] = float((frames.double() - frames64).abs().max())
        lat, out = f"vae/{name}_scaled_latent.npy", f"vae/{name}_decode_frames.npy"
        np.save(os.path.join(args.pack, lat), scaled.numpy())
        np.save(os.path.join(args.pack, out), frames.numpy())
        files.append({"file": lat, "shape": list(scaled.shape), "dtype": "float32", "role": "input",
                      "meaning": f"scaled latent, {fl} latent frames (even); divide by {scaling} before decode",
                      "layout": "B,Cl,Fl,Hl,Wl", "stats": stats(scaled.numpy())})
        files.append({"file": out, "shape": list(frames.shape), "dtype": "float32", "role": "output",
                      "meaning": f"decoded frames (not clamped): 4*Fl = {4 * fl}; a video of 4*Fl-3 = {4 * fl - 3} "
                                 "frames keeps the last 4*Fl-3",
                      "layout": "B,C,F,H,W", "stats": stats(frames.numpy())})
        print(f"{name}: latent {tuple(scaled.shape)} -> frames {tuple(frames.shape)}, fp64 deviation {deviation[name]:.3g}")

    case = {
        "name": CASE,
        "description": "AutoencoderKLCogVideoX.decode of an EVEN number of latent frames with default frame batching "
                       "(num_latent_frames_batch_size=2: Fl=4 decodes as [0:2],[2:4]; Fl=2 as one batch) and no "
                       "tiling. Each even batch's temporal upsampling doubles every frame, latent frame 0 included, "
                       "so 4*Fl frames come out; frames 0..3 stand at latent frame 0. Added by the dvs project "
                       "(not part of the shared pack) with tests/golden_tools/make_vae_even_latent_decode.py.",
        "call": "vae.decode(scaled_latent / scaling_factor).sample",
        "tolerance": {"atol": 0.0005, "rtol": 0.0001},
        "files": files,
        "fp64_max_abs_deviation": deviation,
        "generated_by": {"script": "tests/golden_tools/make_vae_even_latent_decode.py",
                         "diffusers": f"github:huggingface/diffusers {args.commit}",
                         "torch": torch.__version__, "device": "cpu", "dtype": "float32"},
        "shims": SHIMS,
        "reproduces_pack_cases": reproduced,
    }
    pack["cases"] = [c for c in pack["cases"] if c.get("name") != CASE] + [case]
    torch_bf16.write_cases_json(cases_path, pack)
    print(f"{cases_path}: case {CASE} written")


if __name__ == "__main__":
    main()
