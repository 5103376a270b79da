"""Imports diffusers' and transformers' model modules straight from their source trees, without the packages'
__init__ files (which import the whole library and its Hub dependencies, absent here), on Debian's torch 1.13; and
Video-Depth-Anything's from its source tree (install_vda: the shims its pack's fp32 goldens used, and a bf16
conv_transpose2d, which torch 1.13 lacks on the CPU).

Only modules without model math are replaced (config registration, logging, the model base classes, output
containers, Hub and accelerator helpers, imports a model never calls); every layer the golden tools run is the
library's own code. Each replacement is listed in DIFFUSERS_SHIMS / TRANSFORMERS_SHIMS / TORCH_SHIMS / VDA_SHIMS,
which the tools record beside what they write; each tool first reproduces the pack's own float32 goldens with these
imports, which is the check that no stub changes a number.
"""
import dataclasses
import inspect
import logging as pylogging
import os
import sys
import types
from collections import OrderedDict

import torch
import torch.nn as nn
import torch.nn.functional as F

TORCH_SHIMS = [
    "torch.nn.functional.scaled_dot_product_attention (absent in torch 1.13) := softmax(Q K^T * scale + mask) V "
    "computed in float32 from the operands and returned in their dtype (what the pack's float32 goldens used; for "
    "bf16 operands it is what torch >= 2.5's math backend and the flash kernels do: 16-bit operands, float32 "
    "scores, softmax and accumulation, a 16-bit result)",
]

DIFFUSERS_SHIMS = [
    "diffusers, diffusers.models, .autoencoders, .transformers, .unets, diffusers.schedulers := bare packages over "
    "the source tree (their __init__ files, which import the whole library, are not run)",
    "diffusers.configuration_utils := ConfigMixin (empty) and register_to_config (records the bound __init__ "
    "arguments as self.config before __init__ runs, as diffusers does)",
    "diffusers.models.modeling_utils.ModelMixin := torch.nn.Module; loaders.PeftAdapterMixin, "
    "loaders.single_file_model.FromOriginalModelMixin, models.cache_utils.CacheMixin := empty classes "
    "(LoRA, checkpoint conversion and caching hooks, none used)",
    "diffusers.utils := logging.get_logger, deprecate (no-op), BaseOutput (a dataclass base with tuple-style "
    "indexing, as diffusers' own), is_torch_version, is_*_available() = False, apply_lora_scale (identity "
    "decorator: no LoRA), USE_PEFT_BACKEND = False; utils.accelerate_utils.apply_forward_hook := identity; "
    "utils.torch_utils.randn_tensor := torch.randn with the generator (unused on the golden paths), "
    "maybe_allow_in_graph := identity, maybe_adjust_dtype_for_device := identity (CPU keeps every dtype)",
    "diffusers.image_processor.IPAdapterMaskProcessor := placeholder (IP-Adapter masks, unused)",
    "diffusers.models.unets.unet_2d_blocks := placeholder classes (imported by the 2-D VAE code that shares "
    "vae.py; no CogVideoX VAE layer uses them)",
    "diffusers.schedulers.scheduling_utils := SchedulerMixin (empty), KarrasDiffusionSchedulers (empty enum), "
    "SchedulerOutput (BaseOutput)",
    "weights := read from the pack's safetensors by bench/gpu/torch_ref.py's reader (the file format) and loaded "
    "with load_state_dict(strict=True)",
]

TRANSFORMERS_SHIMS = [
    "transformers, transformers.models, transformers.models.t5 := bare packages over the source tree",
    "transformers.configuration_utils.PretrainedConfig := a plain attribute holder with the defaults T5 reads "
    "(is_decoder False, output_attentions / output_hidden_states False, use_return_dict True, "
    "tie_word_embeddings True); T5Config's own __init__ runs",
    "transformers.modeling_utils.PreTrainedModel := torch.nn.Module keeping .config, post_init() a no-op (weights "
    "come from the checkpoint), get_head_mask(None, n) = [None] * n as transformers' ModuleUtilsMixin",
    "transformers.utils := logging.get_logger, docstring decorators (identity), is_torchdynamo_compiling() = False, "
    "is_torch_fx_proxy() = False, DUMMY_INPUTS / DUMMY_MASK; cache_utils, generation, modeling_attn_mask_utils, "
    "pytorch_utils, onnx, utils.model_parallel_utils := placeholders (decoder caches, generation, pruning, model "
    "parallelism: none used by T5EncoderModel)",
    "transformers.modeling_outputs.BaseModelOutput* := output dataclasses with attribute access",
]


def _package(name, path):
    m = types.ModuleType(name)
    m.__path__ = [path]
    sys.modules[name] = m
    return m


