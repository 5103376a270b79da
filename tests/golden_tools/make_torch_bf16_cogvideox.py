#!/usr/bin/python3
"""Writes PyTorch's bf16 run beside every model golden of a CogVideoX conformance pack (tests/golden/A format).

For each golden made by a model (T5, the CogVideoX transformer, the VAE, and the end-to-end chain that uses them),
the same computation is run twice with the libraries' own model code: once in float32, which must reproduce the
pack's golden within the case's tolerance (else nothing is written), and once as PyTorch's bf16 run (defined in
torch_bf16.py: module.to(torch.bfloat16), inputs cast to bf16, outputs back to fp32, the glue between model calls in
fp32). The bf16 outputs go to <pack>/torch_bf16/<golden path>; cases.json gets a "torch_bf16" section with the
definition, the provenance and each file's error against its golden (max_abs, rel_l2). dvs's golden tests read
them (tests/support/precision_rule.hpp): under a tensor-core kernel family a result passes when its error is at
most twice the bf16 run's.

Cases without a model (tokenizer, rope, schedulers, the K-RNR cases on the pack's own inputs) get no file: no
16-bit-operand kernel runs there. The end-to-end files are the bf16 run of the whole harness chain from its first
inputs (the video, the image, the three prompt embeddings and the two recorded noise draws), as the fp32 goldens
were made: the VAE posterior, the image latent, the inversion, K-RNR (fp32 arithmetic on the bf16 chain's values),
the sampling, the decode and the pipeline call.

Not run by the build or the tests (they read the files it wrote). To remake the files:
    git -C <diffusers clone> archive 58eb52c0803ea9af3abec60841c2a093bdf1f951 src/diffusers | tar -x -C /tmp/d
    git -C <transformers clone> archive 59e5b3f01b7773439671c3a827348ba87dc8b92a src/transformers | tar -x -C /tmp/t
    /usr/bin/python3 tests/golden_tools/make_torch_bf16_cogvideox.py --diffusers /tmp/d/src --transformers /tmp/t/src \
        --pack tests/golden/A
Needs Debian's python3-torch (1.13), python3-numpy and python3-packaging (transformers' activations import it).
The stubs (library_stubs.py) replace only modules without model math; they are recorded in cases.json.
"""
import argparse
import importlib
import json
import os
import sys

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "..", "bench", "gpu"))
import library_stubs  # noqa: E402
import torch_bf16  # noqa: E402
from torch_ref import st_read, st_read_dir  # noqa: E402  (the project's safetensors reader)

DIFFUSERS_COMMIT = "58eb52c0803ea9af3abec60841c2a093bdf1f951"
TRANSFORMERS_COMMIT = "59e5b3f01b7773439671c3a827348ba87dc8b92a"


