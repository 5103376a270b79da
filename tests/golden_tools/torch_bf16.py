"""PyTorch's bf16 run beside a pack's float32 goldens: its definition, its error measure and how it is stored.

PyTorch's bf16 run (docs/testing.md, "One precision rule for 16-bit operands"):
  * every model (T5, the CogVideoX transformer, the VAE, Video-Depth-Anything) is the same module as for the fp32
    golden, with the same weights, converted by module.to(torch.bfloat16): weights, buffers and so every
    activation are bfloat16 and each op runs as PyTorch runs it on bfloat16 tensors; a submodule that the library
    itself always runs in float32 stays float32 (Video-Depth-Anything's head.scratch.output_conv2: its caller
    passes it out.float() with autocast off and casts the result back, so a bfloat16 copy could not even be called);
  * its floating-point inputs are the fp32 golden's inputs cast to bfloat16 (tensors the libraries themselves pass
    in float32 or as integers, such as diffusers' RoPE tables and the timesteps, are passed as they pass them);
  * its outputs are cast back to float32;
  * between model calls (the pipeline's glue: CFG, scheduler steps, K-RNR, layout changes, scaling by the VAE
    factor) everything is float32, exactly as the harness that made the fp32 goldens.
The outputs are written to <pack>/torch_bf16/<the fp32 golden's relative path> as float32 .npy like every pack file,
or (Writer(..., narrow=True)) as float16 .npy where every value converts to float16 and back unchanged: a bf16
tensor's values do, within float16's range, so the file holds exactly what the run returned and is half the size.

The error measure of a result r against the fp32 golden g (the same two numbers dvs's tests print):
  max_abs = max_i |r_i - g_i|        rel_l2 = ||r - g||_2 / ||g||_2   (||g||_2 = 0: the denominator is 1)
"""
import json
import os

import numpy as np
import torch

FOLDER = "torch_bf16"


def to_bf16(x):
    """An input as the bf16 run receives it: floating tensors cast to bfloat16, anything else unchanged."""
    if torch.is_tensor(x) and x.is_floating_point():
        return x.to(torch.bfloat16)
    return x


def to_f32(x):
    """An output as the bf16 run returns it: floating tensors back to float32 (tuples and lists elementwise)."""
    if isinstance(x, (tuple, list)):
        return type(x)(to_f32(v) for v in x)
    if torch.is_tensor(x) and x.is_floating_point():
        return x.float()
    return x


def measure(result, golden):
    r = np.asarray(result, dtype=np.float64).ravel()
    g = np.asarray(golden, dtype=np.float64).ravel()
    assert r.shape == g.shape, f"{r.shape} vs {g.shape}"
    d = r - g
    norm = float(np.linalg.norm(g))
    return {"max_abs": float(np.abs(d).max()), "rel_l2": float(np.linalg.norm(d) / (norm if norm > 0 else 1.0))}


class Writer:
    """Collects the bf16 outputs of one pack: checks each against its fp32 golden's shape, writes it, measures it."""

    def __init__(self, pack, narrow=False):
        self.pack = pack
        self.narrow = narrow  # store a file as float16 when that is exact (see the module's docstring)
        self.files = {}

    def golden(self, rel):
        return np.load(os.path.join(self.pack, rel))

    def put(self, case, rel, tensor):
        value = (tensor.detach().float().numpy() if torch.is_tensor(tensor) else np.asarray(tensor)).astype(np.float32)
        golden = self.golden(rel)
        if value.shape != golden.shape:
            raise SystemExit(f"{rel}: the bf16 run gave shape {value.shape}, the fp32 golden has {golden.shape}")
        if not np.all(np.isfinite(value)):
            raise SystemExit(f"{rel}: the bf16 run gave non-finite values")
        out = os.path.join(self.pack, FOLDER, rel)
        os.makedirs(os.path.dirname(out), exist_ok=True)
        half = value.astype(np.float16)
        exact16 = self.narrow and np.array_equal(half.astype(np.float32), value)
        np.save(out, half if exact16 else value)
        stored = np.load(out).astype(np.float32)  # what the tests will read
        if not np.array_equal(stored, value):
            raise SystemExit(f"{out}: the stored file does not read back as the run's values")
        m = measure(stored, golden)
        self.files[rel] = {"case": case, **m, "golden_absmax": float(np.abs(golden).max())}
        if self.narrow:
            self.files[rel]["stored_as"] = "float16 (exact)" if exact16 else "float32"
        print(f"  {rel:52s} max_abs {m['max_abs']:.3e}  rel_l2 {m['rel_l2']:.3e}  {'(float16)' if exact16 else ''}")

    def write_index(self, section):
        """Records `section` (definition, provenance, shims, reproduction checks) and every file's errors in the
        pack's cases.json under the key "torch_bf16"."""
        path = os.path.join(self.pack, "cases.json")
        pack = json.load(open(path))
        pack[FOLDER] = {**section, "files": dict(sorted(self.files.items()))}
        write_cases_json(path, pack)
        print(f"{path}: {FOLDER} section with {len(self.files)} files")


def write_cases_json(path, pack):
    """Replaces a pack's cases.json with `pack` (written whole, then renamed: never half a file)."""
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(pack, f, indent=1)
        f.write("\n")
    os.replace(tmp, path)


def check_reproduces(name, got, golden, atol, rtol, record):
    """The stubbed library code in float32 must reproduce the pack's fp32 golden within the pack's tolerance before
    anything is written (the proof that the stubs changed no math)."""
    got = got.detach().float().numpy() if torch.is_tensor(got) else np.asarray(got)
    diff = float(np.abs(got - golden).max()) if got.shape == golden.shape else float("inf")
    record[name] = diff
    ok = got.shape == golden.shape and bool(np.all(np.abs(got - golden) <= atol + rtol * np.abs(golden)))
    print(f"  fp32 reproduces {name}: max |diff| {diff:.3g} (atol {atol}, rtol {rtol})")
    if not ok:
        raise SystemExit(f"the fp32 run does not reproduce the pack's {name}; nothing written")
