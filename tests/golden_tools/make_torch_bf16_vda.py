#!/usr/bin/python3
"""Writes PyTorch's bf16 run beside every model golden of a Video-Depth-Anything conformance pack (tests/golden/vda-A
format).

The pack's goldens come from two computations of the authors' code: one forward of a window (case window_forward,
with every stage of the encoder, the temporal modules and the DPT head recorded by its cases encoder,
temporal_modules and dpt_head) and the whole clip through infer_video_depth (cases e2e, e2e_metric). Both are run
twice with the authors' own code at the commit the pack names: once in float32, which must reproduce every golden
they make within its case's tolerance (else nothing is written), and once as PyTorch's bf16 run (torch_bf16.py:
module.to(torch.bfloat16), inputs cast to bf16, outputs back to fp32, the glue between model calls in fp32). Stages
are read with forward hooks from the one forward (so each stage's bf16 file carries the error of the chain before
it, as dvs's stage-by-stage test compares its own chained stages); in infer_video_depth the model call is each
window's forward, and preprocessing, upsampling, alignment and blending stay float32. The bf16 outputs go to
<pack>/torch_bf16/<golden path>, float16 where that is exact (every module output is), float32 otherwise (the
clip's upsampled, aligned and blended frames); cases.json gets a "torch_bf16" section with the definition, the
provenance and each file's error against its golden. dvs's golden tests read them (tests/support/precision_rule.hpp).

Cases without a model (size_rule, preprocess, pos_embed: the position table is resampled in float32 whatever the
model dtype) get no file, nor do inputs and the window frame indices (exact integers).

Not run by the build or the tests (they read the files it wrote). To remake the files:
    git -C <Video-Depth-Anything clone> archive 4f5ae23172ba60fd7bc11ef671cca678842c7072 | tar -x -C /tmp/vda
    /usr/bin/python3 tests/golden_tools/make_torch_bf16_vda.py --vda /tmp/vda --pack tests/golden/vda-A
Needs Debian's python3-torch (1.13), python3-numpy and the packages VDA imports: python3-opencv (its resize is the
preprocessing), python3-tqdm, python3-easydict, python3-torchvision. Only the einops stand-in and the baddbmm guard
of library_stubs.VDA_SHIMS replace anything (as for the fp32 goldens); they are recorded in cases.json.
"""
import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # the fp32 goldens were made with one thread; sums in the same order

import argparse  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import types  # noqa: E402

import numpy as np  # noqa: E402
import torch  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import library_stubs  # noqa: E402
import torch_bf16  # noqa: E402

VDA_COMMIT = "4f5ae23172ba60fd7bc11ef671cca678842c7072"
NO_MODEL_CASES = ("size_rule", "preprocess", "pos_embed")
NO_MODEL_FILES = ("e2e/window_frame_indices.npy",)  # exact integers from the windowing arithmetic
FLOAT32_MODULES = ("head.scratch.output_conv2",)  # run in float32 by the library itself (torch_bf16.py)


def check_source(src, index):
    """The source tree is the one the pack was made from: every file cases.json lists, byte for byte."""
    for rel, want in index["source"]["files_sha256"].items():
        have = hashlib.sha256(open(os.path.join(src, rel), "rb").read()).hexdigest()
        if have != want:
            raise SystemExit(f"{src}/{rel}: sha256 {have}, the pack was made from {want} (commit {VDA_COMMIT})")