class Models:
    """The pack's three models built from the libraries' code, in float32 or as PyTorch's bf16 run."""

    def __init__(self, pack, bf16):
        self.pack, self.bf16 = pack, bf16
        mt5 = importlib.import_module("transformers.models.t5.modeling_t5")
        ct5 = importlib.import_module("transformers.models.t5.configuration_t5")
        mtr = importlib.import_module("diffusers.models.transformers.cogvideox_transformer_3d")
        akl = importlib.import_module("diffusers.models.autoencoders.autoencoder_kl_cogvideox")

        def t5(folder):
            cfg = json.load(open(os.path.join(pack, folder, "config.json")))
            m = mt5.T5EncoderModel(ct5.T5Config(**{k: v for k, v in cfg.items() if not k.startswith("_")}))
            w = st_read_dir(os.path.join(pack, folder))
            w = {k: v.float() for k, v in w.items()}
            w["encoder.embed_tokens.weight"] = w["shared.weight"]  # tied (not stored), as from_pretrained ties it
            m.load_state_dict(w, strict=True)
            return m

        def diffusers_model(cls, folder):
            cfg = json.load(open(os.path.join(pack, folder, "config.json")))
            m = cls(**{k: v for k, v in cfg.items() if not k.startswith("_")})
            m.load_state_dict({k: v.float() for k, v in st_read_dir(os.path.join(pack, folder)).items()}, strict=True)
            return m

        self.t5 = t5("model/text_encoder")
        self.t5_bf16_weights = t5("model_bf16/text_encoder")
        self.transformer = diffusers_model(mtr.CogVideoXTransformer3DModel, "model/transformer")
        self.transformer_bf16_weights = diffusers_model(mtr.CogVideoXTransformer3DModel, "model_bf16/transformer")
        self.vae = diffusers_model(akl.AutoencoderKLCogVideoX, "model/vae")
        self.scaling = self.vae.config.scaling_factor
        for m in (self.t5, self.t5_bf16_weights, self.transformer, self.transformer_bf16_weights, self.vae):
            m.eval()
            if bf16:
                m.to(torch.bfloat16)

    def call(self, fn, *args, keep=(), **kwargs):
        """A model call: in the bf16 run, floating inputs cast to bf16 (except the keyword arguments in `keep`, passed
        as the library passes them) and floating outputs back to fp32."""
        if self.bf16:
            args = [torch_bf16.to_bf16(a) for a in args]
            kwargs = {k: (v if k in keep else torch_bf16.to_bf16(v)) for k, v in kwargs.items()}
        with torch.no_grad():
            return torch_bf16.to_f32(fn(*args, **kwargs))

    # ------------------------------------------------------------------------------------------------ T5
    def t5_encode(self, ids, mask=None, hidden=False, model=None):
        m = model or self.t5
        out = self.call(lambda i, a: m(input_ids=i, attention_mask=a, output_hidden_states=hidden), ids, mask)
        return (out.last_hidden_state, out.hidden_states) if hidden else out.last_hidden_state

    # ------------------------------------------------------------------------------------------------ transformer
    def transformer_forward(self, latent, text, t, rope, model=None, taps=None):
        m = model or self.transformer
        handles = []
        if taps is not None:
            def tap(name):
                return lambda mod, inp, out: taps.__setitem__(name, torch_bf16.to_f32(out))
            handles.append(m.time_embedding.register_forward_hook(tap("time_embedding")))
            handles.append(m.patch_embed.register_forward_hook(tap("patch_embed")))
            for i, b in enumerate(m.transformer_blocks):
                handles.append(b.register_forward_hook(tap(f"block{i}")))
            handles.append(m.norm_final.register_forward_hook(tap("norm_final")))
            handles.append(m.proj_out.register_forward_hook(tap("proj_out")))
        timestep = torch.full((latent.shape[0],), int(t), dtype=torch.long)
        out = self.call(lambda x, e, **k: m(hidden_states=x, encoder_hidden_states=e, return_dict=False, **k)[0],
                        latent, text, timestep=timestep, image_rotary_emb=rope, keep=("image_rotary_emb",))
        for h in handles:
            h.remove()
        return out

    # ------------------------------------------------------------------------------------------------ VAE
    def decode(self, z):
        return self.call(lambda v: self.vae.decode(v).sample, z)


def posterior(models, video):
    """(moments, mean, std) of the VAE posterior, each as the run returns it."""
    d = models.call(lambda v: models.vae.encode(v).latent_dist, video)
    return (torch_bf16.to_f32(d.parameters), torch_bf16.to_f32(d.mean), torch_bf16.to_f32(d.std))


def load(pack, rel):
    return torch.from_numpy(np.load(os.path.join(pack, rel)))


def ids(pack, rel):
    return load(pack, rel).long()