def _module(name, **attrs):
    m = types.ModuleType(name)
    m.__dict__.update(attrs)
    sys.modules[name] = m
    return m


def _torch_version_is(op, version):
    have = tuple(int(p) for p in torch.__version__.split("+")[0].split("a")[0].split(".")[:2])
    want = tuple(int(p) for p in version.split(".")[:2])
    return {"<": have < want, "<=": have <= want, ">": have > want, ">=": have >= want, "==": have == want}[op]


class _OutputBase(OrderedDict):
    """Output containers: attribute access and integer indexing over the set fields, as both libraries' own."""

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if v is not None:
                self[f.name] = v

    def __getitem__(self, k):
        return list(self.values())[k] if isinstance(k, int) else super().__getitem__(k)

    def to_tuple(self):
        return tuple(self.values())


def _scaled_dot_product_attention(query, key, value, attn_mask=None, dropout_p=0.0, is_causal=False, scale=None):
    assert dropout_p == 0.0 and not is_causal, "the golden tools run inference only"
    q, k, v = query.float(), key.float(), value.float()
    s = (q @ k.transpose(-2, -1)) * (scale if scale is not None else q.shape[-1] ** -0.5)
    if attn_mask is not None:
        s = s + attn_mask.float()
    return (torch.softmax(s, dim=-1) @ v).to(query.dtype)


def install_torch_shims():
    if not hasattr(F, "scaled_dot_product_attention"):
        F.scaled_dot_product_attention = _scaled_dot_product_attention


def install_diffusers(src):
    """Makes `import diffusers.models...` read the source tree `src` (a diffusers src/ folder)."""
    install_torch_shims()
    root = os.path.join(src, "diffusers")
    _package("diffusers", root)
    _package("diffusers.models", os.path.join(root, "models"))
    for sub in ("autoencoders", "transformers", "unets"):
        _package("diffusers.models." + sub, os.path.join(root, "models", sub))
    _package("diffusers.schedulers", os.path.join(root, "schedulers"))
    _package("diffusers.loaders", os.path.join(root, "loaders"))

    @dataclasses.dataclass
    class BaseOutput(_OutputBase):
        pass

    def identity_decorator(*args, **kwargs):
        if len(args) == 1 and callable(args[0]) and not kwargs:
            return args[0]
        return lambda f: f

    unavailable = lambda *a, **k: False  # noqa: E731
    logging_mod = types.SimpleNamespace(get_logger=pylogging.getLogger)
    common = dict(
        logging=logging_mod,
        deprecate=lambda *a, **k: None,
        BaseOutput=BaseOutput,
        is_torch_version=_torch_version_is,
        is_torch_npu_available=unavailable,
        is_torch_xla_available=unavailable,
        is_torch_xla_version=unavailable,
        is_xformers_available=unavailable,
        apply_lora_scale=lambda name=None: (lambda f: f),
        USE_PEFT_BACKEND=False,
    )
    utils = _package("diffusers.utils", os.path.join(root, "utils"))
    utils.__dict__.update(common)
    _module("diffusers.utils.import_utils", **common)
    _module("diffusers.utils.logging", get_logger=pylogging.getLogger)
    _module("diffusers.utils.accelerate_utils", apply_forward_hook=lambda f: f)
    _module(
        "diffusers.utils.torch_utils",
        randn_tensor=lambda shape, generator=None, device=None, dtype=None, layout=None: torch.randn(
            shape, generator=generator, dtype=dtype),
        maybe_allow_in_graph=identity_decorator,
        maybe_adjust_dtype_for_device=lambda dtype, device: dtype,
        is_torch_version=_torch_version_is,
    )

    def register_to_config(init):
        def wrapper(self, *args, **kwargs):
            bound = inspect.signature(init).bind(self, *args, **kwargs)
            bound.apply_defaults()
            values = dict(bound.arguments)
            values.pop("self")
            values.update(values.pop("kwargs", {}))
            object.__setattr__(self, "config", types.SimpleNamespace(**values))
            init(self, *args, **kwargs)

        return wrapper

    _module("diffusers.configuration_utils", ConfigMixin=type("ConfigMixin", (), {}), register_to_config=register_to_config)
    _module("diffusers.loaders", PeftAdapterMixin=type("PeftAdapterMixin", (), {}))
    sys.modules["diffusers.loaders"].__path__ = [os.path.join(root, "loaders")]
    _module("diffusers.loaders.single_file_model", FromOriginalModelMixin=type("FromOriginalModelMixin", (), {}))
    _module("diffusers.models.modeling_utils", ModelMixin=nn.Module)
    _module("diffusers.models.cache_utils", CacheMixin=type("CacheMixin", (), {}))
    _module("diffusers.image_processor", IPAdapterMaskProcessor=type("IPAdapterMaskProcessor", (), {}))
    placeholder = type("Placeholder", (nn.Module,), {})
    _module("diffusers.models.unets.unet_2d_blocks", AutoencoderTinyBlock=placeholder, UNetMidBlock2D=placeholder,
            get_down_block=None, get_up_block=None)

    @dataclasses.dataclass
    class SchedulerOutput(BaseOutput):
        prev_sample: torch.Tensor = None

    import enum

    _module(
        "diffusers.schedulers.scheduling_utils",
        SchedulerMixin=type("SchedulerMixin", (), {}),
        KarrasDiffusionSchedulers=enum.Enum("KarrasDiffusionSchedulers", {}),
        SchedulerOutput=SchedulerOutput,
    )


