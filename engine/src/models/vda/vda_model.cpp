#include "models/vda/vda_model.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "dvs/error.hpp"
#include "io/weight_set.hpp"
#include "models/vda/vda_pos_embed.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_attention.hpp"
#include "tensor/ops_conv.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/ops_norm.hpp"
#include "tensor/ops_resize.hpp"

namespace dvs {
namespace {

std::string block(int i) { return "pretrained.blocks." + std::to_string(i) + "."; }
std::string motion(int j) { return "head.motion_modules." + std::to_string(j) + ".temporal_transformer."; }
std::string attention_block(int j, int a) {
  return motion(j) + "transformer_blocks.0.attention_blocks." + std::to_string(a) + ".";
}

// Every tensor of the checkpoint (either format: the weight loader tells them apart by content) as f32 host
// tensors.
std::map<std::string, HostTensor> read_checkpoint(const WeightSet& weights, std::map<std::string, Shape>& shapes) {
  std::map<std::string, HostTensor> out;
  for (const auto& [name, ref] : weights.entries()) {
    if (!ref.info->dtype) continue;  // e.g. integer buffers the model does not use
    HostTensor h = ref.file->load(*ref.info);
    if (h.dtype != DType::f32) {
      const auto v = h.to_f32();
      h = HostTensor::from_f32(h.shape, v);
    }
    // A NaN/Inf weight spreads to every pixel and the final ReLU hides it (a flat or zero depth): refused here.
    const float* v = h.as<float>();
    for (int64_t i = 0; i < h.numel(); ++i)
      if (!std::isfinite(v[i]))
        throw Error(ref.file->path().string() + ": tensor " + name + " holds " + (std::isnan(v[i]) ? "NaN" : "an infinite value") +
                    " (first at element " + std::to_string(i) + "): the checkpoint is damaged; download it again "
                    "(dvs-weights inspect --values " + ref.file->path().string() + " lists every such tensor)");
    shapes[name] = h.shape;
    out.emplace(name, std::move(h));
  }
  return out;
}

// ConvTranspose2d with kernel == stride (no overlap) as a Linear: weight [Cin, Cout, k, k] -> [(Cout, a, b), Cin]
// and the bias repeated over the k x k outputs of each channel.
HostTensor transposed_conv_as_linear(const HostTensor& w) {
  const int64_t cin = w.shape[0], cout = w.shape[1], kk = w.shape[2] * w.shape[3];
  HostTensor out({cout * kk, cin}, DType::f32);
  const float* s = w.as<float>();
  float* d = out.as<float>();
  for (int64_t ci = 0; ci < cin; ++ci)
    for (int64_t o = 0; o < cout * kk; ++o) d[o * cin + ci] = s[ci * cout * kk + o];
  return out;
}

HostTensor repeat_each(const HostTensor& bias, int64_t times) {
  HostTensor out({bias.numel() * times}, DType::f32);
  for (int64_t i = 0; i < out.numel(); ++i) out.as<float>()[i] = bias.as<float>()[i / times];
  return out;
}

HostTensor rows_of(const HostTensor& t, int64_t first, int64_t count) {
  const int64_t inner = t.numel() / t.shape[0];
  Shape s = t.shape;
  s[0] = count;
  HostTensor out(s, DType::f32);
  std::copy(t.as<float>() + first * inner, t.as<float>() + (first + count) * inner, out.as<float>());
  return out;
}

void run(vk::Context& ctx, const std::function<void(vk::Recorder&)>& record) { ops::run_now(ctx, record); }

Tensor empty(vk::Context& ctx, Shape s, const char* what) { return Tensor::empty(ctx, std::move(s), DType::f32, what); }

}  // namespace

VdaConfig VdaModel::inspect(const std::filesystem::path& checkpoint) {
  std::map<std::string, Shape> shapes;
  const WeightSet weights = WeightSet::open_file(checkpoint);
  for (const auto& [name, ref] : weights.entries()) shapes[name] = ref.info->shape;
  return resolve_vda_config(checkpoint, shapes);
}

VdaModel VdaModel::load(vk::Context& ctx, const std::filesystem::path& checkpoint) {
  std::map<std::string, Shape> shapes;
  std::map<std::string, HostTensor> host = read_checkpoint(WeightSet::open_file(checkpoint), shapes);
  VdaModel m(ctx, resolve_vda_config(checkpoint, shapes));
  m.file_ = checkpoint;
  auto need = [&](const std::string& name) -> HostTensor& {
    auto it = host.find(name);
    if (it == host.end())
      throw Error(checkpoint.string() + ": tensor " + name + " is missing (not a Video-Depth-Anything checkpoint?)");
    return it->second;
  };
  // Derived layouts, computed once here: transposed convs as Linears, the GEGLU projection split into its value
  // and gate halves (so the gate's GELU fuses into its Linear), the position table kept on the host.
  for (int i = 0; i < 2; ++i) {
    const std::string p = "head.resize_layers." + std::to_string(i) + ".";
    const HostTensor& wt = need(p + "weight");
    host[p + "linear_weight"] = transposed_conv_as_linear(wt);
    host[p + "linear_bias"] = repeat_each(need(p + "bias"), wt.shape[2] * wt.shape[3]);
    host.erase(p + "weight");  // replaced by the Linear form: never uploaded
    host.erase(p + "bias");
  }
  for (int j = 0; j < 4; ++j) {
    const std::string p = motion(j) + "transformer_blocks.0.ff.net.0.proj.";
    const HostTensor& w1 = need(p + "weight");
    const HostTensor& b1 = need(p + "bias");
    const int64_t half = w1.shape[0] / 2;
    host[p + "value_weight"] = rows_of(w1, 0, half);
    host[p + "gate_weight"] = rows_of(w1, half, half);
    host[p + "value_bias"] = rows_of(b1, 0, half);
    host[p + "gate_bias"] = rows_of(b1, half, half);
    host.erase(p + "weight");  // replaced by the halves: never uploaded
    host.erase(p + "bias");
  }
  m.pos_table_ = need("pretrained.pos_embed");
  // The convolutions' weights packed once here into the layout the conv kernels read (packs_as_conv).
  for (auto& [name, t] : host) {
    if (name == "pretrained.pos_embed" || name == "pretrained.mask_token") continue;  // host table / unused
    Tensor up = Tensor::upload(ctx, t, "vda " + name);
    if (packs_as_conv(name, t.shape)) {
      ops::PackedConvWeights p = ops::packed_conv_weights_now(ctx, up, "vda " + name);
      m.weight_bytes_ += p.packed.bytes();
      m.conv_weights_.emplace(name, std::move(p));
      continue;
    }
    m.weight_bytes_ += t.bytes();
    m.weights_.emplace(name, std::move(up));
  }
  return m;
}

const Tensor& VdaModel::w(const std::string& name) const {
  auto it = weights_.find(name);
  if (it == weights_.end()) throw Error(file_.string() + ": tensor " + name + " is missing");
  return it->second;
}

bool VdaModel::packs_as_conv(const std::string& name, const Shape& shape) {
  return shape.size() == 4 && (name == "pretrained.patch_embed.proj.weight" || name == "head.resize_layers.3.weight" ||
                               (name.starts_with("head.scratch.") && name.ends_with(".weight")));
}

const ops::PackedConvWeights& VdaModel::conv_weights(const std::string& name) const {
  auto it = conv_weights_.find(name);
  if (it == conv_weights_.end()) throw Error(file_.string() + ": convolution weights " + name + " are missing");
  return it->second;
}

const Tensor& VdaModel::pos_embed(int64_t h, int64_t w) {
  auto key = std::make_pair(h, w);
  auto it = pos_embed_.find(key);
  if (it != pos_embed_.end()) return it->second;
  return pos_embed_[key] = Tensor::upload(*ctx_, vda_resample_pos_embed(pos_table_, h, w), "vda pos_embed");
}

// ---------------------------------------------------------------------------------------------- encoder

Tensor VdaModel::vit_block(int i, const Tensor& x, int64_t frames, int64_t tokens) {
  vk::Context& ctx = *ctx_;
  const int64_t d = cfg_.embed_dim, heads = cfg_.num_heads, hd = cfg_.head_dim;
  const std::string p = block(i);
  const std::string name = "encoder/block" + std::to_string(i);
  Tensor n = empty(ctx, {frames, tokens, d}, "vit norm"), qkv = empty(ctx, {frames, tokens, 3 * d}, "vit qkv");
  Tensor attn = empty(ctx, {frames, tokens, d}, "vit attention"), hidden = empty(ctx, {frames, tokens, cfg_.mlp_hidden_dim}, "vit mlp");
  ops::AttentionShape as{frames, heads, hd, tokens, tokens};
  ops::AttentionOptions ao;
  ao.scale = float(1.0 / std::sqrt(double(hd)));
  Tensor workspace;  // K/V repacked head-major: pays on CPU devices at these lengths (ops_attention.hpp)
  if (ops::attention_workspace_helps(ctx.caps(), as)) {
    workspace = empty(ctx, {ops::attention_workspace_elements(as)}, "vit attention workspace");
    ao.workspace = &workspace;
  }
  const ops::AttentionOperand out{attn, 0, 0};
  run(ctx, [&](vk::Recorder& r) {
    ops::layernorm(r, x, n, w(p + "norm1.weight"), w(p + "norm1.bias"), cfg_.vit_layer_norm_eps);
    ops::linear(r, n, w(p + "attn.qkv.weight"), qkv, {.bias = w(p + "attn.qkv.bias")});
    ops::attention(r, as, ops::fused_qkv_operand(qkv, 0, heads, hd), ops::fused_qkv_operand(qkv, 1, heads, hd),
                   ops::fused_qkv_operand(qkv, 2, heads, hd), out, ao);
  });
  probe(name + "_norm1", n);
  probe(name + "_qkv", qkv);
  probe(name + "_attn_context", attn);
  // x + ls1·proj(attention), then x + ls2·fc2(GELU(fc1(LN2(x)))): LayerScale is the Linear epilogue's gate.
  run(ctx, [&](vk::Recorder& r) {
    ops::linear(r, attn, w(p + "attn.proj.weight"), x,
                {.bias = w(p + "attn.proj.bias"), .gate = w(p + "ls1.gamma"), .residual = x});
    ops::layernorm(r, x, n, w(p + "norm2.weight"), w(p + "norm2.bias"), cfg_.vit_layer_norm_eps);
    ops::linear(r, n, w(p + "mlp.fc1.weight"), hidden, {.bias = w(p + "mlp.fc1.bias"), .activation = ops::Activation::gelu_erf});
  });
  probe(name + "_norm2", n);
  probe(name + "_gelu", hidden);
  run(ctx, [&](vk::Recorder& r) {
    ops::linear(r, hidden, w(p + "mlp.fc2.weight"), x, {.bias = w(p + "mlp.fc2.bias"), .gate = w(p + "ls2.gamma"), .residual = x});
  });
  probe(name, x);
  return x;
}

std::array<Tensor, 4> VdaModel::encode(const Tensor& x) {
  vk::Context& ctx = *ctx_;
  if (x.rank() != 4 || x.dim(1) != 3 || x.dim(2) % cfg_.patch_size || x.dim(3) % cfg_.patch_size)
    throw Error("vda encoder: input must be [T, 3, H, W] with H and W multiples of " + std::to_string(cfg_.patch_size) +
                ", got " + x.describe());
  const int64_t frames = x.dim(0), h = x.dim(2) / cfg_.patch_size, wd = x.dim(3) / cfg_.patch_size, d = cfg_.embed_dim;
  const int64_t tokens = 1 + h * wd;
  const Tensor& pe = pos_embed(h, wd);
  const HostTensor cls = w("pretrained.cls_token").download(ctx);
  std::array<Tensor, 4> taps;
  for (auto& t : taps) t = empty(ctx, {frames, h * wd, d}, "vit tap");
  // Frames are independent in the ViT: it runs a few at a time, so its temporaries (qkv, MLP hidden) stay the
  // size of a chunk. Probing runs every frame at once (whole tensors).
  const int64_t chunk = probe_ ? frames : std::clamp<int64_t>(encoder_chunk_frames_, 1, frames);
  for (int64_t f0 = 0; f0 < frames; f0 += chunk) {
    const int64_t n = std::min(chunk, frames - f0);
    Tensor patches = empty(ctx, {n, h, wd, d}, "vit patches");
    Tensor tok = empty(ctx, {n, tokens, d}, "vit tokens");
    // CLS token repeated over the frames (concatenated in front of each frame's patches).
    HostTensor cls_rows({n, 1, d}, DType::f32);
    for (int64_t f = 0; f < n; ++f) std::copy(cls.as<float>(), cls.as<float>() + d, cls_rows.as<float>() + f * d);
    Tensor cls_t = Tensor::upload(ctx, cls_rows, "vit cls");
    ops::Conv2dParams patch{int(cfg_.patch_size), 0, 0, 0, 0, true};
    run(ctx, [&](vk::Recorder& r) {
      ops::conv2d(r, x.rows(f0, n), conv_weights("pretrained.patch_embed.proj.weight"), &w("pretrained.patch_embed.proj.bias"),
                  patches, patch);
      ops::concat(r, {cls_t, patches.reshape({n, h * wd, d})}, tok, 1);
      ops::add(r, tok, pe, tok);
    });
    probe("encoder/patch_embed", patches.reshape({n, h * wd, d}));
    probe("encoder/tokens", tok);
    patches = Tensor();
    for (int b = 0; b < cfg_.depth; ++b) {
      vit_block(b, tok, n, tokens);
      step("encoder block " + std::to_string(b + 1) + "/" + std::to_string(cfg_.depth) + ", frames " +
           std::to_string(f0 + 1) + "-" + std::to_string(f0 + n));
      for (int t = 0; t < 4; ++t) {
        if (cfg_.taps[size_t(t)] != b) continue;
        Tensor normed = empty(ctx, {n, tokens, d}, "vit tap");
        Tensor cls_out = empty(ctx, {n, 1, d}, "vit tap cls");
        const Tensor tap = taps[size_t(t)].rows(f0, n);
        run(ctx, [&](vk::Recorder& r) {
          ops::layernorm(r, tok, normed, w("pretrained.norm.weight"), w("pretrained.norm.bias"), cfg_.vit_layer_norm_eps);
          ops::split(r, normed, {cls_out, tap}, 1);
        });
        probe("encoder/tap" + std::to_string(t), tap);
        probe("encoder/tap" + std::to_string(t) + "_cls", cls_out.reshape({n, d}));
      }
    }
  }
  return taps;
}

// ---------------------------------------------------------------------------------------------- temporal

Tensor VdaModel::temporal(int j, const Tensor& x, int64_t frames) {
  vk::Context& ctx = *ctx_;
  const int64_t bt = x.dim(0), c = x.dim(1), hw = x.dim(2) * x.dim(3), batch = bt / frames;
  if (bt % frames || frames > cfg_.temporal_max_len)
    throw Error("vda temporal module: " + std::to_string(bt) + " frames in the batch is not a whole number of " +
                std::to_string(frames) + "-frame windows (at most " + std::to_string(cfg_.temporal_max_len) + ")");
  const int64_t heads = cfg_.temporal_heads, hd = c / heads;
  const std::string p = motion(j), name = "temporal/m" + std::to_string(j) + "_";
  const Shape seq{batch, hw, frames, c};  // one sequence of frames per spatial position
  probe(name + "in", x);
  // Frame-major [B, T, HW, C] copies of sequence tensors, only for probes (the pack's layout).
  auto probe_frame_major = [&](const std::string& n, const Tensor& t) {
    if (!probe_) return;
    const int64_t cols = t.dim(-1);
    Tensor fm = empty(ctx, {batch * frames, hw, cols}, "probe");
    run(ctx, [&](vk::Recorder& r) { ops::permute(r, t.reshape({batch, hw, frames, cols}), fm.reshape({batch, frames, hw, cols}), {0, 2, 1, 3}); });
    probe(name + n, fm);
  };
  Tensor gn = empty(ctx, x.shape(), "temporal groupnorm");
  Tensor scratch = empty(ctx, {ops::groupnorm_scratch_elems(x.shape(), cfg_.group_norm_groups)}, "groupnorm scratch");
  Tensor tokens = empty(ctx, seq, "temporal tokens");
  run(ctx, [&](vk::Recorder& r) {
    ops::groupnorm(r, x, gn, cfg_.group_norm_groups, w(p + "norm.weight"), w(p + "norm.bias"), cfg_.group_norm_eps, false, scratch);
    ops::permute(r, gn.reshape({batch, frames, c, hw}), tokens, {0, 3, 1, 2});
  });
  probe(name + "groupnorm", gn);
  gn = Tensor();
  scratch = Tensor();
  // Every spatial position is its own sequence of frames, so the block runs on chunks of positions: its working
  // set (~14 sequence-sized tensors) stays small whatever the map size. Probing runs one chunk (whole tensors).
  const int64_t positions = batch * hw, per_position = frames * c * 4 * 14;
  const int64_t chunk = probe_ ? positions
                               : std::clamp<int64_t>(temporal_chunk_positions_ > 0 ? temporal_chunk_positions_
                                                                                  : kTemporalChunkBytes / per_position,
                                                     1, positions);
  const std::string fp = p + "transformer_blocks.0.";
  const int64_t ff = w(fp + "ff.net.0.proj.value_weight").dim(0);
  ops::AttentionOptions ao;
  ao.scale = float(1.0 / std::sqrt(double(hd)));
  for (int64_t p0 = 0; p0 < positions; p0 += chunk) {
    const int64_t n = std::min(chunk, positions - p0);
    const Shape s3{n, frames, c};
    const Tensor part = tokens.reshape({positions, frames, c}).rows(p0, n);
    Tensor hidden = empty(ctx, s3, "temporal hidden"), norm = empty(ctx, s3, "temporal norm");
    run(ctx, [&](vk::Recorder& r) { ops::linear(r, part, w(p + "proj_in.weight"), hidden, {.bias = w(p + "proj_in.bias")}); });
    probe_frame_major("proj_in", hidden);
    Tensor q = empty(ctx, s3, "temporal q"), k = empty(ctx, s3, "temporal k"), v = empty(ctx, s3, "temporal v");
    Tensor context = empty(ctx, s3, "temporal context");
    for (int a = 0; a < 2; ++a) {
      const std::string ap = attention_block(j, a), an = "attn" + std::to_string(a) + "_";
      const std::string np = fp + "norms." + std::to_string(a) + ".";
      const Tensor pe = w(ap + "pos_encoder.pe").reshape({w(ap + "pos_encoder.pe").dim(1), c}).rows(0, frames);
      run(ctx, [&](vk::Recorder& r) {
        ops::layernorm(r, hidden, norm, w(np + "weight"), w(np + "bias"), cfg_.temporal_layer_norm_eps);
      });
      probe_frame_major(an + "norm", norm);
      run(ctx, [&](vk::Recorder& r) {
        ops::add(r, norm, pe, norm);  // the position embedding reaches q, k and v
        ops::linear(r, norm, w(ap + "to_q.weight"), q);
        ops::linear(r, norm, w(ap + "to_k.weight"), k);
        ops::linear(r, norm, w(ap + "to_v.weight"), v);
        ops::attention(r, q, k, v, context, heads, ao);
        ops::linear(r, context, w(ap + "to_out.0.weight"), hidden, {.bias = w(ap + "to_out.0.bias"), .residual = hidden});
      });
      probe(name + an + "pe", norm);
      probe(name + an + "q", q);
      probe(name + an + "k", k);
      probe(name + an + "v", v);
      probe(name + an + "context", context);
    }
    q = k = v = context = Tensor();
    // GEGLU feed-forward: value · GELU_erf(gate), the halves of one projection (split at load).
    Tensor value = empty(ctx, {n, frames, ff}, "geglu value"), gate = empty(ctx, {n, frames, ff}, "geglu gate");
    run(ctx, [&](vk::Recorder& r) {
      ops::layernorm(r, hidden, norm, w(fp + "ff_norm.weight"), w(fp + "ff_norm.bias"), cfg_.temporal_layer_norm_eps);
      ops::linear(r, norm, w(fp + "ff.net.0.proj.value_weight"), value, {.bias = w(fp + "ff.net.0.proj.value_bias")});
      ops::linear(r, norm, w(fp + "ff.net.0.proj.gate_weight"), gate,
                  {.bias = w(fp + "ff.net.0.proj.gate_bias"), .activation = ops::Activation::gelu_erf});
      ops::mul(r, value, gate, value);
      ops::linear(r, value, w(fp + "ff.net.2.weight"), hidden, {.bias = w(fp + "ff.net.2.bias"), .residual = hidden});
      ops::linear(r, hidden, w(p + "proj_out.weight"), part, {.bias = w(p + "proj_out.bias")});  // in place: read
    });
    probe_frame_major("ff_norm", norm);
    probe_frame_major("geglu", value);
    probe_frame_major("block_out", hidden);
  }
  Tensor out = empty(ctx, x.shape(), "temporal out");
  run(ctx, [&](vk::Recorder& r) {
    ops::permute(r, tokens, out.reshape({batch, frames, c, hw}), {0, 2, 3, 1});
    ops::add(r, out, x, out);
  });
  probe_frame_major("proj_out", tokens);
  probe(name + "out", out);
  return out;
}

// ---------------------------------------------------------------------------------------------- DPT head

Tensor VdaModel::conv(const std::string& prefix, const Tensor& x, int stride, int pad, bool bias) {
  const ops::ConvWeights wt = conv_weights(prefix + "weight");
  ops::Conv2dParams cp{stride, pad, pad, pad, pad, false};
  Tensor y = empty(*ctx_, ops::conv2d_shape(x.shape(), wt.shape(), cp), "head conv");
  run(*ctx_, [&](vk::Recorder& r) { ops::conv2d(r, x, wt, bias ? &w(prefix + "bias") : nullptr, y, cp); });
  return y;
}

// Reassemble tap i: 1x1 projection (a Linear on the tokens), then its resize layer.
Tensor VdaModel::reassemble(int i, const Tensor& tap, int64_t h, int64_t wd) {
  vk::Context& ctx = *ctx_;
  const int64_t bt = tap.dim(0), oc = cfg_.out_channels[size_t(i)];
  const std::string p = "head.projects." + std::to_string(i) + ".";
  Tensor proj = empty(ctx, {bt, h * wd, oc}, "head projection");  // channels last
  Tensor proj_nchw = empty(ctx, {bt, oc, h, wd}, "head projection");
  run(ctx, [&](vk::Recorder& r) {
    ops::linear(r, tap, w(p + "weight").reshape({oc, cfg_.embed_dim}), proj, {.bias = w(p + "bias")});
    ops::permute(r, proj, proj_nchw.reshape({bt, oc, h * wd}), {0, 2, 1});
  });
  probe("head/project" + std::to_string(i), proj_nchw);
  if (i == 2) return proj_nchw;
  if (i == 3) return conv("head.resize_layers.3.", proj_nchw, 2, 1, true);
  // ConvTranspose2d, kernel = stride = k: a Linear to (Cout, a, b) per token, then each token's k x k block is
  // put in place: [BT, h, w, Cout, k, k] -> [BT, Cout, h, k, w, k].
  const std::string rp = "head.resize_layers." + std::to_string(i) + ".";
  const int64_t kk = w(rp + "linear_weight").dim(0) / oc;  // k x k outputs per channel (kernel = stride = k)
  const int64_t k = std::lround(std::sqrt(double(kk)));
  Tensor up = empty(ctx, {bt, h * wd, oc * k * k}, "head transposed conv");
  Tensor y = empty(ctx, {bt, oc, h * k, wd * k}, "head resize");
  run(ctx, [&](vk::Recorder& r) {
    ops::linear(r, proj, w(rp + "linear_weight"), up, {.bias = w(rp + "linear_bias")});
    ops::permute(r, up.reshape({bt, h, wd, oc, k, k}), y.reshape({bt, oc, h, k, wd, k}), {0, 3, 1, 4, 2, 5});
  });
  return y;
}

// RCU(x) = x + conv2(ReLU(conv1(ReLU(x)))), 3x3 convs with bias.
Tensor VdaModel::residual_conv_unit(const std::string& p, const Tensor& x) {
  Tensor a = empty(*ctx_, x.shape(), "rcu relu");
  run(*ctx_, [&](vk::Recorder& r) { ops::relu(r, x, a); });
  Tensor b = conv(p + "conv1.", a, 1, 1, true);
  run(*ctx_, [&](vk::Recorder& r) { ops::relu(r, b, b); });
  Tensor c = conv(p + "conv2.", b, 1, 1, true);
  run(*ctx_, [&](vk::Recorder& r) { ops::add(r, c, x, c); });
  return c;
}

// FeatureFusionBlock: out_conv(resize(RCU2(x0 + RCU1(x1)))), bilinear with align_corners.
Tensor VdaModel::fusion(int i, const Tensor& x0, const Tensor* x1, int64_t out_h, int64_t out_w) {
  const std::string p = "head.scratch.refinenet" + std::to_string(i) + ".";
  Tensor sum = x0;
  if (x1) {
    Tensor res = residual_conv_unit(p + "resConfUnit1.", *x1);
    sum = empty(*ctx_, x0.shape(), "fusion sum");
    run(*ctx_, [&](vk::Recorder& r) { ops::add(r, x0, res, sum); });
  }
  Tensor refined = residual_conv_unit(p + "resConfUnit2.", sum);
  Tensor resized = empty(*ctx_, {x0.dim(0), x0.dim(1), out_h, out_w}, "fusion resize");
  run(*ctx_, [&](vk::Recorder& r) { ops::resize_bilinear(r, refined, resized, true); });
  return conv(p + "out_conv.", resized, 1, 0, true);
}

Tensor VdaModel::head(std::array<Tensor, 4> taps, int64_t h, int64_t wd, int64_t frames) {
  std::array<Tensor, 4> layer;
  for (int i = 0; i < 4; ++i) {
    layer[size_t(i)] = reassemble(i, taps[size_t(i)], h, wd);
    taps[size_t(i)] = Tensor();  // freed as soon as it is reassembled
    probe("head/layer" + std::to_string(i + 1), layer[size_t(i)]);
  }
  layer[2] = temporal(0, layer[2], frames);
  step("head temporal module 1/4");
  layer[3] = temporal(1, layer[3], frames);
  step("head temporal module 2/4");
  std::array<Tensor, 4> rn;
  for (int i = 0; i < 4; ++i) {
    rn[size_t(i)] = conv("head.scratch.layer" + std::to_string(i + 1) + "_rn.", layer[size_t(i)], 1, 1, false);
    probe("head/layer" + std::to_string(i + 1) + "_rn", rn[size_t(i)]);
    layer[size_t(i)] = Tensor();  // the reassembled maps are not read again
  }
  Tensor path4 = fusion(4, rn[3], nullptr, rn[2].dim(2), rn[2].dim(3));
  probe("head/refinenet4", path4);
  path4 = temporal(2, path4, frames);
  step("head temporal module 3/4");
  Tensor path3 = fusion(3, path4, &rn[2], rn[1].dim(2), rn[1].dim(3));
  probe("head/refinenet3", path3);
  path3 = temporal(3, path3, frames);
  step("head temporal module 4/4");
  // refinenet2, refinenet1 and the output convolutions run a few frames at a time, as the reference does: at the
  // real size their maps are the model's largest (32 channels at 14h x 14w, ~61 MiB a frame). Frames are
  // independent there, so the chunking changes no value.
  const int64_t ps = cfg_.patch_size;
  const int64_t chunk = micro_batch_ > 0 ? std::min<int64_t>(micro_batch_, frames) : frames;
  Tensor out = empty(*ctx_, {frames, 1, h * ps, wd * ps}, "head output");
  std::map<std::string, Tensor> whole;  // the chunked stages reassembled for the probe (only when probing)
  auto keep = [&](const std::string& name, const Tensor& part, int64_t first) {
    if (!probe_) return;
    auto it = whole.find(name);
    if (it == whole.end()) {
      Shape s = part.shape();
      s[0] = frames;
      it = whole.emplace(name, empty(*ctx_, s, "probe copy")).first;
    }
    run(*ctx_, [&](vk::Recorder& r) { ops::scale(r, part, it->second.rows(first, part.dim(0)), 1.0f); });
  };
  for (int64_t f0 = 0; f0 < frames; f0 += chunk) {
    const int64_t n = std::min(chunk, frames - f0);
    const Tensor rn0 = rn[0].rows(f0, n), rn1 = rn[1].rows(f0, n);
    Tensor path2 = fusion(2, path3.rows(f0, n), &rn1, rn0.dim(2), rn0.dim(3));
    keep("head/refinenet2", path2, f0);
    Tensor path1 = fusion(1, path2, &rn0, 2 * rn0.dim(2), 2 * rn0.dim(3));
    path2 = Tensor();
    keep("head/refinenet1", path1, f0);
    Tensor out1 = conv("head.scratch.output_conv1.", path1, 1, 1, true);
    path1 = Tensor();
    keep("head/output_conv1", out1, f0);
    Tensor up = empty(*ctx_, {n, out1.dim(1), h * ps, wd * ps}, "head output resize");
    run(*ctx_, [&](vk::Recorder& r) { ops::resize_bilinear(r, out1, up, true); });
    out1 = Tensor();
    if (f0 == 0) probe("head/output_interp_frame0", up.rows(0, 1));
    Tensor hidden = conv("head.scratch.output_conv2.0.", up, 1, 1, true);
    up = Tensor();
    run(*ctx_, [&](vk::Recorder& r) { ops::relu(r, hidden, hidden); });
    Tensor part = conv("head.scratch.output_conv2.2.", hidden, 1, 0, true);
    run(*ctx_, [&](vk::Recorder& r) { ops::relu(r, part, out.rows(f0, n)); });
    step("head full resolution, frames " + std::to_string(f0 + 1) + "-" + std::to_string(f0 + n));
  }
  for (const auto& [name, t] : whole) probe(name, t);
  probe("head/output", out);
  return out;
}

void VdaModel::step(const std::string& what) {
  if (step_hook_) step_hook_(what, ++steps_done_, steps_total_);
}

Tensor VdaModel::forward(const Tensor& x) {
  const int64_t frames = x.dim(0), ps = cfg_.patch_size;
  const int64_t h = x.dim(2) / ps, wd = x.dim(3) / ps;
  // The steps step() reports: every block of every encoder chunk, the four temporal modules, the tail's chunks
  // (chunk sizes as encode() and head() choose them).
  auto chunks = [&](int64_t chunk) { return int((frames + chunk - 1) / chunk); };
  const int64_t encoder_chunk = probe_ ? frames : std::clamp<int64_t>(encoder_chunk_frames_, 1, frames);
  steps_done_ = 0;
  steps_total_ = chunks(encoder_chunk) * cfg_.depth + 4 + chunks(micro_batch_ > 0 ? std::min<int64_t>(micro_batch_, frames) : frames);
  Tensor out = head(encode(x), h, wd, frames);
  // forward() resizes to the input size (the head's 14h x 14w already is) and applies ReLU again: both identities
  // on a ReLU output of the input's size.
  return out.reshape({frames, h * ps, wd * ps});
}

}  // namespace dvs