def run_models(m, pack, cases, settings):
    """Every model golden of the pack as {relative path: tensor}, computed by `m` (fp32 or the bf16 run)."""
    out = {}
    # T5 (case t5_masked, t5_masked_layers, t5_nomask, t5_text_to_embeddings, t5_e2e_prompts, bf16_sharded)
    masked_ids = ids(pack, "t5/masked_input_ids.npy")
    last, hidden = m.t5_encode(masked_ids, ids(pack, "t5/masked_attention_mask.npy"), hidden=True)
    out["t5/masked_last_hidden_state.npy"] = last
    for i, h in enumerate(hidden):
        out[f"t5/masked_hidden_state_{i}.npy"] = torch_bf16.to_f32(h)
    out["t5/nomask_last_hidden_state.npy"] = m.t5_encode(masked_ids)
    out["t5/text_embeds.npy"] = m.t5_encode(ids(pack, "t5/text_input_ids.npy"))
    for name in ("prompt", "negative", "empty"):
        out[f"e2e/{name}_embeds.npy"] = m.t5_encode(ids(pack, f"e2e/{name}_input_ids.npy"))
    out["bf16_sharded/t5_nomask_last_hidden_state.npy"] = m.t5_encode(masked_ids, model=m.t5_bf16_weights)

    # transformer (transformer_t999 with its taps, transformer_t500, bf16_sharded)
    latent, text = load(pack, "transformer/hidden_states.npy"), load(pack, "transformer/encoder_hidden_states.npy")
    rope = (load(pack, "transformer/rope_cos.npy"), load(pack, "transformer/rope_sin.npy"))
    for t, tapped in ((999, ["time_embedding", "patch_embed", "block0", "block1", "norm_final", "proj_out"]),
                      (500, ["time_embedding", "block0"])):
        taps = {}
        out[f"transformer/output_t{t}.npy"] = m.transformer_forward(latent, text, t, rope, taps=taps)
        for name in tapped:
            if name.startswith("block"):
                out[f"transformer/t{t}_{name}_hidden.npy"], out[f"transformer/t{t}_{name}_encoder.npy"] = taps[name]
            else:
                out[f"transformer/t{t}_{name}.npy"] = taps[name]
    out["bf16_sharded/transformer_output_t999.npy"] = m.transformer_forward(latent, text, 999, rope,
                                                                           model=m.transformer_bf16_weights)

    # VAE (vae_encode, vae_decode, vae_tiled, vae_frame_batching, vae_decode_even_latent)
    s = m.scaling
    video = load(pack, "vae/video.npy")
    moments, mean, std = posterior(m, video)
    out.update({"vae/encode_moments.npy": moments, "vae/encode_mean.npy": mean, "vae/encode_std.npy": std,
                "vae/encode_scaled_latent.npy": mean * s})
    out["vae/decode_frames.npy"] = m.decode(load(pack, "vae/encode_scaled_latent.npy") / s)
    _, out["vae/chunk17_encode_mean.npy"], out["vae/chunk17_encode_std.npy"] = posterior(m, load(pack, "vae/chunk17_video.npy"))
    out["vae/chunk17_decode_frames.npy"] = m.decode(load(pack, "vae/chunk17_encode_mean.npy"))
    for name in ("even4", "even2"):
        out[f"vae/{name}_decode_frames.npy"] = m.decode(load(pack, f"vae/{name}_scaled_latent.npy") / s)
    tiling = cases["vae_tiled"]["tiling"]
    m.vae.enable_tiling(**tiling)
    _, out["vae/tiled_encode_mean.npy"], out["vae/tiled_encode_std.npy"] = posterior(m, video)
    out["vae/tiled_decode_frames.npy"] = m.decode(load(pack, "vae/encode_scaled_latent.npy") / s)
    m.vae.disable_tiling()

    out.update(run_chain(m, pack, cases, settings, rope))
    return out


