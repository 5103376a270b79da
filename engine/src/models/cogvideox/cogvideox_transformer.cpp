#include "models/cogvideox/cogvideox_transformer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <string>

#include "dvs/error.hpp"
#include "models/activation_plan.hpp"
#include "tensor/ops_attention.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/ops_norm.hpp"
#include "tensor/ops_position.hpp"
#include "vk/context.hpp"

namespace dvs::models {

namespace {

std::string blk(int64_t i) { return "transformer_blocks." + std::to_string(i) + "."; }

}  // namespace

// The per-block tables (mod1, mod2) are made at each block's start from its own norm1/norm2 weights; q, attn and
// ff are views of `region` for the chunk at hand (q and the attention output side by side, the FFN's hidden state
// over both once they are dead).
struct CogVideoXTransformer::Activations {
  Tensor tproj, t1, emb, semb, mod1, mod2, out_mod, patches, h, xn, k, v, region, proj, lora_tmp;
  VkDeviceSize attn_offset = 0;  // bytes into `region` where a chunk's attention output starts
};

CogVideoXTransformer::CogVideoXTransformer(vk::Context& ctx, const std::filesystem::path& dir, WeightResidency residency,
                                           int stream_slots)
    : CogVideoXTransformer(ctx, ComponentWeights(ctx, dir), residency, stream_slots) {}

CogVideoXTransformer::CogVideoXTransformer(vk::Context& ctx, ComponentWeights weights, WeightResidency residency,
                                           int stream_slots)
    : ctx_(ctx),
      weights_(std::move(weights)),
      cfg_(CogVideoXTransformerConfig::from_json(weights_.config(), (weights_.dir() / "config.json").string())) {
  check_weights(residency, stream_slots);
}

void CogVideoXTransformer::check_weights(WeightResidency residency, int stream_slots) {
  // Upload (and shape-check) everything at load so a bad checkpoint fails here, not mid-recording. Streamed
  // block weights are shape-checked from their headers and go to host memory instead.
  const int64_t D = cfg_.dim(), T = cfg_.time_embed_dim, p = cfg_.patch_size, Dh = cfg_.head_dim;
  std::vector<std::vector<std::string>> streamed(size_t(cfg_.num_layers));
  int64_t block = -1;  // the block being checked (-1: outside the blocks)
  auto need = [&](const std::string& name, const Shape& shape) {
    if (block < 0 || residency == WeightResidency::resident) {
      weights_.get(name, shape);
    } else {
      weights_.check(name, shape);
      streamed[size_t(block)].push_back(name);
    }
  };
  // Every Linear's weight feeds only a GEMM: kept in the tensor cores' operand type where they run it.
  const bool f16_gemm_weights = ops::gemm_weight_dtype(ctx_.caps()) == DType::f16;
  auto lin = [&](const std::string& name, int64_t in, int64_t out, bool bias) {
    if (f16_gemm_weights) weights_.store_as(name + ".weight", DType::f16);
    need(name + ".weight", {out, in});
    if (bias) need(name + ".bias", {out});
  };
  auto ln = [&](const std::string& name, int64_t n, bool affine) {
    if (!affine) return;
    need(name + ".weight", {n});
    need(name + ".bias", {n});
  };
  weights_.get("patch_embed.proj.weight", {D, cfg_.in_channels, p, p});
  if (weights_.has("patch_embed.proj.bias")) weights_.get("patch_embed.proj.bias", {D});
  lin("patch_embed.text_proj", cfg_.text_embed_dim, D, true);
  lin("time_embedding.linear_1", D, T, true);
  lin("time_embedding.linear_2", T, T, true);
  for (int64_t i = 0; i < cfg_.num_layers; ++i) {
    block = i;
    const std::string b = blk(i);
    lin(b + "norm1.linear", T, 6 * D, true);
    ln(b + "norm1.norm", D, cfg_.norm_affine);
    ln(b + "attn1.norm_q", Dh, true);
    ln(b + "attn1.norm_k", Dh, true);
    for (const char* n : {"to_q", "to_k", "to_v"}) lin(b + "attn1." + n, D, D, cfg_.attention_bias);
    lin(b + "attn1.to_out.0", D, D, true);
    lin(b + "norm2.linear", T, 6 * D, true);
    ln(b + "norm2.norm", D, cfg_.norm_affine);
    lin(b + "ff.net.0.proj", D, 4 * D, true);
    lin(b + "ff.net.2", 4 * D, D, true);
  }
  block = -1;
  ln("norm_final", D, cfg_.norm_affine);
  lin("norm_out.linear", T, 2 * D, true);
  ln("norm_out.norm", D, cfg_.norm_affine);
  lin("proj_out", D, p * p * cfg_.out_channels, true);
  if (residency == WeightResidency::stream && cfg_.num_layers > 0)
    stream_ = std::make_unique<BlockStream>(
        ctx_, weights_, cfg_.num_layers, [&](int64_t i) { return streamed[size_t(i)]; }, stream_slots,
        "transformer blocks");
}

Tensor CogVideoXTransformer::block_weight(int64_t block, const std::string& suffix) {
  const std::string name = blk(block) + suffix;
  return stream_ ? stream_->get(block, name) : weights_.get(name);
}

int64_t CogVideoXTransformer::token_chunk(const CogVideoXTransformerConfig& cfg, int64_t B, int64_t S, uint64_t limit) {
  const int64_t D = cfg.dim();
  // Rows between 256-byte boundaries of the RoPE tables [N, head_dim] f32 (256: any device's binding alignment).
  const int64_t step = 256 / std::gcd<int64_t>(256, cfg.head_dim * 4);
  const uint64_t row = uint64_t(std::max<int64_t>(B, 1)) * uint64_t(4 * D) * 4;  // one token's FFN state, every batch row
  const uint64_t half = std::max(uint64_t(std::max<int64_t>(B, 1)) * uint64_t(S) * uint64_t(D) * 2,
                                 uint64_t(kMinChunkTokens) * row);
  const int64_t tokens = int64_t(std::min(limit, half) / row) / step * step;
  return std::max<int64_t>(1, std::min(std::max(tokens, step), S));
}

uint64_t CogVideoXTransformer::chunk_limit() const {
  return std::min<uint64_t>(ctx_.allocator().max_binding(), ctx_.allocator().max_allocation());
}

const std::pair<Tensor, Tensor>& CogVideoXTransformer::rope_tables(int64_t F, int64_t H, int64_t W) {
  const auto key = std::make_tuple(F, H, W);
  if (auto it = rope_.find(key); it != rope_.end()) return it->second;
  const int64_t p = cfg_.patch_size;
  ops::RopeTables t = ops::cogvideox_rope_tables(cfg_.head_dim, F, H / p, W / p, cfg_.sample_height / p,
                                                 cfg_.sample_width / p);
  return rope_
      .emplace(key, std::make_pair(Tensor::upload(ctx_, t.cos, "RoPE cos"), Tensor::upload(ctx_, t.sin, "RoPE sin")))
      .first->second;
}

HostTensor cogvideox_sincos_pos_embedding(const CogVideoXTransformerConfig& cfg, int64_t F, int64_t H, int64_t W) {
  const int64_t D = cfg.dim(), p = cfg.patch_size, Hp = H / p, Wp = W / p, L = cfg.max_text_seq_length;
  if (D % 16 != 0) throw Error("CogVideoX sincos positional embedding: the width " + std::to_string(D) + " must be a multiple of 16");
  const int64_t Dt = D / 4, Dh = 3 * D / 8;  // temporal part, and each of the two spatial halves
  HostTensor out({L + F * Hp * Wp, D}, DType::f32);
  float* o = out.as<float>();
  std::fill(o, o + out.numel(), 0.0f);
  // get_1d_sincos_pos_embed_from_grid: omega = 1 / 10000^(k / (e/2)) in fp64, [sin(pos·omega) | cos(pos·omega)].
  auto put_1d = [](float* dst, int64_t e, float pos) {
    const int64_t half = e / 2;
    for (int64_t k = 0; k < half; ++k) {
      const double omega = 1.0 / std::pow(10000.0, double(k) / (double(e) / 2.0));
      const double a = double(pos) * omega;
      dst[k] = float(std::sin(a));
      dst[half + k] = float(std::cos(a));
    }
  };
  for (int64_t f = 0; f < F; ++f)
    for (int64_t i = 0; i < Hp; ++i)
      for (int64_t j = 0; j < Wp; ++j) {
        float* row = o + (L + (f * Hp + i) * Wp + j) * D;
        // Grids are fp32 aranges divided by the interpolation scales; the spatial grid's first plane is w.
        put_1d(row, Dt, float(f) / cfg.temporal_interpolation_scale);
        put_1d(row + Dt, Dh, float(j) / cfg.spatial_interpolation_scale);
        put_1d(row + Dt + Dh, Dh, float(i) / cfg.spatial_interpolation_scale);
      }
  return out;
}

const Tensor& CogVideoXTransformer::positional_embedding(int64_t F, int64_t H, int64_t W, int64_t L) {
  const auto key = std::make_tuple(F, H, W, L);
  if (auto it = pos_.find(key); it != pos_.end()) return it->second;
  Tensor t;
  if (cfg_.learned_pos) {
    // diffusers CogVideoXPatchEmbed: a learned table needs the config's spatial size; the whole
    // [1, L_max + N, D] table is added, so the text must be max_text_seq_length long.
    if (H != cfg_.sample_height || W != cfg_.sample_width)
      throw Error("CogVideoX transformer: latent " + std::to_string(H) + "x" + std::to_string(W) +
                  " differs from the learned positional embedding's " + std::to_string(cfg_.sample_height) + "x" +
                  std::to_string(cfg_.sample_width) + " (diffusers rejects other resolutions for this model)");
    if (L != cfg_.max_text_seq_length)
      throw Error("CogVideoX transformer: text length " + std::to_string(L) + " must equal max_text_seq_length " +
                  std::to_string(cfg_.max_text_seq_length) + " (the positional embedding covers exactly it)");
    const int64_t p = cfg_.patch_size, S = L + F * (H / p) * (W / p);
    t = Tensor::empty(ctx_, {S, cfg_.dim()}, DType::f32, "positional embedding");
    if ((F - 1) * cfg_.temporal_compression_ratio + 1 == cfg_.sample_frames) {
      const Tensor& stored = weights_.get("patch_embed.pos_embedding", {1, S, cfg_.dim()});
      ops::run_now(ctx_, [&](vk::Recorder& rec) {
        if (stored.dtype() == DType::f32)
          rec.copy(stored.buffer(), t.buffer(), t.bytes());
        else
          ops::cast(rec, stored, t);
      });
    } else {
      // Another frame count: diffusers recomputes the table as 3D sincos (learned values unused).
      t.write(ctx_, cogvideox_sincos_pos_embedding(cfg_, F, H, W));
    }
  }
  return pos_.emplace(key, t).first->second;
}

CogVideoXTransformer::Activations CogVideoXTransformer::plan(const CogVideoXTransformerConfig& cfg, ActivationPlan& p,
                                                             int64_t B, int64_t F, int64_t H, int64_t W, int64_t L,
                                                             int64_t lora_rank, int64_t chunk) {
  const int64_t D = cfg.dim(), T = cfg.time_embed_dim, ps = cfg.patch_size;
  const int64_t N = F * (H / ps) * (W / ps), S = L + N;
  Activations a;
  a.tproj = p.make({B, D});
  a.t1 = p.make({B, T});
  a.emb = p.make({B, T});
  a.semb = p.make({B, T});
  a.mod1 = p.make({B, 6 * D});
  a.mod2 = p.make({B, 6 * D});
  a.out_mod = p.make({B, 2 * D});
  a.patches = p.make({B, N, cfg.in_channels * ps * ps});
  a.h = p.make({B, S, D});
  a.xn = p.make({B, S, D});
  a.k = p.make({B, S, D});
  a.v = p.make({B, S, D});
  // One chunk's q and attention output (the latter on an aligned byte offset), and its FFN hidden state over
  // both once they are dead.
  a.attn_offset = (VkDeviceSize(B * chunk * D) * 4 + 255) / 256 * 256;
  a.region = p.make({std::max<int64_t>(B * chunk * 4 * D, int64_t(a.attn_offset / 4) + B * chunk * D)});
  a.proj = p.make({B, N, ps * ps * cfg.out_channels});
  if (lora_rank > 0) a.lora_tmp = p.make({B * S, lora_rank});
  return a;
}

vk::ArenaLayout CogVideoXTransformer::arena_layout(const CogVideoXTransformerConfig& config, uint64_t alignment,
                                                  int64_t B, int64_t F, int64_t H, int64_t W, int64_t L,
                                                  int64_t lora_rank, uint64_t alloc_limit, uint64_t chunk_limit) {
  ActivationPlan p(alignment, alloc_limit, "transformer activation arena");
  const int64_t S = L + F * (H / config.patch_size) * (W / config.patch_size);
  plan(config, p, B, F, H, W, L, lora_rank, token_chunk(config, B, S, std::min(alloc_limit, chunk_limit)));
  return p.layout();
}

uint64_t CogVideoXTransformer::arena_bytes(const CogVideoXTransformerConfig& config, uint64_t alignment, int64_t B,
                                           int64_t F, int64_t H, int64_t W, int64_t L, int64_t lora_rank,
                                           uint64_t alloc_limit, uint64_t chunk_limit) {
  return arena_layout(config, alignment, B, F, H, W, L, lora_rank, alloc_limit, chunk_limit).bytes();
}

vk::ArenaLayout CogVideoXTransformer::arena_layout(int64_t B, int64_t F, int64_t H, int64_t W, int64_t L) const {
  return arena_layout(cfg_, ctx_.allocator().alignment(), B, F, H, W, L, lora_rank_, ctx_.allocator().max_allocation(),
                      chunk_limit());
}

uint64_t CogVideoXTransformer::arena_bytes(int64_t B, int64_t F, int64_t H, int64_t W, int64_t L) const {
  return arena_layout(B, F, H, W, L).bytes();
}

void CogVideoXTransformer::release_call_memory() {
  arena_.reset();
  rope_.clear();
  pos_.clear();
}

void CogVideoXTransformer::set_lora(std::map<std::string, LoraAdapter> adapters) {
  const int64_t D = cfg_.dim();
  int64_t rank = 0;
  for (const auto& [name, ad] : adapters) {
    bool known = false;
    for (int64_t i = 0; i < cfg_.num_layers && !known; ++i)
      for (const char* m : {"attn1.to_q", "attn1.to_k", "attn1.to_v", "attn1.to_out.0"})
        if (name == blk(i) + m) known = true;
    if (!known)
      throw Error("LoRA: module '" + name + "' is not an attention projection of this transformer (supported: " +
                  "transformer_blocks.<i>.attn1.{to_q,to_k,to_v,to_out.0}, i < " + std::to_string(cfg_.num_layers) + ")");
    if (ad.down.shape() != Shape{ad.rank, D} || ad.up.shape() != Shape{D, ad.rank} || ad.up.dtype() != DType::f32)
      throw Error("LoRA: module '" + name + "' has A " + ad.down.describe() + " and B " + ad.up.describe() +
                  ", expected A [rank, " + std::to_string(D) + "] and f32 B [" + std::to_string(D) + ", rank]");
    rank = std::max(rank, ad.rank);
  }
  lora_ = std::move(adapters);
  lora_rank_ = rank;
}

void CogVideoXTransformer::clear_lora() {
  lora_.clear();
  lora_rank_ = 0;
}

const LoraAdapter* CogVideoXTransformer::lora(const std::string& module) const {
  auto it = lora_.find(module);
  return it == lora_.end() ? nullptr : &it->second;
}

void CogVideoXTransformer::record(vk::Recorder& rec, vk::Arena& arena, const Tensor& latent, const Tensor& text,
                                  const Tensor& timesteps, const Tensor& out, const std::vector<Tensor>* taps) {
  if (latent.rank() != 5 || latent.dtype() != DType::f32 || latent.dim(2) != cfg_.in_channels)
    throw Error("CogVideoX transformer: the latent must be f32 [B, F, " + std::to_string(cfg_.in_channels) +
                ", H, W], got " + latent.describe());
  const int64_t B = latent.dim(0), F = latent.dim(1), H = latent.dim(3), W = latent.dim(4);
  const int64_t ps = cfg_.patch_size;
  if (H % ps != 0 || W % ps != 0)
    throw Error("CogVideoX transformer: latent height and width must be multiples of the patch size");
  if (text.rank() != 3 || text.dim(0) != B || text.dim(2) != cfg_.text_embed_dim || text.dtype() != DType::f32)
    throw Error("CogVideoX transformer: the text embeddings must be f32 [" + std::to_string(B) + ", L, " +
                std::to_string(cfg_.text_embed_dim) + "], got " + text.describe());
  const int64_t L = text.dim(1), N = F * (H / ps) * (W / ps), S = L + N;
  const int64_t D = cfg_.dim(), Dh = cfg_.head_dim, nh = cfg_.heads, Cpp = cfg_.in_channels * ps * ps;
  const int64_t P = ps * ps * cfg_.out_channels;
  ops::expect_shape("CogVideoXTransformer", "timesteps", timesteps, {B});
  ops::expect_shape("CogVideoXTransformer", "out", out, {B, F, cfg_.out_channels, H, W});
  const size_t n_taps = 2 + size_t(cfg_.num_layers) + 2;
  if (taps && taps->size() != n_taps) throw Error("internal: CogVideoXTransformer: wrong number of taps");
  const auto rope_it = rope_.find(std::make_tuple(F, H, W));
  const auto pos_it = pos_.find(std::make_tuple(F, H, W, L));
  if (rope_it == rope_.end() || pos_it == pos_.end())
    throw Error("internal: CogVideoXTransformer: rope_tables / positional_embedding not created before recording");
  const Tensor& cos = rope_it->second.first;
  const Tensor& sin = rope_it->second.second;
  const Tensor& pos = pos_it->second;

  const int64_t chunk = token_chunk(cfg_, B, S, chunk_limit());
  ActivationPlan plan_(arena);
  Activations a = plan(cfg_, plan_, B, F, H, W, L, lora_rank_, chunk);
  if (stream_) stream_->begin_call(rec);  // the uploads' schedule for this recording's submission
  // A GEMM over the B batch rows: x [m, k] · Wᵀ -> y [m, n] in each, batch rows x_stride / y_stride elements apart.
  auto batched = [&](int64_t m_rows, int64_t n, int64_t k, int64_t x_stride, int64_t y_stride) {
    ops::LinearShape s;
    s.batch = B, s.m = m_rows, s.n = n, s.k = k, s.x_batch_stride = x_stride, s.y_batch_stride = y_stride;
    return s;
  };
  size_t tap_i = 0;
  auto tap = [&](const Tensor& t) {
    if (taps) rec.copy(t.buffer(), (*taps)[tap_i].buffer(), t.bytes());
    ++tap_i;
  };
  auto w = [&](const std::string& name) -> const Tensor& { return weights_.get(name); };
  auto bias_of = [&](const std::string& name) { return weights_.has(name) ? weights_.get(name) : Tensor(); };
  auto ln_w = [&](const std::string& name) { return cfg_.norm_affine ? w(name + ".weight") : Tensor(); };
  auto ln_b = [&](const std::string& name) { return cfg_.norm_affine ? w(name + ".bias") : Tensor(); };

  // Timestep embedding and every adaLN table (they only depend on emb).
  ops::timestep_embedding(rec, timesteps, a.tproj, cfg_.flip_sin_to_cos, cfg_.freq_shift);
  {
    ops::LinearEpilogue e1;
    e1.bias = w("time_embedding.linear_1.bias");
    e1.activation = ops::Activation::silu;
    ops::linear(rec, a.tproj, w("time_embedding.linear_1.weight"), a.t1, e1);
    ops::LinearEpilogue e2;
    e2.bias = w("time_embedding.linear_2.bias");
    ops::linear(rec, a.t1, w("time_embedding.linear_2.weight"), a.emb, e2);
  }
  tap(a.emb);
  ops::silu(rec, a.emb, a.semb);
  auto modulation_table = [&](const Tensor& weight, const Tensor& bias, const Tensor& table) {
    ops::LinearEpilogue e;
    e.bias = bias;
    ops::linear(rec, a.semb, weight, table, e);
  };
  modulation_table(w("norm_out.linear.weight"), w("norm_out.linear.bias"), a.out_mod);

  // Patch embedding: [text_proj(text) ; conv(latent)] written into the rows of one [B, S, D] sequence.
  ops::patchify(rec, latent, a.patches, int(ps));
  {
    const ops::LinearShape s = batched(N, D, Cpp, N * Cpp, S * D);
    ops::LinearEpilogue e;
    e.bias = bias_of("patch_embed.proj.bias");
    ops::linear_batched(rec, a.patches, w("patch_embed.proj.weight").reshape({D, Cpp}),
                        element_range(a.h, L * D, B * S * D - L * D), s, e);
    const ops::LinearShape t = batched(L, D, cfg_.text_embed_dim, L * cfg_.text_embed_dim, S * D);
    ops::LinearEpilogue et;
    et.bias = w("patch_embed.text_proj.bias");
    if (L > 0) ops::linear_batched(rec, text, w("patch_embed.text_proj.weight"), a.h, t, et);
  }
  if (pos.defined()) ops::add(rec, a.h, pos, a.h);
  tap(a.h);

  // The token chunks: the text rows, then the video rows, `chunk` at a time (a chunk never holds both).
  std::vector<std::pair<int64_t, int64_t>> chunks;  // first row, rows
  for (int64_t s0 = 0; s0 < L; s0 += chunk) chunks.emplace_back(s0, std::min(chunk, L - s0));
  for (int64_t s0 = L; s0 < S; s0 += chunk) chunks.emplace_back(s0, std::min(chunk, S - s0));
  // What only GEMMs read (the blocks' LayerNorm output: q/k/v, the FFN's first layer, LoRA's A; the FFN's hidden
  // state): in the tensor cores' operand type where they run them, in the first half of their f32 space.
  const DType gemm_x = ops::gemm_activation_dtype(ctx_.caps());
  const Tensor xn = gemm_x == DType::f16
                        ? Tensor::on(a.xn.buffer().sub(0, VkDeviceSize(a.xn.numel()) * 2), a.xn.shape(), DType::f16)
                        : a.xn;
  // Rows [s0, s0 + n) of every batch row of a [B, S, cols] tensor, as the flat range a strided GEMM walks.
  auto rows_of = [&](const Tensor& t, int64_t cols, int64_t s0) { return element_range(t, s0 * cols, B * S * cols - s0 * cols); };
  // h[rows s0..s0+n) += gate ⊙ (x·Wᵀ + b), x a chunk [B, n, k]; text rows gate from column 5D (enc_gate), video rows
  // from 2D (gate).
  auto gated_residual = [&](const Tensor& x, int64_t k, const Tensor& weight, const Tensor& bias, const Tensor& table,
                            int64_t s0, int64_t n) {
    ops::LinearShape s = batched(n, D, k, n * k, S * D);
    s.vec_batch_stride = 6 * D;
    const int64_t gate_col = s0 < L ? 5 * D : 2 * D;
    const Tensor y = rows_of(a.h, D, s0);
    ops::LinearEpilogue e;
    e.bias = bias;
    e.gate = element_range(table, gate_col, B * 6 * D - gate_col);
    e.residual = y;
    ops::linear_batched(rec, x, weight, y, s, e);
  };
  // y (+)= x·Wᵀ (+ b) for rows [s0, s0 + n) of xn into a chunk y [B, n, cols] (n = S: the whole sequence).
  auto project = [&](const Tensor& weight, const Tensor& bias, const Tensor& y, int64_t cols, int64_t s0, int64_t n,
                     const Tensor& residual, ops::Activation act) {
    const ops::LinearShape s = batched(n, cols, D, S * D, n * cols);
    ops::LinearEpilogue e;
    e.bias = bias;
    e.activation = act;
    e.residual = residual;
    ops::linear_batched(rec, rows_of(xn, D, s0), weight, y, s, e);
  };
  // LoRA: y += (x·Aᵀ)·(scale·B)ᵀ over the rows [s0, s0 + n) of xn, before the q/k norms as in diffusers'
  // LoRA-wrapped Linear; t = x·Aᵀ goes to the scratch [B, n, rank].
  auto lora_project = [&](const LoraAdapter& ad, const Tensor& y, int64_t s0, int64_t n) {
    const Tensor t = Tensor::on(a.lora_tmp.buffer(), {B * n, ad.rank}, DType::f32);
    project(ad.down, Tensor(), t, ad.rank, s0, n, Tensor(), ops::Activation::none);
    ops::linear(rec, t, ad.up, y.reshape({B * n, D}), ops::LinearEpilogue{.residual = y.reshape({B * n, D})});
  };

  auto adaln = [&](const Tensor& weight, const Tensor& bias, const Tensor& table) {
    ops::Modulation m;
    m.table = table;
    m.seq_len = S;
    m.split = L;
    m.shift_col[0] = 3 * D;  // text rows: enc_shift, enc_scale
    m.scale_col[0] = 4 * D;
    m.shift_col[1] = 0;  // video rows: shift, scale
    m.scale_col[1] = D;
    ops::layernorm(rec, a.h, xn, weight, bias, cfg_.norm_eps, &m);
  };

  ops::AttentionOptions aopt;
  aopt.scale = float(1.0 / std::sqrt(double(Dh)));
  // A chunk's q and attention output (f32; the output is f16 where attn16 below says so).
  auto chunk_q = [&](int64_t n) {
    return Tensor::on(a.region.buffer().sub(0, VkDeviceSize(B * n * D) * 4), {B, n, D}, DType::f32);
  };
  auto chunk_o32 = [&](int64_t n) {
    return Tensor::on(a.region.buffer().sub(a.attn_offset, VkDeviceSize(B * n * D) * 4), {B, n, D}, DType::f32);
  };
  // Beside tensor-core GEMMs, where every chunk's attention runs on a flash kernel, its output (the to_out GEMM's
  // X) is written fp16. Where that kernel is the tensor cores', q, k and v reach it in their operand type and
  // head-major (half the bytes every query block reads, each key tile one contiguous block), written by one pass
  // each (ops::attention_heads: the per-head LayerNorm and RoPE on q and k, the fp16 rounding, the layout) instead
  // of in-place f32 passes and casts: K into xn's second half (xn is fp16 then), V into k's first half once K is
  // read, each chunk's Q into the second half of its f32 attention output's space (the f16 output takes the first).
  bool attn16 = gemm_x == DType::f16, qkv16 = attn16;
  for (const auto& [s0, n] : chunks) {
    const ops::AttentionShape shape{B, nh, Dh, n, S};
    attn16 = attn16 && ops::attention_takes_f16(ctx_.caps(), shape, {chunk_q(n)}, {a.k}, {a.v}, {chunk_o32(n)}, aopt);
    qkv16 = qkv16 && attn16 &&
            ops::attention_split_plan(ctx_.caps(), shape, {chunk_q(n)}, {a.k}, {a.v}, {chunk_o32(n)}, aopt).family ==
                ops::KernelFamily::coopmat;
  }
  const VkDeviceSize half_bytes = VkDeviceSize(B * S * D) * 2;
  const Tensor k16 = Tensor::on(a.xn.buffer().sub(half_bytes, half_bytes), {B, nh, S, Dh}, DType::f16);
  const Tensor v16 = Tensor::on(a.k.buffer().sub(0, half_bytes), {B, nh, S, Dh}, DType::f16);
  const ops::AttentionOperand attn_k = qkv16 ? ops::AttentionOperand{k16, 0, 0, true} : ops::AttentionOperand{a.k};
  const ops::AttentionOperand attn_v = qkv16 ? ops::AttentionOperand{v16, 0, 0, true} : ops::AttentionOperand{a.v};
  // A chunk's q for the tensor-core kernel: [B, H, n, Dh] fp16 after the f16 attention output.
  auto chunk_q16 = [&](int64_t n) {
    const VkDeviceSize bytes = VkDeviceSize(B * n * D) * 2;
    return Tensor::on(a.region.buffer().sub(a.attn_offset + bytes, bytes), {B, nh, n, Dh}, DType::f16);
  };
  const Tensor k2d = a.k.reshape({B * S, D});
  for (int64_t i = 0; i < cfg_.num_layers; ++i) {
    const std::string b = blk(i);
    if (stream_) stream_->mark_block(rec, i);
    auto bw = [&](const std::string& suffix) { return block_weight(i, suffix); };
    auto block_bias = [&](const std::string& suffix) {
      const bool present = stream_ ? stream_->has(i, b + suffix) : weights_.has(b + suffix);
      return present ? bw(suffix) : Tensor();
    };
    auto ln_of = [&](const std::string& suffix) { return cfg_.norm_affine ? bw(suffix) : Tensor(); };
    modulation_table(bw("norm1.linear.weight"), bw("norm1.linear.bias"), a.mod1);
    modulation_table(bw("norm2.linear.weight"), bw("norm2.linear.bias"), a.mod2);
    adaln(ln_of("norm1.norm.weight"), ln_of("norm1.norm.bias"), a.mod1);
    // K and V of the whole sequence; per-head LayerNorm on k, RoPE on its video rows.
    const Tensor* kv[2] = {&a.k, &a.v};
    const char* kv_name[2] = {"to_k", "to_v"};
    for (int j = 0; j < 2; ++j) {
      const std::string proj = std::string("attn1.") + kv_name[j];
      project(bw(proj + ".weight"), block_bias(proj + ".bias"), *kv[j], D, 0, S, Tensor(), ops::Activation::none);
      if (const LoraAdapter* ad = lora(b + proj)) lora_project(*ad, *kv[j], 0, S);
    }
    // q and k: diffusers' norm_q/norm_k (LayerNorm per head, eps 1e-6), then RoPE on the video tokens.
    auto qk_heads = [&](const char* norm, int64_t rope_first, const Tensor& cos_rows, const Tensor& sin_rows) {
      ops::AttentionHeadsOptions o{.norm = true,
                                   .norm_weight = bw(std::string("attn1.") + norm + ".weight"),
                                   .norm_bias = bw(std::string("attn1.") + norm + ".bias"),
                                   .eps = 1e-6f};
      if (cos_rows.defined()) {  // (no rows: nothing rotated)
        o.rope = true;
        o.cos = cos_rows;
        o.sin = sin_rows;
        o.rope_first = rope_first;
      }
      return o;
    };
    if (qkv16) {  // k is read before v overwrites its first half
      ops::attention_heads(rec, a.k, k16, nh, qk_heads("norm_k", L, cos, sin));
      ops::attention_heads(rec, a.v, v16, nh, {});
    } else {
      ops::head_layernorm(rec, k2d, k2d, nh, Dh, 0, bw("attn1.norm_k.weight"), bw("attn1.norm_k.bias"), 1e-6f);
      if (N > 0) ops::rope(rec, k2d, k2d, B, S, L, nh, Dh, 0, cos, sin);
    }
    // Attention chunk by chunk of queries: q, its norm and RoPE, attention over every key, the gated output.
    for (const auto& [s0, n] : chunks) {
      const Tensor q = chunk_q(n), o32 = chunk_o32(n);
      const Tensor o = attn16 ? Tensor::on(o32.buffer().sub(0, VkDeviceSize(B * n * D) * 2), {B, n, D}, DType::f16) : o32;
      const Tensor q2d = q.reshape({B * n, D});
      project(bw("attn1.to_q.weight"), block_bias("attn1.to_q.bias"), q, D, s0, n, Tensor(), ops::Activation::none);
      if (const LoraAdapter* ad = lora(b + "attn1.to_q")) lora_project(*ad, q, s0, n);
      ops::AttentionOperand attn_q{q};
      if (qkv16) {  // a chunk is all text (no RoPE) or all video
        attn_q = {chunk_q16(n), 0, 0, true};
        ops::attention_heads(rec, q, attn_q.t, nh,
                             s0 >= L ? qk_heads("norm_q", 0, cos.rows(s0 - L, n), sin.rows(s0 - L, n))
                                     : qk_heads("norm_q", 0, Tensor(), Tensor()));
      } else {
        ops::head_layernorm(rec, q2d, q2d, nh, Dh, 0, bw("attn1.norm_q.weight"), bw("attn1.norm_q.bias"), 1e-6f);
        if (s0 >= L) ops::rope(rec, q2d, q2d, B, n, 0, nh, Dh, 0, cos.rows(s0 - L, n), sin.rows(s0 - L, n));
      }
      ops::attention(rec, ops::AttentionShape{B, nh, Dh, n, S}, attn_q, attn_k, attn_v, ops::AttentionOperand{o}, aopt);
      gated_residual(o, D, bw("attn1.to_out.0.weight"), bw("attn1.to_out.0.bias"), a.mod1, s0, n);
      if (const LoraAdapter* ad = lora(b + "attn1.to_out.0")) {  // gate ⊙ (u + v) = gate ⊙ u + gate ⊙ v
        const Tensor t = Tensor::on(a.lora_tmp.buffer(), {B * n, ad->rank}, DType::f32);
        ops::linear(rec, o.reshape({B * n, D}), ad->down, t);
        gated_residual(t, ad->rank, ad->up, Tensor(), a.mod1, s0, n);
      }
    }

    adaln(ln_of("norm2.norm.weight"), ln_of("norm2.norm.bias"), a.mod2);
    for (const auto& [s0, n] : chunks) {
      const Tensor ff = Tensor::on(a.region.buffer().sub(0, VkDeviceSize(B * n * 4 * D) * dtype_size(gemm_x)),
                                   {B, n, 4 * D}, gemm_x);
      project(bw("ff.net.0.proj.weight"), bw("ff.net.0.proj.bias"), ff, 4 * D, s0, n, Tensor(), ops::Activation::gelu_tanh);
      gated_residual(ff, 4 * D, bw("ff.net.2.weight"), bw("ff.net.2.bias"), a.mod2, s0, n);
    }
    tap(a.h);
    // One submission per block (Recorder::boundary): progress and Ctrl-C between blocks.
    rec.boundary("transformer block " + std::to_string(i + 1) + "/" + std::to_string(cfg_.num_layers));
  }

  // norm_final and norm_out are per-token: run them on the whole sequence, keep the video rows.
  ops::layernorm(rec, a.h, a.xn, ln_w("norm_final"), ln_b("norm_final"), cfg_.norm_eps);
  tap(a.xn);
  {
    ops::Modulation m;
    m.table = a.out_mod;  // AdaLayerNorm(chunk_dim=1): (shift, scale)
    m.seq_len = S;
    m.split = 0;
    m.shift_col[0] = m.shift_col[1] = 0;
    m.scale_col[0] = m.scale_col[1] = D;
    ops::layernorm(rec, a.xn, a.xn, ln_w("norm_out.norm"), ln_b("norm_out.norm"), cfg_.norm_eps, &m);
  }
  {
    const ops::LinearShape s = batched(N, P, D, S * D, N * P);
    ops::LinearEpilogue e;
    e.bias = w("proj_out.bias");
    ops::linear_batched(rec, element_range(a.xn, L * D, B * S * D - L * D), w("proj_out.weight"), a.proj, s, e);
  }
  tap(a.proj);
  ops::unpatchify(rec, a.proj, out, int(ps));
}

Tensor CogVideoXTransformer::forward(const Tensor& latent, const Tensor& text, std::span<const float> timesteps,
                                     CogVideoXTaps* taps) {
  if (latent.rank() != 5 || text.rank() != 3)
    throw Error("CogVideoX transformer: latent must be [B, F, C, H, W] and text [B, L, D], got " + latent.describe() +
                " and " + text.describe());
  const int64_t B = latent.dim(0), F = latent.dim(1), H = latent.dim(3), W = latent.dim(4), L = text.dim(1);
  const int64_t ps = cfg_.patch_size, D = cfg_.dim(), N = F * (H / ps) * (W / ps), S = L + N;
  if (timesteps.size() != 1 && int64_t(timesteps.size()) != B)
    throw Error("CogVideoX transformer: give 1 timestep or one per batch row (" + std::to_string(B) + ")");
  HostTensor ht({B}, DType::f32);
  for (int64_t b = 0; b < B; ++b) ht.as<float>()[b] = timesteps[timesteps.size() == 1 ? 0 : size_t(b)];
  const Tensor dev_t = Tensor::upload(ctx_, ht, "timesteps");
  rope_tables(F, H, W);
  positional_embedding(F, H, W, L);
  Tensor out = Tensor::empty(ctx_, {B, F, cfg_.out_channels, H, W}, DType::f32, "transformer output");
  std::vector<Tensor> tap_t;
  if (taps) {
    tap_t.push_back(Tensor::empty(ctx_, {B, cfg_.time_embed_dim}, DType::f32, "tap"));
    for (int64_t i = 0; i < cfg_.num_layers + 2; ++i) tap_t.push_back(Tensor::empty(ctx_, {B, S, D}, DType::f32, "tap"));
    tap_t.push_back(Tensor::empty(ctx_, {B, N, ps * ps * cfg_.out_channels}, DType::f32, "tap"));
  }
  vk::Arena& arena = arena_for(ctx_, arena_, arena_layout(B, F, H, W, L), "transformer activation arena");
  vk::Recorder rec(ctx_);
  rec.begin();
  record(rec, arena, latent, text, dev_t, out, taps ? &tap_t : nullptr);
  rec.end();
  rec.submit();
  if (taps) {
    // Split [B, S, D] sequences into text rows [B, L, D] and video rows [B, N, D] on the host.
    auto rows = [&](const HostTensor& seq, int64_t first, int64_t count) {
      HostTensor r({B, count, D}, DType::f32);
      for (int64_t b = 0; b < B; ++b)
        std::memcpy(r.as<float>() + b * count * D, seq.as<float>() + (b * S + first) * D, size_t(count * D) * 4);
      return r;
    };
    taps->time_embedding = tap_t[0].download(ctx_);
    taps->patch_embed = tap_t[1].download(ctx_);
    taps->block_hidden.clear();
    taps->block_encoder.clear();
    for (int64_t i = 0; i < cfg_.num_layers; ++i) {
      const HostTensor seq = tap_t[size_t(2 + i)].download(ctx_);
      taps->block_encoder.push_back(rows(seq, 0, L));
      taps->block_hidden.push_back(rows(seq, L, N));
    }
    taps->norm_final = rows(tap_t[size_t(2 + cfg_.num_layers)].download(ctx_), L, N);
    taps->proj_out = tap_t.back().download(ctx_);
  }
  return out;
}

}  // namespace dvs::models