def install_transformers(src):
    """Makes `import transformers.models.t5.modeling_t5` read the source tree `src` (a transformers src/ folder)."""
    install_torch_shims()
    root = os.path.join(src, "transformers")
    _package("transformers", root)
    _package("transformers.models", os.path.join(root, "models"))
    _package("transformers.models.t5", os.path.join(root, "models", "t5"))

    class PretrainedConfig:
        def __init__(self, **kwargs):
            self.is_decoder = False
            self.is_encoder_decoder = False
            self.output_attentions = False
            self.output_hidden_states = False
            self.return_dict = True
            self.tie_word_embeddings = True
            self.pruned_heads = {}
            self._attn_implementation = "eager"
            for k, v in kwargs.items():
                setattr(self, k, v)

        @property
        def use_return_dict(self):
            return self.return_dict

    class PreTrainedModel(nn.Module):
        def __init__(self, config, *args, **kwargs):
            super().__init__()
            self.config = config

        def post_init(self):
            pass

        def get_head_mask(self, head_mask, num_hidden_layers, is_attention_chunked=False):
            assert head_mask is None, "the golden tools pass no head mask"
            return [None] * num_hidden_layers

    def docstring_decorator(*args, **kwargs):
        return lambda f: f

    @dataclasses.dataclass
    class BaseModelOutput(_OutputBase):
        last_hidden_state: torch.Tensor = None
        hidden_states: tuple = None
        attentions: tuple = None

    @dataclasses.dataclass
    class BaseModelOutputWithPastAndCrossAttentions(_OutputBase):
        last_hidden_state: torch.Tensor = None
        past_key_values: tuple = None
        hidden_states: tuple = None
        attentions: tuple = None
        cross_attentions: tuple = None

    placeholder = type("Placeholder", (), {})
    utils = dict(
        DUMMY_INPUTS=[[0]],
        DUMMY_MASK=[[1]],
        add_start_docstrings=docstring_decorator,
        add_start_docstrings_to_model_forward=docstring_decorator,
        replace_return_docstrings=docstring_decorator,
        is_torch_fx_proxy=lambda x: False,
        is_torchdynamo_compiling=lambda: False,
        logging=types.SimpleNamespace(get_logger=pylogging.getLogger),
    )
    _module("transformers.utils", **utils)
    _module("transformers.utils.model_parallel_utils", assert_device_map=None, get_device_map=None)
    _module("transformers.configuration_utils", PretrainedConfig=PretrainedConfig)
    _module("transformers.modeling_utils", PreTrainedModel=PreTrainedModel)
    _module("transformers.cache_utils", Cache=placeholder, DynamicCache=placeholder, EncoderDecoderCache=placeholder,
            StaticCache=placeholder)
    _module("transformers.generation", GenerationMixin=placeholder)
    _module("transformers.onnx", OnnxSeq2SeqConfigWithPast=placeholder)
    _module("transformers.modeling_attn_mask_utils", AttentionMaskConverter=placeholder)
    _module("transformers.pytorch_utils", ALL_LAYERNORM_LAYERS=[], find_pruneable_heads_and_indices=None,
            prune_linear_layer=None)
    outputs = {n: placeholder for n in ("Seq2SeqLMOutput", "Seq2SeqModelOutput", "Seq2SeqQuestionAnsweringModelOutput",
                                        "Seq2SeqSequenceClassifierOutput", "TokenClassifierOutput")}
    _module("transformers.modeling_outputs", BaseModelOutput=BaseModelOutput,
            BaseModelOutputWithPastAndCrossAttentions=BaseModelOutputWithPastAndCrossAttentions, **outputs)


