#!/usr/bin/env python3
"""PyTorch baselines for the device benchmark stage, and the block comparison's reference folder.

  torch_ref.py --json F [--out DIR] [--seed 0] [--quick] [--no-baselines] [--no-block]
  torch_ref.py --golden tests/golden/A     (validate the plain CogVideoX transformer against the golden pack)

Baselines (CUDA events: 3 warm-ups, then the median of up to 20 timed runs or ~1 s), one JSON line per case,
flushed as each case ends: GEMM at the transformer's shapes (F.linear = torch.matmul against W^T, bf16 and
fp16), attention (SDPA flash, cuDNN where available), the VAE decoder's causal conv3d shapes (F.conv3d
bf16), device-to-device copy bandwidth, an 8192^3 matmul as the measured ceiling.

Block: a plain PyTorch CogVideoX transformer (diffusers' CogVideoXTransformer3DModel math, written here from
its definition: patch embedding with learned positional table, timestep embedding, blocks with
CogVideoXLayerNormZero, qk-LayerNorm, 3D RoPE on video tokens, tanh-GELU FFN, final norm, AdaLayerNorm
norm_out, proj_out, unpatchify) with random bf16 weights, written as a diffusers transformer folder
(config.json with num_layers=1, bf16 safetensors) with its inputs and two outputs: bf16 eager and an fp32
reference (same bf16-rounded weights and inputs upcast, TF32 off). Runs on torch 1.13 (CPU) and 2.x (CUDA).
"""
import argparse
import json
import math
import os
import struct
import sys
import time

import numpy as np
import torch
import torch.nn.functional as F

# ----------------------------------------------------------------------------------------------- safetensors
# A small reader/writer of our own: the device has the safetensors package, the CPU machine may not.
_ST_DTYPES = {"F32": (torch.float32, 4), "BF16": (torch.bfloat16, 2), "F16": (torch.float16, 2)}


def st_read(path):
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
        data = f.read()
    out = {}
    for name, e in header.items():
        if name == "__metadata__":
            continue
        dt, size = _ST_DTYPES[e["dtype"]]
        a, b = e["data_offsets"]
        raw = np.frombuffer(data[a:b], dtype=np.int16 if size == 2 else np.float32).copy()
        t = torch.from_numpy(raw)
        if size == 2:
            t = t.view(dt)
        out[name] = t.reshape(e["shape"])
    return out


def st_read_dir(folder):
    w = {}
    for fn in sorted(os.listdir(folder)):
        if fn.endswith(".safetensors"):
            w.update(st_read(os.path.join(folder, fn)))
    return w


def st_write(path, tensors):
    header, blobs, off = {}, [], 0
    for name in sorted(tensors):
        t = tensors[name].detach().contiguous().cpu()
        if t.dtype == torch.bfloat16 or t.dtype == torch.float16:
            raw = t.view(torch.int16).numpy().tobytes()
            dt = "BF16" if t.dtype == torch.bfloat16 else "F16"
        else:
            raw = t.float().numpy().tobytes()
            dt = "F32"
        header[name] = {"dtype": dt, "shape": list(t.shape), "data_offsets": [off, off + len(raw)]}
        blobs.append(raw)
        off += len(raw)
    h = json.dumps(header).encode()
    h += b" " * ((8 - len(h) % 8) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(h)))
        f.write(h)
        for b in blobs:
            f.write(b)


# ------------------------------------------------------------------------------------- plain CogVideoX math
def timestep_sinusoid(t, dim, flip_sin_to_cos=True, freq_shift=0.0):
    """diffusers get_timestep_embedding: exp(-ln(1e4) k / (half - shift)), [sin | cos] (flipped: [cos | sin])."""
    half = dim // 2
    exponent = -math.log(10000.0) * torch.arange(half, dtype=torch.float32, device=t.device) / (half - freq_shift)
    emb = t.float()[:, None] * torch.exp(exponent)[None, :]
    emb = torch.cat([torch.sin(emb), torch.cos(emb)], dim=-1)
    if flip_sin_to_cos:
        emb = torch.cat([emb[:, half:], emb[:, :half]], dim=-1)
    return emb