def run_chain(m, pack, cases, settings, rope):
    """The end-to-end harness chain (cases e2e_*), from its first inputs, as the pack describes it."""
    sched = importlib.import_module("diffusers.schedulers.scheduling_ddim_cogvideox")
    inverse = importlib.import_module("diffusers.schedulers.scheduling_ddim_inverse")
    cfg = {k: v for k, v in json.load(open(os.path.join(pack, "model", "scheduler", "scheduler_config.json"))).items()
           if not k.startswith("_")}
    s, g = m.scaling, settings["guidance_scale"]
    bfchw = lambda x: x.permute(0, 2, 1, 3, 4)  # noqa: E731  (VAE B,C,F,H,W <-> diffusion B,F,C,H,W)
    out = {}

    # The video posterior (x0 of the inversion, mu / sigma / x0 of K-RNR) and the image latent.
    _, mean, std = posterior(m, load(pack, "vae/video.npy"))
    out["e2e/video_posterior_mean.npy"], out["e2e/video_posterior_std.npy"] = mean, std
    x0_mean = bfchw(s * mean)
    out["e2e/inversion_x0.npy"] = x0_mean
    _, img_mean, img_std = posterior(m, load(pack, "e2e/image.npy")[:, :, None])
    out["e2e/image_posterior_mean.npy"], out["e2e/image_posterior_std.npy"] = img_mean, img_std
    img = bfchw(s * (img_mean + img_std * load(pack, "e2e/image_sample_noise.npy")))
    fl = x0_mean.shape[1]
    image_latents = torch.cat([img, torch.zeros((1, fl - 1) + tuple(img.shape[2:]))], dim=1)
    out["e2e/image_latents.npy"] = image_latents
    krnr_x0 = bfchw(s * (mean + std * load(pack, "e2e/video_sample_noise.npy")))
    out["e2e/krnr_x0.npy"] = krnr_x0

    def guided_step(x, t, text, prefix):
        both = torch.cat([torch.cat([x, x]), torch.cat([image_latents, image_latents])], dim=2)
        v = m.transformer_forward(both, text, t, rope)
        uncond, cond = v.chunk(2)
        if prefix:
            out[f"{prefix}_model_uncond.npy"], out[f"{prefix}_model_cond.npy"] = uncond, cond
        return uncond + g * (cond - uncond)

    # Inversion (e2e_inversion): both CFG halves use T5("").
    empty = load(pack, "e2e/empty_embeds.npy")
    inv = inverse.DDIMInverseScheduler(**cfg)
    inv.set_timesteps(settings["num_inversion_steps"])
    assert [int(t) for t in inv.timesteps] == cases["e2e_inversion"]["timesteps"], inv.timesteps
    x = x0_mean
    for i, t in enumerate(inv.timesteps):
        prefix = f"e2e/inversion_step{i}_t{int(t)}"
        v = guided_step(x, int(t), torch.cat([empty, empty]), prefix)
        x = inv.step(v, t, x, return_dict=False)[0]
        out[f"{prefix}_latent.npy"] = x
    eps = x
    out["e2e/eps_inv.npy"] = eps

    # K-RNR (e2e_krnr: the official per-element analytic AdaIN, k = 10, delta = 2, 3 rounds) and its paper variant.
    k = cases["e2e_krnr"]
    mu, sigma = bfchw(s * mean), bfchw(s * std)
    e = eps
    for r in range(k["rounds"]):
        eps_k = k["m_k"] * krnr_x0 + k["n_k"] * e
        eps_d = k["m_delta"] * krnr_x0 + k["n_delta"] * e
        cur_mean, cur_std = k["m_k"] * mu + k["n_k"] * e, k["m_k"] * sigma
        tgt_mean, tgt_std = k["m_delta"] * mu + k["n_delta"] * e, k["m_delta"] * sigma
        e = (eps_k - cur_mean) / (cur_std + 1e-9) * tgt_std + tgt_mean
        out[f"e2e/krnr_round{r}_eps_k.npy"], out[f"e2e/krnr_round{r}_eps_delta.npy"] = eps_k, eps_d
        out[f"e2e/krnr_round{r}_out.npy"] = e
    x_init = e
    out["e2e/x_init.npy"] = x_init
    b = cases["e2e_krnr_brief_variant"]
    bk, bd = b["c_k"] * krnr_x0 + b["r_k"] * eps, b["c_delta"] * krnr_x0 + b["r_delta"] * eps
    dims = (1, 3, 4)  # per channel over (F, H, W) of B,F,C,H,W
    out["e2e/brief_eps_k.npy"], out["e2e/brief_eps_delta.npy"] = bk, bd
    out["e2e/brief_x_init.npy"] = ((bk - bk.mean(dims, keepdim=True)) / bk.std(dims, unbiased=False, keepdim=True)
                                   * bd.std(dims, unbiased=False, keepdim=True) + bd.mean(dims, keepdim=True))

    # Sampling (e2e_sampling) over the strength-truncated timesteps, the decode, and the pipeline call (all steps).
    text = torch.cat([load(pack, "e2e/negative_embeds.npy"), load(pack, "e2e/prompt_embeds.npy")])
    steps = settings["num_inference_steps"]

    def sample(timesteps, record):
        sch = sched.CogVideoXDDIMScheduler(**cfg)
        sch.set_timesteps(steps)
        x = x_init
        for i, t in enumerate(timesteps):
            prefix = f"e2e/sampling_step{i}_t{t}" if record else None
            guided = guided_step(x, t, text, prefix)
            x, pred = sch.step(guided, torch.tensor(t), x, return_dict=False)
            if record:
                out[f"{prefix}_guided.npy"], out[f"{prefix}_pred_x0.npy"], out[f"{prefix}_latent.npy"] = guided, pred, x
        return x

    final = sample([int(t) for t in load(pack, "e2e/sampling_timesteps.npy")], True)
    out["e2e/final_latent.npy"] = final
    out["e2e/final_frames.npy"] = m.decode(bfchw(final) / s)
    out["e2e/pipeline_call_latents.npy"] = sample(cases["e2e_pipeline_call"]["timesteps"], False)
    return out