def build_model(vd, pack, bf16):
    """The pack's tiny VideoDepthAnything as its README builds it: the class's own __init__, with the encoder zoo's
    DINOv2('vits') keyword arguments but the pack's embed_dim / depth / num_heads, and the pack's tapped blocks."""
    cfg = json.load(open(os.path.join(pack, "model", "config.json")))
    enc, head = cfg["encoder"], cfg["head"]
    dinov2 = sys.modules["video_depth_anything.dinov2"]
    real_vit, real_zoo = dinov2.DinoVisionTransformer, vd.DINOv2

    def tiny_vit(**kwargs):
        kwargs.update(embed_dim=enc["embed_dim"], depth=enc["depth"], num_heads=enc["num_heads"])
        return real_vit(**kwargs)

    dinov2.DinoVisionTransformer, vd.DINOv2 = tiny_vit, lambda model_name: real_zoo("vits")
    try:
        m = vd.VideoDepthAnything(encoder=enc["name"], features=head["features"], out_channels=head["out_channels"],
                                  num_frames=cfg["temporal"]["temporal_max_len"], pe="ape")
    finally:
        dinov2.DinoVisionTransformer, vd.DINOv2 = real_vit, real_zoo
    m.intermediate_layer_idx[enc["name"]] = enc["intermediate_layer_idx"]
    m.load_state_dict(torch.load(os.path.join(pack, "model", cfg["checkpoint"]), map_location="cpu"), strict=True)
    m.eval()
    if bf16:
        m.to(torch.bfloat16)
        for name in FLOAT32_MODULES:
            m.get_submodule(name).float()
    return m


def model_call(model, bf16):
    """The model call of the run: the window forward, with bf16 inputs and fp32 outputs in the bf16 run."""
    forward = model.forward

    def call(x):
        with torch.no_grad():
            return torch_bf16.to_f32(forward(torch_bf16.to_bf16(x) if bf16 else x))

    return call


class Taps:
    """Stage outputs read with hooks, as float32 copies; a module called several times (the head's micro-batches of
    frames) gives the concatenation of its calls along the batch axis."""

    def __init__(self):
        self.got, self.handles = {}, []

    def add(self, name, tensor):
        self.got.setdefault(name, []).append(torch_bf16.to_f32(tensor.detach()).clone())

    def output(self, module, name, pick=lambda out: out):
        self.handles.append(module.register_forward_hook(lambda m, i, o: self.add(name, pick(o))))

    def input(self, module, name):
        self.handles.append(module.register_forward_pre_hook(lambda m, i: self.add(name, i[0])))

    def result(self):
        for h in self.handles:
            h.remove()
        return {name: torch.cat(parts, 0) for name, parts in self.got.items()}


def window_forward(model, pack, bf16):
    """One forward of the pack's window and every stage the pack records, as {golden path: tensor}."""
    t = Taps()
    enc, head = model.pretrained, model.head
    first = lambda out: out[0]  # noqa: E731  (modules returning (output, hidden states))
    t.output(enc.patch_embed, "encoder/patch_embed")
    t.input(enc.blocks[0], "encoder/tokens")
    b0 = enc.blocks[0]
    for mod, name in ((b0.norm1, "norm1"), (b0.attn.qkv, "qkv"), (b0.attn, "attn"), (b0.ls1, "ls1"),
                      (b0.norm2, "norm2"), (b0.mlp.fc1, "fc1"), (b0.mlp.act, "gelu"), (b0.mlp, "mlp"), (b0.ls2, "ls2")):
        t.output(mod, f"encoder/block0_{name}")
    t.input(b0.attn.proj, "encoder/block0_attn_context")
    for i, blk in enumerate(enc.blocks):
        t.output(blk, f"encoder/block{i}")
    taps_of = enc.get_intermediate_layers

    def get_intermediate_layers(*args, **kwargs):  # the four taps the head receives: (patch rows, CLS row) each
        taps = taps_of(*args, **kwargs)
        for i, (patches, cls) in enumerate(taps):
            t.add(f"encoder/tap{i}", patches)
            t.add(f"encoder/tap{i}_cls", cls)
        return taps

    enc.get_intermediate_layers = get_intermediate_layers
    for j, mm in enumerate(head.motion_modules):
        t.input(mm, f"temporal/m{j}_in")
        t.output(mm, f"temporal/m{j}_out", first)
        if j > 1:
            continue
        tt = mm.temporal_transformer
        blk = tt.transformer_blocks[0]
        p = f"temporal/m{j}_"
        t.output(tt.norm, p + "groupnorm")
        t.output(tt.proj_in, p + "proj_in")
        for a, ab in enumerate(blk.attention_blocks):
            t.output(blk.norms[a], p + f"attn{a}_norm")
            t.output(ab.pos_encoder, p + f"attn{a}_pe")
            for proj in ("q", "k", "v"):
                t.output(getattr(ab, "to_" + proj), p + f"attn{a}_{proj}")
            t.input(ab.to_out[0], p + f"attn{a}_context")
            t.output(ab, p + f"attn{a}_out", first)
        t.output(blk.ff_norm, p + "ff_norm")
        t.output(blk.ff.net[0].proj, p + "geglu_proj")
        t.output(blk.ff.net[0], p + "geglu")
        t.output(blk.ff, p + "ff")
        t.output(blk, p + "block_out", first)
        t.output(tt.proj_out, p + "proj_out")
    for i in range(4):
        t.output(head.projects[i], f"head/project{i}")
        t.output(head.resize_layers[i], f"head/layer{i + 1}")
        t.output(getattr(head.scratch, f"layer{i + 1}_rn"), f"head/layer{i + 1}_rn")
        t.output(getattr(head.scratch, f"refinenet{i + 1}"), f"head/refinenet{i + 1}")
    t.output(head.scratch.output_conv1, "head/output_conv1")
    t.input(head.scratch.output_conv2, "head/output_interp_frame0")
    t.output(head, "head/output", first)
    try:
        depth = model_call(model, bf16)(torch.from_numpy(np.load(os.path.join(pack, "window", "input.npy"))))
    finally:
        del enc.get_intermediate_layers
    out = {f"{name}.npy": v for name, v in t.result().items()}
    out["head/output_interp_frame0.npy"] = out["head/output_interp_frame0.npy"][:1]  # frame 0 only, as the pack
    out["window/depth.npy"] = depth
    return out