# ---------------------------------------------------------------------------------------------- Video-Depth-Anything
# VDA's own imports that Debian has (cv2, tqdm, easydict, torchvision: python3-opencv, python3-tqdm,
# python3-easydict, python3-torchvision) are the real packages; only these are replaced, as for pack vda-A's fp32
# goldens (tests/golden/vda-A/README.md, "Shims and harness notes").
VDA_SHIMS = [
    "einops := stand-in implementing exactly the patterns VDA's motion_module.py uses (rearrange "
    "'b c f h w -> (b f) c h w', '(b f) c h w -> b c f h w', '(b f) d c -> (b d) f c', '(b d) f c -> (b f) d c'; "
    "repeat 'b n c -> (b d) n c', never executed) by reshape/permute; Debian 12 has no python3-einops; data "
    "movement only",
    "torch.baddbmm as seen by motion_module/attention.py: calls with beta=0 are evaluated as "
    "baddbmm(zeros_like(input), b1, b2, beta=1, alpha) (torch 1.13's CPU kernel would otherwise multiply an "
    "uninitialised torch.empty buffer by 0, and NaN garbage stays NaN); the scores are alpha*(q@k^T) either way",
    "xformers: not installed, so VDA's own fallback attention (plain bmm + softmax) runs; nothing patched",
    "torch.nn.functional.conv_transpose2d on bfloat16 tensors (torch 1.13 has no CPU kernel for it: "
    "slow_conv_transpose2d is not implemented for BFloat16 and the mkldnn route fails) := the same call in float32 "
    "on the bf16 input, weight and bias, its result rounded to bfloat16 once (what GPU kernels do: 16-bit operands, "
    "float32 accumulation, a 16-bit result); float32 calls are untouched. VDA's head uses it for its two "
    "non-overlapping upsamplings (resize_layers 0 and 1)",
]

_EINOPS_PATTERNS = {
    # pattern: (the axis sizes it is given, the reshape/permute that moves the data)
    "b c f h w -> (b f) c h w": ((), lambda x: x.permute(0, 2, 1, 3, 4).reshape(-1, *x.shape[1:2], *x.shape[3:])),
    "(b f) c h w -> b c f h w": (("f",), lambda x, f: x.reshape(-1, f, *x.shape[1:]).permute(0, 2, 1, 3, 4)),
    "(b f) d c -> (b d) f c": (("f",), lambda x, f: x.reshape(-1, f, *x.shape[1:]).permute(0, 2, 1, 3).reshape(
        -1, f, x.shape[2])),
    "(b d) f c -> (b f) d c": (("d",), lambda x, d: x.reshape(-1, d, *x.shape[1:]).permute(0, 2, 1, 3).reshape(
        -1, d, x.shape[2])),
}


def _rearrange(x, pattern, **sizes):
    if pattern not in _EINOPS_PATTERNS or tuple(sizes) != _EINOPS_PATTERNS[pattern][0]:
        raise NotImplementedError(f"einops stand-in: pattern {pattern!r} with {sizes} is not one VDA uses")
    return _EINOPS_PATTERNS[pattern][1](x, *sizes.values())


def _repeat(x, pattern, **sizes):
    if pattern != "b n c -> (b d) n c":
        raise NotImplementedError(f"einops stand-in: repeat pattern {pattern!r} is not one VDA uses")
    return x.repeat_interleave(sizes["d"], dim=0)


class _TorchWithGuardedBaddbmm(types.ModuleType):
    """torch, except that baddbmm(beta=0) never reads its `input` (see VDA_SHIMS)."""

    def __init__(self):
        super().__init__("torch")

    def __getattr__(self, name):
        return getattr(torch, name)

    @staticmethod
    def baddbmm(input, batch1, batch2, *, beta=1, alpha=1, **kwargs):
        if beta == 0:
            return torch.baddbmm(torch.zeros_like(input), batch1, batch2, beta=1, alpha=alpha, **kwargs)
        return torch.baddbmm(input, batch1, batch2, beta=beta, alpha=alpha, **kwargs)


_conv_transpose2d = F.conv_transpose2d


def _conv_transpose2d_any_dtype(input, weight, bias=None, *args, **kwargs):
    if input.dtype != torch.bfloat16:
        return _conv_transpose2d(input, weight, bias, *args, **kwargs)
    return _conv_transpose2d(input.float(), weight.float(), None if bias is None else bias.float(), *args,
                             **kwargs).to(torch.bfloat16)


def install_vda(src):
    """Makes `import video_depth_anything...` and `utils.util` read the source tree `src` (a Video-Depth-Anything
    checkout's root) with the shims of VDA_SHIMS, and returns the video_depth module."""
    sys.path.insert(0, src)
    F.conv_transpose2d = _conv_transpose2d_any_dtype
    _module("einops", rearrange=_rearrange, repeat=_repeat)
    import importlib

    attention = importlib.import_module("video_depth_anything.motion_module.attention")
    attention.torch = _TorchWithGuardedBaddbmm()
    return importlib.import_module("video_depth_anything.video_depth")