def rope_1d(dim, pos, theta=10000.0):
    freqs = 1.0 / (theta ** (torch.arange(0, dim, 2, dtype=torch.float32)[: dim // 2] / dim))
    freqs = torch.outer(pos.float(), freqs)
    return freqs.cos().repeat_interleave(2, dim=1), freqs.sin().repeat_interleave(2, dim=1)


def rope_3d(head_dim, frames, grid_h, grid_w, base_h, base_w):
    """get_3d_rotary_pos_embed (linspace grid, use_real) with the pipeline's crop region for the grid."""
    # get_resize_crop_region_for_grid(src=(grid_h, grid_w), tgt_width=base_w, tgt_height=base_h)
    r = grid_h / grid_w
    if r > base_h / base_w:
        rh = base_h
        rw = int(round(base_h / grid_h * grid_w))
    else:
        rw = base_w
        rh = int(round(base_w / grid_w * grid_h))
    top = int(round((base_h - rh) / 2.0))
    left = int(round((base_w - rw) / 2.0))
    start, stop = (top, left), (top + rh, left + rw)
    gh = np.linspace(start[0], stop[0] * (grid_h - 1) / grid_h, grid_h, endpoint=True, dtype=np.float32)
    gw = np.linspace(start[1], stop[1] * (grid_w - 1) / grid_w, grid_w, endpoint=True, dtype=np.float32)
    gt = np.linspace(0, frames * (frames - 1) / frames, frames, endpoint=True, dtype=np.float32)
    dt, dh, dw = head_dim // 4, head_dim // 8 * 3, head_dim // 8 * 3
    ct, st = rope_1d(dt, torch.from_numpy(gt))
    ch, sh = rope_1d(dh, torch.from_numpy(gh))
    cw, sw = rope_1d(dw, torch.from_numpy(gw))

    def combine(ft, fh, fw):
        ft = ft[:, None, None, :].expand(-1, grid_h, grid_w, -1)
        fh = fh[None, :, None, :].expand(frames, -1, grid_w, -1)
        fw = fw[None, None, :, :].expand(frames, grid_h, -1, -1)
        return torch.cat([ft, fh, fw], dim=-1).reshape(frames * grid_h * grid_w, -1)

    return combine(ct, ch, cw), combine(st, sh, sw)


def apply_rope(x, cos, sin):
    """x [B, H, S, D]; pairs (x[2i], x[2i+1]); computed in fp32, back to x's dtype (diffusers apply_rotary_emb)."""
    xr, xi = x.reshape(*x.shape[:-1], -1, 2).unbind(-1)
    rot = torch.stack([-xi, xr], dim=-1).flatten(3)
    return (x.float() * cos[None, None] + rot.float() * sin[None, None]).to(x.dtype)


def sdpa(q, k, v):
    """16-bit: SDPA (what diffusers runs). fp32/fp64 (the reference, and torch 1.13 without SDPA): the plain
    formula softmax(q k^T / sqrt(d)) v in chunks of query rows, so the reference never depends on which SDPA
    backend a build picks (an fp32 math fallback would need B*H*S^2 scores: 121 GB at the real size)."""
    if q.dtype in (torch.float16, torch.bfloat16) and hasattr(F, "scaled_dot_product_attention"):
        return F.scaled_dot_product_attention(q, k, v)
    scale = 1.0 / math.sqrt(q.shape[-1])
    rows = max(1, (1 << 28) // max(1, q.shape[0] * q.shape[1] * k.shape[2]))  # ~1 GiB of fp32 scores
    out = []
    for i in range(0, q.shape[2], rows):
        s = torch.matmul(q[:, :, i:i + rows], k.transpose(-1, -2)) * scale
        out.append(torch.matmul(torch.softmax(s, dim=-1), v))
    return torch.cat(out, dim=2)


def layer_norm(x, w, b, eps):
    return F.layer_norm(x, (x.shape[-1],), w, b, eps)


def cogvideox_forward(cfg, W, latent, text, timestep, rope, taps=None):
    """CogVideoXTransformer3DModel.forward (1.0 layout, as 5B-I2V). latent [B,F,C,H,W]; text [B,L,Dt]; timestep [B]."""
    B, Fr, C, H, Wd = latent.shape
    p = cfg["patch_size"]
    heads, hd = cfg["num_attention_heads"], cfg["attention_head_dim"]
    D = heads * hd
    eps = cfg["norm_eps"]
    dt = latent.dtype
    lin = lambda x, n: F.linear(x, W[n + ".weight"], W.get(n + ".bias"))

    t_emb = timestep_sinusoid(timestep, D, cfg["flip_sin_to_cos"], cfg["freq_shift"]).to(dt)
    emb = lin(F.silu(lin(t_emb, "time_embedding.linear_1")), "time_embedding.linear_2")

    txt = lin(text, "patch_embed.text_proj")
    img = F.conv2d(latent.reshape(-1, C, H, Wd), W["patch_embed.proj.weight"], W["patch_embed.proj.bias"], stride=p)
    img = img.view(B, Fr, D, H // p, Wd // p).flatten(3).transpose(2, 3).flatten(1, 2)
    x = torch.cat([txt, img], dim=1)
    if cfg["use_learned_positional_embeddings"]:
        x = x + W["patch_embed.pos_embedding"].to(dt)
    L = text.shape[1]
    enc, hid = x[:, :L], x[:, L:]
    if taps is not None:
        taps["time_embedding"], taps["patch_embed"] = emb, x
    cos, sin = rope

    for i in range(cfg["num_layers"]):
        pre = "transformer_blocks.%d." % i

        def norm_zero(name, h, e):
            m = lin(F.silu(emb), pre + name + ".linear").chunk(6, dim=1)
            nw, nb = W[pre + name + ".norm.weight"], W[pre + name + ".norm.bias"]
            h = layer_norm(h, nw, nb, eps) * (1 + m[1])[:, None] + m[0][:, None]
            e = layer_norm(e, nw, nb, eps) * (1 + m[4])[:, None] + m[3][:, None]
            return h, e, m[2][:, None], m[5][:, None]

        nh, ne, gate, egate = norm_zero("norm1", hid, enc)
        s = torch.cat([ne, nh], dim=1)
        q, k, v = (lin(s, pre + "attn1.to_" + n).view(B, -1, heads, hd).transpose(1, 2) for n in "qkv")
        q = layer_norm(q, W[pre + "attn1.norm_q.weight"], W[pre + "attn1.norm_q.bias"], 1e-6)
        k = layer_norm(k, W[pre + "attn1.norm_k.weight"], W[pre + "attn1.norm_k.bias"], 1e-6)
        q = torch.cat([q[:, :, :L], apply_rope(q[:, :, L:], cos, sin)], dim=2)
        k = torch.cat([k[:, :, :L], apply_rope(k[:, :, L:], cos, sin)], dim=2)
        a = sdpa(q, k, v).transpose(1, 2).reshape(B, -1, D)
        a = lin(a, pre + "attn1.to_out.0")
        hid = hid + gate * a[:, L:]
        enc = enc + egate * a[:, :L]

        nh, ne, gate, egate = norm_zero("norm2", hid, enc)
        s = torch.cat([ne, nh], dim=1)
        ff = lin(F.gelu(lin(s, pre + "ff.net.0.proj"), approximate="tanh"), pre + "ff.net.2")
        hid = hid + gate * ff[:, L:]
        enc = enc + egate * ff[:, :L]
        if taps is not None:
            taps["block%d_hidden" % i], taps["block%d_encoder" % i] = hid, enc

    x = layer_norm(torch.cat([enc, hid], dim=1), W["norm_final.weight"], W["norm_final.bias"], eps)[:, L:]
    if taps is not None:
        taps["norm_final"] = x
    shift, scale = lin(F.silu(emb), "norm_out.linear").chunk(2, dim=1)
    x = layer_norm(x, W["norm_out.norm.weight"], W["norm_out.norm.bias"], eps) * (1 + scale)[:, None] + shift[:, None]
    x = lin(x, "proj_out")
    if taps is not None:
        taps["proj_out"] = x
    x = x.reshape(B, Fr, H // p, Wd // p, -1, p, p)
    return x.permute(0, 1, 4, 2, 5, 3, 6).flatten(5, 6).flatten(3, 4)


def rope_for(cfg, frames, h, w):
    p = cfg["patch_size"]
    return rope_3d(cfg["attention_head_dim"], frames, h // p, w // p, cfg["sample_height"] // p, cfg["sample_width"] // p)


# --------------------------------------------------------------------------------------- golden validation
def validate_golden(pack):
    """Run the plain transformer on the pack's tiny model (fp32 and fp64) and compare with diffusers' outputs."""
    tdir = os.path.join(pack, "transformer")
    cfg = json.load(open(os.path.join(pack, "model", "transformer", "config.json")))
    W = st_read_dir(os.path.join(pack, "model", "transformer"))
    load = lambda n: torch.from_numpy(np.load(os.path.join(tdir, n)))
    latent, text = load("hidden_states.npy"), load("encoder_hidden_states.npy")
    _, Fr, _, H, Wd = latent.shape
    cos, sin = rope_for(cfg, Fr, H, Wd)
    worst = 0.0

    def rel(a, b):
        a, b = a.double(), b.double()
        return float((a - b).norm() / b.norm()), float((a - b).abs().max())

    for name, ref in (("rope_cos", load("rope_cos.npy")), ("rope_sin", load("rope_sin.npy"))):
        r, m = rel(cos if name == "rope_cos" else sin, ref)
        print("%-24s rel %.3e  max_abs %.3e" % (name, r, m))
        worst = max(worst, r)
    for t in (999, 500):
        for dtype in (torch.float32, torch.float64):
            Wc = {k: v.to(dtype) for k, v in W.items()}
            taps = {}
            out = cogvideox_forward(cfg, Wc, latent.to(dtype), text.to(dtype), torch.tensor([t]),
                                    (cos.to(dtype), sin.to(dtype)), taps)
            r, m = rel(out, load("output_t%d.npy" % t))
            print("%-24s rel %.3e  max_abs %.3e" % ("output_t%d %s" % (t, str(dtype)[6:]), r, m))
            worst = max(worst, r)
            for tap in ("time_embedding", "block0_hidden", "block0_encoder", "patch_embed", "block1_hidden",
                        "norm_final", "proj_out"):
                fn = os.path.join(tdir, "t%d_%s.npy" % (t, tap))
                if os.path.exists(fn) and dtype == torch.float32:
                    r, m = rel(taps[tap], load(os.path.basename(fn)))
                    print("  %-22s rel %.3e  max_abs %.3e" % (tap, r, m))
                    worst = max(worst, r)
    print("golden: worst relative L2 error %.3e (%s)" % (worst, "PASS" if worst < 1e-5 else "FAIL"))
    return worst < 1e-5


# ------------------------------------------------------------------------------------------------- timing
class Reporter:
    def __init__(self, path):
        self.f = open(path, "a") if path else None

    def emit(self, **kw):
        kw.setdefault("source", "torch")
        line = json.dumps(kw)
        print(line, flush=True)
        if self.f:
            self.f.write(line + "\n")
            self.f.flush()


def sync(dev):
    if dev.type == "cuda":
        torch.cuda.synchronize()


def time_ms(fn, dev, warmup=3, reps=20, budget_s=1.0):
    """Median ms of fn(): CUDA events around each call on a GPU, else the host clock."""
    for _ in range(warmup):
        fn()
    sync(dev)
    times, t_start = [], time.perf_counter()
    while len(times) < reps and (len(times) < 5 or time.perf_counter() - t_start < budget_s):
        if dev.type == "cuda":
            a, b = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
            a.record()
            fn()
            b.record()
            b.synchronize()
            times.append(a.elapsed_time(b))
        else:
            t0 = time.perf_counter()
            fn()
            times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times)), len(times)


def randn(shape, dev, dtype, gen, scale=1.0):
    return (torch.randn(shape, device=dev, generator=gen, dtype=torch.float32) * scale).to(dtype)


def sig(x, digits=4):
    """x to `digits` significant digits: a rate rounded to decimals reads 0.0 for the smoke's tiny shapes on a busy
    CPU, and a ratio to 0 is no ratio (gpu_stage_torch_smoke failed on it now and then)."""
    return float("%.*g" % (digits, x))


def run_case(rep, case, shape, fn, dev, flops=0.0, nbytes=0.0, **extra):
    try:
        ms, n = time_ms(fn, dev)
        d = dict(case=case, shape=shape, ms=sig(ms), runs=n, **extra)
        if flops:
            d["tflops"] = sig(flops / (ms * 1e9))
        if nbytes:
            d["gbps"] = sig(nbytes / (ms * 1e6))
        rep.emit(**d)
    except Exception as e:  # one failed case (out of memory, missing backend) must not stop the others
        rep.emit(case=case, shape=shape, error="%s: %s" % (type(e).__name__, str(e)[:300]), **extra)
    if dev.type == "cuda":
        torch.cuda.empty_cache()


def baselines(rep, dev, quick, gen):
    # --quick: the same odd shapes as dvs-bench's smoke mode, so the summary's join is exercised on a CPU.
    M = 37 if quick else 2 * 17776
    gemms = [(3072, 3072), (3072, 9216), (3072, 12288), (12288, 3072)]
    if quick:
        gemms = [(24, 45), (72, 40)]
    for dtype in ((torch.bfloat16, torch.float16) if dev.type == "cuda" else (torch.float32,)):
        dn = str(dtype)[6:]
        for K, N in gemms:
            x, w = randn((M, K), dev, dtype, gen), randn((N, K), dev, dtype, gen, 1 / math.sqrt(K))
            run_case(rep, "gemm", "%dx%dx%d" % (M, K, N), lambda: F.linear(x, w), dev, 2.0 * M * N * K, dtype=dn,
                     backend="torch.matmul (F.linear, W^T)")
            del x, w
        n = 256 if quick else 8192
        a, b = randn((n, n), dev, dtype, gen), randn((n, n), dev, dtype, gen)
        run_case(rep, "ceiling_matmul", "%d^3" % n, lambda: torch.matmul(a, b), dev, 2.0 * n ** 3, dtype=dn,
                 backend="torch.matmul")
        del a, b

    # Attention: B=2, H=48, D=64, S=17,776 (FLOPs 4 B H S^2 D).
    B, Hh, S, Dh = (2, 3, 45, 64) if quick else (2, 48, 17776, 64)
    adt = torch.bfloat16 if dev.type == "cuda" else torch.float32
    q, k, v = (randn((B, Hh, S, Dh), dev, adt, gen) for _ in range(3))
    flops = 4.0 * B * Hh * S * S * Dh
    shape = "%dx%dx%dx%d" % (B, Hh, S, Dh)
    backends = [("default", None)]
    try:
        from torch.nn.attention import SDPBackend, sdpa_kernel
        backends = [("flash", SDPBackend.FLASH_ATTENTION), ("cudnn", SDPBackend.CUDNN_ATTENTION),
                    ("efficient", SDPBackend.EFFICIENT_ATTENTION)]
    except ImportError:
        sdpa_kernel = None
    for name, be in backends:
        if be is None or dev.type != "cuda":
            run_case(rep, "attention", shape, lambda: sdpa(q, k, v), dev, flops, dtype=str(adt)[6:], backend="sdpa")
            break

        def f(be=be):
            with sdpa_kernel(be):
                return F.scaled_dot_product_attention(q, k, v)
        run_case(rep, "attention", shape, f, dev, flops, dtype=str(adt)[6:], backend="sdpa_" + name)
    del q, k, v

    # VAE decoder conv3d 3x3x3, causal: 2 replicated first frames in front, spatial zero padding 1.
    convs = [(128, 480, 720), (256, 240, 360), (512, 60, 90)]
    frames = 4
    if quick:
        convs, frames = [(12, 10, 14)], 3
    cdt = torch.bfloat16 if dev.type == "cuda" else torch.float32
    if dev.type == "cuda":
        torch.backends.cudnn.benchmark = True
    for c, h, w in convs:
        x = randn((1, c, frames, h, w), dev, cdt, gen)
        x = torch.cat([x[:, :, :1], x[:, :, :1], x], dim=2)
        wt = randn((c, c, 3, 3, 3), dev, cdt, gen, 1 / math.sqrt(27 * c))
        bias = randn((c,), dev, cdt, gen, 0.05)
        run_case(rep, "conv3d", "%d->%d@%dx%dxF%d" % (c, c, h, w, frames),
                 lambda: F.conv3d(x, wt, bias, padding=(0, 1, 1)), dev, 2.0 * c * c * 27 * frames * h * w,
                 dtype=str(cdt)[6:], backend="F.conv3d (cudnn)" if dev.type == "cuda" else "F.conv3d")
        del x, wt, bias

    nb = (1 << 20) if quick else (256 << 20)
    src = torch.randint(0, 255, (nb,), device=dev, dtype=torch.uint8, generator=gen)
    dst = torch.empty_like(src)
    run_case(rep, "copy", "%dMiB" % (nb >> 20), lambda: dst.copy_(src), dev, nbytes=2.0 * nb, backend="copy_ (D2D)")
    del src, dst


# ---------------------------------------------------------------------------------------------- the block
REAL_CONFIG = {
    "_class_name": "CogVideoXTransformer3DModel", "_diffusers_version": "0.32.0", "activation_fn": "gelu-approximate",
    "attention_bias": True, "attention_head_dim": 64, "dropout": 0.0, "flip_sin_to_cos": True, "freq_shift": 0,
    "in_channels": 32, "max_text_seq_length": 226, "norm_elementwise_affine": True, "norm_eps": 1e-05,
    "num_attention_heads": 48, "num_layers": 42, "ofs_embed_dim": None, "out_channels": 16, "patch_bias": True,
    "patch_size": 2, "patch_size_t": None, "sample_frames": 49, "sample_height": 60, "sample_width": 90,
    "spatial_interpolation_scale": 1.875, "temporal_compression_ratio": 4, "temporal_interpolation_scale": 1.0,
    "text_embed_dim": 4096, "time_embed_dim": 512, "timestep_activation_fn": "silu",
    "use_learned_positional_embeddings": True, "use_rotary_positional_embeddings": True,
}
# The real widths (heads, hidden 3072, FFN 12288, text 4096 x 226, time 512, channels 32/16) on a 1-frame 4x4
# latent: a CPU check of the real-size folder through dvs's loader (--block-size mid).
MID_CONFIG = dict(REAL_CONFIG, sample_frames=1, sample_height=4, sample_width=4)
QUICK_CONFIG = dict(REAL_CONFIG, attention_head_dim=16, num_attention_heads=2, in_channels=8, out_channels=4,
                    max_text_seq_length=8, sample_frames=9, sample_height=8, sample_width=8, text_embed_dim=32,
                    time_embed_dim=32)


def random_weights(cfg, dev, gen):
    """Random bf16 weights by diffusers' names, scaled like the golden pack (fan-in normals, norms near 1)."""
    D = cfg["num_attention_heads"] * cfg["attention_head_dim"]
    hd, T, C, p = cfg["attention_head_dim"], cfg["time_embed_dim"], cfg["in_channels"], cfg["patch_size"]
    Fl = (cfg["sample_frames"] - 1) // cfg["temporal_compression_ratio"] + 1
    n_pos = cfg["max_text_seq_length"] + Fl * (cfg["sample_height"] // p) * (cfg["sample_width"] // p)
    shapes = {
        "patch_embed.proj.weight": (D, C, p, p), "patch_embed.proj.bias": (D,),
        "patch_embed.text_proj.weight": (D, cfg["text_embed_dim"]), "patch_embed.text_proj.bias": (D,),
        "patch_embed.pos_embedding": (1, n_pos, D),
        "time_embedding.linear_1.weight": (T, D), "time_embedding.linear_1.bias": (T,),
        "time_embedding.linear_2.weight": (T, T), "time_embedding.linear_2.bias": (T,),
        "norm_final.weight": (D,), "norm_final.bias": (D,),
        "norm_out.linear.weight": (2 * D, T), "norm_out.linear.bias": (2 * D,),
        "norm_out.norm.weight": (D,), "norm_out.norm.bias": (D,),
        "proj_out.weight": (p * p * cfg["out_channels"], D), "proj_out.bias": (p * p * cfg["out_channels"],),
    }
    for i in range(cfg["num_layers"]):
        b = "transformer_blocks.%d." % i
        for n in ("norm1", "norm2"):
            shapes.update({b + n + ".linear.weight": (6 * D, T), b + n + ".linear.bias": (6 * D,),
                           b + n + ".norm.weight": (D,), b + n + ".norm.bias": (D,)})
        for n in ("to_q", "to_k", "to_v", "to_out.0"):
            shapes.update({b + "attn1." + n + ".weight": (D, D), b + "attn1." + n + ".bias": (D,)})
        for n in ("norm_q", "norm_k"):
            shapes.update({b + "attn1." + n + ".weight": (hd,), b + "attn1." + n + ".bias": (hd,)})
        shapes.update({b + "ff.net.0.proj.weight": (4 * D, D), b + "ff.net.0.proj.bias": (4 * D,),
                       b + "ff.net.2.weight": (D, 4 * D), b + "ff.net.2.bias": (D,)})
    W = {}
    for name in sorted(shapes):
        s = shapes[name]
        if name.endswith("pos_embedding"):
            t = randn(s, dev, torch.float32, gen, 0.5)
        elif len(s) >= 2:
            t = randn(s, dev, torch.float32, gen, 1 / math.sqrt(float(np.prod(s[1:]))))
        elif ".norm" in name or name.startswith("norm_final") or "norm_q" in name or "norm_k" in name:
            t = 1 + randn(s, dev, torch.float32, gen, 0.1) if name.endswith("weight") else randn(s, dev, torch.float32, gen, 0.1)
        else:
            t = randn(s, dev, torch.float32, gen, 0.05)
        W[name] = t.to(torch.bfloat16)
    return W


def block(rep, dev, out_dir, size, gen):
    cfg = dict({"quick": QUICK_CONFIG, "mid": MID_CONFIG, "real": REAL_CONFIG}[size], num_layers=1)
    tdir = os.path.join(out_dir, "transformer")
    os.makedirs(tdir, exist_ok=True)
    t0 = time.perf_counter()
    W = random_weights(cfg, dev, gen)
    Fl = (cfg["sample_frames"] - 1) // cfg["temporal_compression_ratio"] + 1
    B, H, Wd = 2, cfg["sample_height"], cfg["sample_width"]
    # Inputs rounded to bf16 so that every side (torch bf16, torch fp32, dvs f32 inputs) sees the same values.
    latent = randn((B, Fl, cfg["in_channels"], H, Wd), dev, torch.bfloat16, gen)
    text = randn((B, cfg["max_text_seq_length"], cfg["text_embed_dim"]), dev, torch.bfloat16, gen)
    timestep = torch.tensor([999, 999], device=dev)
    rope = tuple(t.to(dev) for t in rope_for(cfg, Fl, H, Wd))
    json.dump(cfg, open(os.path.join(tdir, "config.json"), "w"), indent=2)
    st_write(os.path.join(tdir, "diffusion_pytorch_model.safetensors"), W)
    np.save(os.path.join(out_dir, "latent.npy"), latent.float().cpu().numpy())
    np.save(os.path.join(out_dir, "text.npy"), text.float().cpu().numpy())
    np.save(os.path.join(out_dir, "timestep.npy"), timestep.float().cpu().numpy())
    written = time.perf_counter() - t0
    shape = "%d layer, %dx%dx%dx%dx%d, text %d" % (cfg["num_layers"], B, Fl, cfg["in_channels"], H, Wd,
                                                   cfg["max_text_seq_length"])
    S = cfg["max_text_seq_length"] + Fl * (H // 2) * (Wd // 2)
    D = cfg["num_attention_heads"] * cfg["attention_head_dim"]
    # FLOPs of the block's GEMMs and attention (the rest is small): qkv+out 4 D^2, FFN 16 D^2 per token.
    flops = B * S * 24.0 * D * D + 4.0 * B * cfg["num_attention_heads"] * S * S * cfg["attention_head_dim"]

    with torch.no_grad():
        bdt = torch.bfloat16
        Wb = {k: v.to(bdt) for k, v in W.items()}
        fwd = lambda: cogvideox_forward(cfg, Wb, latent.to(bdt), text.to(bdt), timestep, rope)
        try:
            out_b = fwd().float()
        except RuntimeError:  # a CPU build without some bf16 kernel: fp32 (then the "bf16" error is 0)
            bdt = torch.float32
            Wb = {k: v.to(bdt) for k, v in W.items()}
            out_b = fwd().float()
        np.save(os.path.join(out_dir, "out_torch_bf16.npy"), out_b.cpu().numpy())
        ms, n = time_ms(fwd, dev, warmup=2, reps=10, budget_s=2.0)
        rep.emit(case="block", shape=shape, ms=sig(ms), runs=n, tflops=sig(flops / (ms * 1e9)),
                 dtype=str(bdt)[6:], backend="plain torch eager (SDPA)", write_s=round(written, 1), dir=out_dir)
        del Wb
        if dev.type == "cuda":
            torch.backends.cuda.matmul.allow_tf32 = False
            torch.backends.cudnn.allow_tf32 = False
            torch.cuda.empty_cache()
        Wf = {k: v.float() for k, v in W.items()}
        out_f = cogvideox_forward(cfg, Wf, latent.float(), text.float(), timestep, rope).float()
        np.save(os.path.join(out_dir, "out_torch_fp32.npy"), out_f.cpu().numpy())
        err = float((out_b - out_f).double().norm() / out_f.double().norm())
        rep.emit(case="block_error", shape=shape, impl="torch_bf16", rel_l2_vs_fp32=err)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default="")
    ap.add_argument("--out", default="/tmp/dvs_gpu_block")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="tiny shapes (CPU check of the script)")
    ap.add_argument("--no-baselines", action="store_true")
    ap.add_argument("--no-block", action="store_true")
    ap.add_argument("--block-size", choices=("real", "mid", "quick"), default="",
                    help="block config (default: quick with --quick, else real)")
    ap.add_argument("--golden", default="", help="validate against a golden pack folder and exit")
    a = ap.parse_args()
    if a.golden:
        torch.manual_seed(0)
        sys.exit(0 if validate_golden(a.golden) else 1)
    dev = torch.device("cuda" if torch.cuda.is_available() else "cpu")
    rep = Reporter(a.json)
    info = dict(case="torch_info", torch=torch.__version__, device=str(dev))
    if dev.type == "cuda":
        info.update(gpu=torch.cuda.get_device_name(0), cuda=torch.version.cuda,
                    cudnn=torch.backends.cudnn.version())
    rep.emit(**info)
    gen = torch.Generator(device=dev)
    gen.manual_seed(a.seed)
    with torch.no_grad():
        if not a.no_baselines:
            baselines(rep, dev, a.quick, gen)
        if not a.no_block:
            try:
                block(rep, dev, a.out, a.block_size or ("quick" if a.quick else "real"), gen)
            except Exception as e:
                rep.emit(case="block", error="%s: %s" % (type(e).__name__, str(e)[:300]))


if __name__ == "__main__":
    main()