def tolerance_of(cases, rel):
    """The pack's tolerance for a golden file: its case's (encode/decode parts by file name; frames_atol for frames)."""
    for c in cases.values():
        if any(f.get("file") == rel for f in c.get("files", [])) or rel.startswith("bf16_sharded/") and c["name"] == "bf16_sharded":
            t = c["tolerance"]
            if "t5" in t:
                t = t["t5" if "t5" in rel else "transformer"]
            if "encode" in t:
                t = t["decode" if "decode" in rel else "encode"]
            if rel.endswith("frames.npy") and "frames_atol" in t:
                return t["frames_atol"], 0.0
            return t["atol"], t["rtol"]
    raise SystemExit(f"{rel}: no case of cases.json lists it")


def case_of(cases, rel):
    order = ["t5_masked", "t5_masked_layers", "t5_nomask", "t5_text_to_embeddings", "t5_e2e_prompts", "bf16_sharded",
             "transformer_t999", "transformer_t500", "vae_encode", "vae_decode", "vae_tiled", "vae_frame_batching",
             "vae_decode_even_latent", "e2e_image_latents", "e2e_inversion", "e2e_krnr", "e2e_krnr_brief_variant",
             "e2e_sampling", "e2e_pipeline_call"]
    for name in order:
        c = cases[name]
        if any(f.get("file") == rel and f.get("role") != "input" for f in c.get("files", [])):
            return name
    for name in order:
        if any(f.get("file") == rel for f in cases[name].get("files", [])):
            return name
    return "e2e_krnr" if rel.startswith("e2e/video_posterior") else "unlisted"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--diffusers", required=True, help="the src/ folder of a diffusers source tree")
    ap.add_argument("--transformers", required=True, help="the src/ folder of a transformers source tree")
    ap.add_argument("--pack", required=True, help="the pack folder")
    args = ap.parse_args()
    torch.set_num_threads(1)  # the fp32 goldens were made with one thread; sums in the same order
    library_stubs.install_diffusers(args.diffusers)
    library_stubs.install_transformers(args.transformers)
    index = json.load(open(os.path.join(args.pack, "cases.json")))
    cases, settings = {c["name"]: c for c in index["cases"]}, index["e2e_settings"]

    print("float32 run (must reproduce the pack):")
    fp32 = run_models(Models(args.pack, bf16=False), args.pack, cases, settings)
    reproduced = {}
    for rel, value in fp32.items():
        golden = np.load(os.path.join(args.pack, rel))
        torch_bf16.check_reproduces(rel, value, golden, *tolerance_of(cases, rel), reproduced)

    print("bf16 run:")
    writer = torch_bf16.Writer(args.pack)
    for rel, value in run_models(Models(args.pack, bf16=True), args.pack, cases, settings).items():
        writer.put(case_of(cases, rel), rel, value)
    writer.write_index({
        "definition": torch_bf16.__doc__.split("\n\n")[1].strip(),
        "measure": "max_abs = max |bf16 - golden|; rel_l2 = ||bf16 - golden||_2 / ||golden||_2 (per file)",
        "rule": "a dvs result computed with 16-bit-operand kernels passes when its max_abs and its rel_l2 against "
                "the fp32 golden are each at most 2x the bf16 run's (docs/testing.md)",
        "generated_by": {"script": "tests/golden_tools/make_torch_bf16_cogvideox.py",
                         "diffusers": f"github:huggingface/diffusers {DIFFUSERS_COMMIT}",
                         "transformers": f"upstream commit {TRANSFORMERS_COMMIT}",
                         "torch": torch.__version__, "device": "cpu", "threads": 1},
        "shims": library_stubs.TORCH_SHIMS + library_stubs.DIFFUSERS_SHIMS + library_stubs.TRANSFORMERS_SHIMS,
        "fp32_reproduces_pack_max_abs_diff": reproduced,
    })


if __name__ == "__main__":
    main()