def whole_clip(vd, model, pack, cases, bf16):
    """infer_video_depth on the pack's clip, relative then metric, with each window's forward, its upsampling to the
    frame size and each later window's (scale, shift), as {golden path: tensor}."""
    e2e = cases["e2e"]
    frames = np.load(os.path.join(pack, "preprocess", "frames_uint8.npy")).astype(np.uint8)
    windows, upsampled, scale_shift, inside = [], [], [], [False]
    call = model_call(model, bf16)

    def forward(x):  # each window's model call
        inside[0] = True
        try:
            out = call(x)
        finally:
            inside[0] = False
        windows.append(out)
        return out

    def interpolate(*args, **kwargs):  # video_depth.py's resizes; the one outside forward is a window's upsampling
        out = torch.nn.functional.interpolate(*args, **kwargs)
        if not inside[0]:
            upsampled.append(out.squeeze(1).clone())
        return out

    def compute_scale_and_shift(*args, **kwargs):
        result = real_fit(*args, **kwargs)
        scale_shift.append(np.asarray(result, dtype=np.float32))
        return result

    real_f, real_fit = vd.F, vd.compute_scale_and_shift
    spy_f = types.ModuleType("torch.nn.functional")
    spy_f.__dict__.update(real_f.__dict__)
    spy_f.interpolate = interpolate
    model.forward, vd.F, vd.compute_scale_and_shift = forward, spy_f, compute_scale_and_shift
    try:
        depth, fps = model.infer_video_depth(frames, e2e["target_fps_in"], input_size=e2e["input_size"], device="cpu",
                                             fp32=True)
        assert fps == e2e["fps_out"], fps
        out = {"e2e/window_depth.npy": torch.cat(windows, 0), "e2e/window_depth_upsampled.npy": torch.stack(upsampled),
               "e2e/align_scale_shift.npy": np.stack(scale_shift), "e2e/depth.npy": depth}
        model.metric = True
        out["e2e/depth_metric_mode.npy"], _ = model.infer_video_depth(frames, e2e["target_fps_in"],
                                                                     input_size=e2e["input_size"], device="cpu",
                                                                     fp32=True)
    finally:
        model.metric = False
        del model.forward
        vd.F, vd.compute_scale_and_shift = real_f, real_fit
    return out


def run(vd, pack, cases, bf16):
    model = build_model(vd, pack, bf16)
    return {**window_forward(model, pack, bf16), **whole_clip(vd, model, pack, cases, bf16)}


def pack_files(cases):
    """{golden path: (case, role, atol, rtol)} for every file of the model cases (the first case listing it), less
    the files of the cases without a model (the clip's preprocessing, which case e2e lists again)."""
    no_model = {f["file"] for name in NO_MODEL_CASES for f in cases[name]["files"]}
    files = {}
    for name, c in cases.items():
        for f in c["files"]:
            if name not in NO_MODEL_CASES and f["file"] not in no_model:
                files.setdefault(f["file"], (name, f.get("role"), c["tolerance"]["atol"], c["tolerance"]["rtol"]))
    return files


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--vda", required=True, help="the root of a Video-Depth-Anything source tree at " + VDA_COMMIT)
    ap.add_argument("--pack", required=True, help="the pack folder")
    args = ap.parse_args()
    torch.set_num_threads(1)
    index = json.load(open(os.path.join(args.pack, "cases.json")))
    check_source(args.vda, index)
    vd = library_stubs.install_vda(args.vda)
    import cv2

    cv2.setNumThreads(1)
    cases = {c["name"]: c for c in index["cases"]}
    files = pack_files(cases)

    print("float32 run (must reproduce the pack):")
    fp32 = run(vd, args.pack, cases, bf16=False)
    wanted = {rel for rel, (_, role, _, _) in files.items() if role != "input" and rel not in NO_MODEL_FILES}
    if wanted - set(fp32):
        raise SystemExit(f"the run does not make the pack's {sorted(wanted - set(fp32))}; nothing written")
    reproduced = {}
    for rel in sorted(set(fp32) & set(files)):
        _, _, atol, rtol = files[rel]
        torch_bf16.check_reproduces(rel, fp32[rel], np.load(os.path.join(args.pack, rel)), atol, rtol, reproduced)
    if set(fp32) - set(files):
        raise SystemExit(f"the run made {sorted(set(fp32) - set(files))}, which the pack does not list")

    print("bf16 run:")
    writer = torch_bf16.Writer(args.pack, narrow=True)
    for rel, value in sorted(run(vd, args.pack, cases, bf16=True).items()):
        if rel in wanted:
            writer.put(files[rel][0], rel, value)
    writer.write_index({
        "definition": torch_bf16.__doc__.split("\n\n")[1].strip(),
        "measure": "max_abs = max |bf16 - golden|; rel_l2 = ||bf16 - golden||_2 / ||golden||_2 (per file)",
        "rule": "a dvs result computed with 16-bit-operand kernels passes when its max_abs and its rel_l2 against "
                "the fp32 golden are each at most 2x the bf16 run's (docs/testing.md)",
        "calls": {"window_forward": "one forward of window/input.npy; every stage of cases encoder, temporal_modules "
                                    "and dpt_head read with hooks from that forward (chained)",
                  "e2e": "infer_video_depth(frames, target_fps, input_size, device='cpu', fp32=True) with each "
                         "window's forward as the bf16 model call; preprocessing, upsampling, alignment and "
                         "blending in float32; e2e_metric: the same with model.metric = True"},
        "float32_modules": list(FLOAT32_MODULES),
        "storage": "float16 .npy where every value converts to float16 and back unchanged (each file's stored_as), "
                   "else float32; the errors are measured on the stored values in float64",
        "generated_by": {"script": "tests/golden_tools/make_torch_bf16_vda.py",
                         "video_depth_anything": f"github:DepthAnything/Video-Depth-Anything {VDA_COMMIT}",
                         "torch": torch.__version__, "opencv": cv2.__version__, "device": "cpu", "threads": 1},
        "shims": library_stubs.VDA_SHIMS,
        "fp32_reproduces_pack_max_abs_diff": reproduced,
    })


if __name__ == "__main__":
    main()
