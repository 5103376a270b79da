#include "models/cogvideox/cogvideox_vae.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <utility>

#include "dvs/error.hpp"
#include "io/option_names.hpp"
#include "spec/model_schema.hpp"
#include "models/cogvideox/vae_tiling.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_conv.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"
#include "tensor/ops_norm.hpp"
#include "tensor/ops_vae_extra.hpp"
#include "vk/context.hpp"
#include "vk/recorder.hpp"

namespace dvs::models {

// ---- per-call state -----------------------------------------------------------------------------------------

namespace {

// A tensor with a shape and no memory, for dry runs (memory planning from the config alone). `id` becomes the
// view's offset so that pooled shape-only buffers stay distinguishable.
Tensor shape_only(const Shape& s, VkDeviceSize id = 0) {
  vk::BufferView none;
  none.offset = id;
  none.size = VkDeviceSize(std::max<int64_t>(shape_numel(s), 1)) * 4;
  return Tensor::on(none, s, DType::f32);
}

// Buffers of one call. Intermediates come from a best-fit pool (a free buffer of at least the size and at most
// twice it, else a new one); a buffer returned with put() may be reused by a later dispatch of the same
// recording (the recorder orders the write after earlier reads of the range). Everything allocated stays
// referenced until release_batch(), which runs after the batch's submit. A dry run (no context) allocates
// nothing and only counts bytes.
struct Run {
  using Key = std::pair<VkBuffer, VkDeviceSize>;
  struct Slot {
    Tensor owner;
    uint64_t capacity;
  };
  vk::Context* ctx = nullptr;  // null: dry run
  std::map<Key, Slot> slots;   // every buffer of this batch
  std::multimap<uint64_t, Key> free;
  std::map<std::string, Tensor> cache;  // conv caches, carried across frame batches
  std::map<Shape, Tensor> zq;           // decoder: the latent batch resized to each feature size
  Tensor z;                             // decoder: the latent batch (SpatialNorm's condition)
  uint64_t batch_bytes = 0, cache_bytes = 0, peak_bytes = 0, dry_ids = 0;
  uint64_t largest = 0;      // the largest single buffer allocated (an activation, a conv staging or a cache)
  std::string largest_what;  // what it holds, with its shape

  explicit Run(vk::Context* c) : ctx(c) {}

  void note_buffer(uint64_t bytes, const std::string& what, const Shape& s) {
    if (bytes <= largest) return;
    largest = bytes;
    largest_what = what + " [" + shape_str(s) + "]";
  }

  static Key key_of(const Tensor& t) { return {t.buffer().buffer, t.buffer().offset}; }

  Tensor get(const Shape& s, const char* what = "activation") {
    const uint64_t need = uint64_t(std::max<int64_t>(shape_numel(s), 1)) * 4;
    if (auto it = free.lower_bound(need); it != free.end() && it->first <= 2 * need) {
      const Key k = it->second;
      free.erase(it);
      return Tensor::on(slots.at(k).owner.buffer(), s, DType::f32);
    }
    batch_bytes += need;
    note_buffer(need, what, s);
    Tensor owner = ctx ? Tensor::empty(*ctx, {int64_t(need / 4)}, DType::f32, "vae activation")
                       : shape_only({int64_t(need / 4)}, ++dry_ids);
    slots.emplace(key_of(owner), Slot{owner, need});
    return Tensor::on(owner.buffer(), s, DType::f32);
  }
  void put(const Tensor& t) {
    const Key k = key_of(t);
    free.emplace(slots.at(k).capacity, k);
  }
  // An owning tensor with t's contents (a batch result outlives release_batch(); t is a view into the pool):
  // t's buffer itself when it fits exactly, else a copy. Live runs only, after the batch's submit.
  Tensor owned(const Tensor& t) {
    const Tensor& owner = slots.at(key_of(t)).owner;
    if (owner.numel() == t.numel()) return owner.reshape(t.shape());
    Tensor c = Tensor::empty(*ctx, t.shape(), DType::f32, "vae result");
    ops::run_now(*ctx, [&](vk::Recorder& rec) { rec.copy(t.buffer(), c.buffer(), t.bytes()); });
    return c;
  }
  Tensor new_cache(const std::string& name, const Shape& s) {
    cache_bytes += uint64_t(shape_numel(s)) * 4;
    note_buffer(uint64_t(shape_numel(s)) * 4, "conv cache of " + name, s);
    Tensor c = ctx ? Tensor::empty(*ctx, s, DType::f32, name + " cache") : shape_only(s);
    cache.emplace(name, c);
    return c;
  }
  void release_batch() {
    peak_bytes = std::max(peak_bytes, batch_bytes + cache_bytes);
    batch_bytes = 0;
    free.clear();
    slots.clear();
    zq.clear();
    z = Tensor();
  }
};

Shape with_channels(const Shape& s, int64_t c) {
  Shape r = s;
  r[1] = c;
  return r;
}

}  // namespace

// ---- layers ---------------------------------------------------------------------------------------------------

namespace {

// The model's layers over one frame batch. rec == nullptr: dry run (weights are shape-only tensors made from
// the config's schema, nothing is recorded).
struct Layers {
  const VaeConfig& cfg;
  vk::Recorder* rec;
  ComponentWeights* weights;                          // live run
  const std::map<std::string, Shape>* weight_shapes;  // dry run
  std::map<std::string, Tensor> dry_weights;

  const Tensor& W(const std::string& n) {
    if (weights) return weights->get(n);
    auto it = dry_weights.find(n);
    if (it != dry_weights.end()) return it->second;
    auto s = weight_shapes->find(n);
    if (s == weight_shapes->end()) throw Error("internal: VAE dry run: no tensor " + n + " in the schema");
    return dry_weights.emplace(n, shape_only(s->second)).first->second;
  }
  // Convolution weights: packed once at load on a live run (ComponentWeights::packed_conv), the shape-only stored
  // tensor on a dry run (only shapes are read there).
  ops::ConvWeights CW(const std::string& n) {
    if (weights) return weights->packed_conv(n);
    return W(n);
  }
  const Tensor* Bias(const std::string& n) {
    const bool present = weights ? weights->has(n) : weight_shapes->count(n) > 0;
    return present ? &W(n) : nullptr;
  }

  // CogVideoXCausalConv3d (kt = 3 here) with its cache under `prefix`.
  // Staging of one convolution (its repacked input and weights) from the pool, so that dry runs count it
  // like every other buffer; returned right after the op is recorded.
  ops::ConvScratch conv_scratch(Run& run, const ops::ConvScratchSize& s) {
    return {run.get({s.input}, "convolution staging (repacked input)"), run.get({s.weights}, "convolution staging (weights)")};
  }
  void put_scratch(Run& run, const ops::ConvScratch& s) {
    run.put(s.input);
    run.put(s.weights);
  }

  Tensor causal_conv(Run& run, const Tensor& x, const std::string& prefix) {
    const ops::ConvWeights wt = CW(prefix + ".conv.weight");
    const Tensor* b = Bias(prefix + ".conv.bias");
    Tensor y = run.get({x.dim(0), wt.dim(0), x.dim(2), x.dim(3), x.dim(4)});
    const ops::ConvScratch cs = conv_scratch(run, ops::causal_conv3d_scratch(x.shape(), wt.shape()));
    if (wt.dim(2) == 1) {
      if (rec) ops::causal_conv3d(*rec, x, wt, b, y, nullptr, nullptr, &cs);
    } else if (auto it = run.cache.find(prefix); it == run.cache.end()) {
      Tensor c = run.new_cache(prefix, ops::causal_conv3d_cache_shape(x.shape(), wt.shape()));
      if (rec) ops::causal_conv3d(*rec, x, wt, b, y, nullptr, &c, &cs);
    } else {
      if (rec) ops::causal_conv3d(*rec, x, wt, b, y, &it->second, &it->second, &cs);
    }
    put_scratch(run, cs);
    return y;
  }

  void group_norm(Run& run, const Tensor& x, const Tensor& y, const std::string& prefix, float eps, bool silu) {
    Tensor scratch = run.get({ops::groupnorm_scratch_elems(x.shape(), cfg.norm_num_groups)}, "GroupNorm scratch");
    if (rec)
      ops::groupnorm(*rec, x, y, cfg.norm_num_groups, W(prefix + ".weight"), W(prefix + ".bias"), eps, silu, scratch);
    run.put(scratch);
  }

  // CogVideoXSpatialNorm3D: GroupNorm(f) * conv_y(zq) + conv_b(zq), zq = the latent batch resized to f's
  // (F, H, W) by nearest, frame 0 alone when F is odd and > 1. Returns a new tensor.
  Tensor spatial_norm(Run& run, const Tensor& f, const std::string& prefix) {
    const Shape zs = {run.z.dim(0), run.z.dim(1), f.dim(2), f.dim(3), f.dim(4)};
    auto it = run.zq.find(zs);
    if (it == run.zq.end()) {
      Tensor zq = run.get(zs);
      const int64_t frames = f.dim(2);
      if (rec) ops::upsample_nearest(*rec, run.z, zq, frames > 1 && frames % 2 == 1);
      it = run.zq.emplace(zs, zq).first;
    }
    const Tensor& zq = it->second;
    Tensor cy = run.get(f.shape()), cb = run.get(f.shape()), y = run.get(f.shape());
    const ops::ConvScratch cs = conv_scratch(run, ops::causal_conv3d_scratch(zq.shape(), CW(prefix + ".conv_y.conv.weight").shape()));
    if (rec) {
      ops::conv1x1(*rec, zq, CW(prefix + ".conv_y.conv.weight"), Bias(prefix + ".conv_y.conv.bias"), cy, &cs);
      ops::conv1x1(*rec, zq, CW(prefix + ".conv_b.conv.weight"), Bias(prefix + ".conv_b.conv.bias"), cb, &cs);
    }
    put_scratch(run, cs);
    group_norm(run, f, y, prefix + ".norm_layer", 1e-6f, false);
    if (rec) ops::scale_shift(*rec, y, cy, cb, y);
    run.put(cy);
    run.put(cb);
    return y;
  }

  void silu(const Tensor& x) {
    if (rec) ops::silu(*rec, x, x);
  }

  // CogVideoXResnetBlock3D (no temb, 1x1x1 shortcut when the channel count changes). Returns a new tensor.
  Tensor resnet(Run& run, const Tensor& x, const std::string& p, bool spatial) {
    const int64_t cin = x.dim(1);
    Tensor h;
    if (spatial) {
      h = spatial_norm(run, x, p + ".norm1");
      silu(h);
    } else {
      h = run.get(x.shape());
      group_norm(run, x, h, p + ".norm1", cfg.norm_eps, true);
    }
    Tensor h2 = causal_conv(run, h, p + ".conv1");
    run.put(h);
    if (spatial) {
      Tensor n2 = spatial_norm(run, h2, p + ".norm2");
      silu(n2);
      run.put(h2);
      h2 = n2;
    } else {
      group_norm(run, h2, h2, p + ".norm2", cfg.norm_eps, true);
    }
    Tensor out = causal_conv(run, h2, p + ".conv2");
    run.put(h2);
    if (cin != out.dim(1)) {
      Tensor s = run.get(out.shape());
      const ops::ConvScratch cs = conv_scratch(run, ops::causal_conv3d_scratch(x.shape(), CW(p + ".conv_shortcut.weight").shape()));
      if (rec) {
        ops::conv1x1(*rec, x, CW(p + ".conv_shortcut.weight"), Bias(p + ".conv_shortcut.bias"), s, &cs);
        ops::add(*rec, out, s, out);
      }
      put_scratch(run, cs);
      run.put(s);
    } else if (rec) {
      ops::add(*rec, out, x, out);
    }
    if (rec) rec->boundary("VAE " + p);  // one submission per resnet step of one frame batch
    return out;
  }

  // CogVideoXEncoder3D on one frame batch -> moments [B, 2*Cl, Fb', Hl, Wl].
  Tensor encoder(Run& run, const Tensor& x) {
    const size_t n = cfg.block_out_channels.size();
    Tensor h = causal_conv(run, x, "encoder.conv_in");
    for (size_t i = 0; i < n; ++i) {
      const std::string p = "encoder.down_blocks." + std::to_string(i);
      for (int64_t j = 0; j < cfg.layers_per_block; ++j) {
        Tensor next = resnet(run, h, p + ".resnets." + std::to_string(j), false);
        run.put(h);
        h = next;
      }
      if (i + 1 < n) {
        if (int64_t(i) < cfg.temporal_levels()) {
          Shape ts = h.shape();
          ts[2] = ops::downsample_time_frames(ts[2]);
          Tensor t = run.get(ts);
          if (rec) ops::avgpool_time_pairs(*rec, h, t);
          run.put(h);
          h = t;
        }
        const ops::ConvWeights wt = CW(p + ".downsamplers.0.conv.weight");
        const auto params = ops::Conv2dParams::downsample3x3();
        Tensor y = run.get(ops::conv2d_shape(h.shape(), wt.shape(), params));
        const ops::ConvScratch cs = conv_scratch(run, ops::conv2d_scratch(h.shape(), wt.shape()));
        if (rec) ops::conv2d(*rec, h, wt, Bias(p + ".downsamplers.0.conv.bias"), y, params, &cs);
        put_scratch(run, cs);
        run.put(h);
        h = y;
        if (rec) rec->boundary("VAE " + p + ".downsamplers");
      }
    }
    for (int j = 0; j < 2; ++j) {
      Tensor next = resnet(run, h, "encoder.mid_block.resnets." + std::to_string(j), false);
      run.put(h);
      h = next;
    }
    group_norm(run, h, h, "encoder.norm_out", 1e-6f, true);
    Tensor out = causal_conv(run, h, "encoder.conv_out");
    run.put(h);
    if (cfg.use_quant_conv) {
      Tensor q = run.get(out.shape());
      const ops::ConvScratch cs = conv_scratch(run, ops::causal_conv3d_scratch(out.shape(), CW("quant_conv.weight").shape()));
      if (rec) ops::conv1x1(*rec, out, CW("quant_conv.weight"), Bias("quant_conv.bias"), q, &cs);
      put_scratch(run, cs);
      out = q;
    }
    return out;
  }

  // CogVideoXDecoder3D on one latent batch -> frames.
  Tensor decoder(Run& run, const Tensor& z_in) {
    const size_t n = cfg.block_out_channels.size();
    Tensor z = z_in;
    if (cfg.use_post_quant_conv) {
      z = run.get(z_in.shape());
      const ops::ConvScratch cs = conv_scratch(run, ops::causal_conv3d_scratch(z_in.shape(), CW("post_quant_conv.weight").shape()));
      if (rec) ops::conv1x1(*rec, z_in, CW("post_quant_conv.weight"), Bias("post_quant_conv.bias"), z, &cs);
      put_scratch(run, cs);
    }
    run.z = z;
    Tensor h = causal_conv(run, z, "decoder.conv_in");
    for (int j = 0; j < 2; ++j) {
      Tensor next = resnet(run, h, "decoder.mid_block.resnets." + std::to_string(j), true);
      run.put(h);
      h = next;
    }
    for (size_t i = 0; i < n; ++i) {
      const std::string p = "decoder.up_blocks." + std::to_string(i);
      for (int64_t j = 0; j <= cfg.layers_per_block; ++j) {
        Tensor next = resnet(run, h, p + ".resnets." + std::to_string(j), true);
        run.put(h);
        h = next;
      }
      if (i + 1 < n) {
        const bool compress_time = int64_t(i) < cfg.temporal_levels();
        Tensor u = run.get(ops::upsample2x_shape(h.shape(), compress_time));
        if (rec) ops::upsample2x(*rec, h, u, compress_time);
        run.put(h);
        const ops::ConvWeights wt = CW(p + ".upsamplers.0.conv.weight");
        const auto params = ops::Conv2dParams::same3x3();
        Tensor y = run.get(ops::conv2d_shape(u.shape(), wt.shape(), params));
        const ops::ConvScratch cs = conv_scratch(run, ops::conv2d_scratch(u.shape(), wt.shape()));
        if (rec) ops::conv2d(*rec, u, wt, Bias(p + ".upsamplers.0.conv.bias"), y, params, &cs);
        put_scratch(run, cs);
        run.put(u);
        h = y;
        if (rec) rec->boundary("VAE " + p + ".upsamplers");
      }
    }
    Tensor nrm = spatial_norm(run, h, "decoder.norm_out");
    run.put(h);
    silu(nrm);
    Tensor out = causal_conv(run, nrm, "decoder.conv_out");
    run.put(nrm);
    return out;
  }
};

}  // namespace

// ---- model ----------------------------------------------------------------------------------------------------

CogVideoXVae::CogVideoXVae(vk::Context& ctx, const std::filesystem::path& vae_dir)
    : CogVideoXVae(ctx, ComponentWeights(ctx, vae_dir)) {}

CogVideoXVae::CogVideoXVae(vk::Context& ctx, ComponentWeights weights)
    : ctx_(ctx), weights_(std::move(weights)), cfg_(VaeConfig::from_json(weights_.config())) {
  // Every convolution weight (the only tensors of rank 4 or 5) packed now, in the layout and operand dtype the conv
  // kernels read, not at its first call: packing holds one weight's stored and packed copies at once, which inside a
  // call lifted that call's peak above its plan by the largest weight (a 512-channel 3x3x3 conv: 13.5 MiB).
  for (const std::string& name : weights_.names())
    if (weights_.info(name).shape.size() >= 4) weights_.packed_conv(name);
}

CogVideoXVae::~CogVideoXVae() = default;

std::vector<std::pair<int64_t, int64_t>> CogVideoXVae::frame_batches(int64_t frames, int64_t batch) {
  // diffusers: num_batches = max(F // b, 1); batch i = [b*i + (0 if i == 0 else r), b*(i+1) + r), r = F % b.
  std::vector<std::pair<int64_t, int64_t>> out;
  const int64_t n = std::max<int64_t>(frames / batch, 1), r = frames % batch;
  for (int64_t i = 0; i < n; ++i) {
    const int64_t start = batch * i + (i == 0 ? 0 : r);
    const int64_t end = std::min(batch * (i + 1) + r, frames);
    if (end > start) out.emplace_back(start, end);
  }
  return out;
}

namespace {

// Splits x [B, C, F, H, W] into the given frame ranges (one copy per band; x itself when there is one band).
std::vector<Tensor> split_frames(vk::Context& ctx, const Tensor& x,
                                 const std::vector<std::pair<int64_t, int64_t>>& ranges) {
  if (ranges.size() == 1 && ranges[0].first == 0 && ranges[0].second == x.dim(2)) return {x};
  std::vector<Tensor> bands;
  for (auto [s, e] : ranges) {
    Shape sh = x.shape();
    sh[2] = e - s;
    bands.push_back(Tensor::empty(ctx, sh, DType::f32, "vae frame batch"));
  }
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::split(rec, x, bands, 2); });
  return bands;
}

Tensor concat_frames(vk::Context& ctx, const std::vector<Tensor>& parts, const std::string& what) {
  if (parts.size() == 1) return parts[0];
  Shape sh = parts[0].shape();
  sh[2] = 0;
  for (const Tensor& t : parts) sh[2] += t.dim(2);
  Tensor out = Tensor::empty(ctx, sh, DType::f32, what);
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::concat(rec, parts, out, 2); });
  return out;
}

void check_video(const char* what, const Tensor& t, int64_t channels) {
  if (t.rank() != 5 || t.dtype() != DType::f32 || t.dim(1) != channels)
    throw Error(std::string("CogVideoX VAE ") + what + ": expected f32 [B, " + std::to_string(channels) +
                ", F, H, W], got " + t.describe());
}

}  // namespace

// Refuses, before any work, a call whose largest single buffer (the planner's figure, the one `dvs plan` and
// the preflight check) exceeds one allocation: the ops split every binding, but one buffer is one allocation
// (at 480 x 720 an untiled decode of a 2-latent-frame batch holds 256 x 8 x 480 x 720 f32 = 2.6 GiB in one).
void CogVideoXVae::check_allocations(const char* what, const VaeFootprint& f) const {
  const uint64_t limit = ctx_.caps().max_memory_allocation_size;
  if (limit && f.largest_allocation > limit)
    throw Error(std::string("CogVideoX VAE ") + what + ": its largest buffer, " + f.largest_what + ", needs " +
                vk::format_bytes(f.largest_allocation) + ", more than the device allocates at once " +
                "(maxMemoryAllocationSize " + vk::format_bytes(limit) + "); use VAE tiling (" +
                option_name("RunOptions::vae_tile_height/width") + ") with " +
                "smaller tiles (dvs plan --device shows the tile that fits)");
}

// One network over a clip, frame batch by frame batch (diffusers' batching with the conv caches carried in `run`),
// the batches' outputs joined on time. Records the call's peak and largest buffer.
Tensor CogVideoXVae::run_frame_batches(const Tensor& x, int64_t frames_batch, bool decoder, const char* name) {
  std::vector<Tensor> inputs = split_frames(ctx_, x, frame_batches(x.dim(2), frames_batch));
  Run run(&ctx_);
  std::vector<Tensor> outs;
  for (const Tensor& batch : inputs) {
    Tensor out;
    ops::run_now(ctx_, [&](vk::Recorder& rec) {
      Layers L{cfg_, &rec, &weights_, nullptr, {}};
      out = decoder ? L.decoder(run, batch) : L.encoder(run, batch);
    });
    outs.push_back(run.owned(out));
    run.release_batch();
  }
  last_peak_bytes_ = run.peak_bytes;
  last_footprint_ = {run.peak_bytes, run.largest, run.largest, run.largest_what};
  return concat_frames(ctx_, outs, name);
}

Tensor CogVideoXVae::encode_moments(const Tensor& video) {
  check_video("encode", video, cfg_.in_channels);
  check_allocations("encode", encode_footprint(weights_.config(), video.shape(), sample_frames_batch, false));
  return run_frame_batches(video, sample_frames_batch, false, "vae moments");
}

VaePosterior CogVideoXVae::posterior_of(const Tensor& moments) {
  VaePosterior p;
  p.moments = moments;
  const Shape half = with_channels(moments.shape(), moments.dim(1) / 2);
  p.mean = Tensor::empty(ctx_, half, DType::f32, "vae posterior mean");
  p.std = Tensor::empty(ctx_, half, DType::f32, "vae posterior std");
  ops::run_now(ctx_, [&](vk::Recorder& rec) { ops::vae_posterior(rec, moments, p.mean, p.std); });
  return p;
}

VaePosterior CogVideoXVae::encode(const Tensor& video) {
  check_video("encode", video, cfg_.in_channels);
  check_allocations("encode", encode_footprint(weights_.config(), video.shape(), sample_frames_batch, true));
  return posterior_of(run_frame_batches(video, sample_frames_batch, false, "vae moments"));
}

Tensor CogVideoXVae::decode(const Tensor& z) {
  check_video("decode", z, cfg_.latent_channels);
  check_allocations("decode", decode_footprint(weights_.config(), z.shape(), latent_frames_batch));
  return run_frame_batches(z, latent_frames_batch, true, "vae frames");
}

// ---- memory planning ------------------------------------------------------------------------------------------

namespace {

// The largest of the buffers offered so far, with what it holds.
struct LargestBuffer {
  uint64_t bytes = 0;
  std::string what;
  void offer(uint64_t b, const std::string& w) {
    if (b > bytes) bytes = b, what = w;
  }
  void offer(const Shape& s, const std::string& w) {
    offer(uint64_t(std::max<int64_t>(shape_numel(s), 1)) * 4, w + " [" + shape_str(s) + "]");
  }
};

struct DryRun {
  VaeFootprint footprint;  // working set and largest buffer of the batches (largest_allocation: the same)
  Shape result;            // the call's result: the batch results concatenated on frames
};

// The same layer code on shape-only tensors: the working set of every frame batch, from the config alone.
DryRun dry_run(const nlohmann::json& config, const Shape& input, bool encode, int64_t batch) {
  const VaeConfig cfg = VaeConfig::from_json(config);
  std::map<std::string, Shape> shapes;
  for (const auto& t : schema_for("AutoencoderKLCogVideoX", config, "vae config").tensors) shapes[t.name] = t.shape;
  if (input.size() != 5 || input[1] != (encode ? cfg.in_channels : cfg.latent_channels))
    throw Error("VAE memory plan: the input must be [B, " + std::to_string(encode ? cfg.in_channels : cfg.latent_channels) +
                ", F, H, W], got [" + shape_str(input) + "]");
  Run run(nullptr);
  DryRun d;
  for (auto [s, e] : CogVideoXVae::frame_batches(input[2], batch)) {
    Shape b = input;
    b[2] = e - s;
    Layers L{cfg, nullptr, nullptr, &shapes, {}};
    const Tensor x = shape_only(b);
    const Shape out = (encode ? L.encoder(run, x) : L.decoder(run, x)).shape();
    if (d.result.empty()) d.result = out;
    else d.result[2] += out[2];
    run.release_batch();
  }
  d.footprint = {run.peak_bytes, run.largest, run.largest, run.largest_what};
  return d;
}

// The buffers an untiled call allocates around its batches (split_frames, Run::owned, concat_frames,
// posterior_of): a band per batch when there are several, the concatenated result, the posterior's halves.
// A batch result copied out of the pool is never larger than the pool buffer it came from, already counted.
DryRun whole_call(const nlohmann::json& config, const Shape& input, bool encode, int64_t batch, bool posterior) {
  DryRun d = dry_run(config, input, encode, batch);
  LargestBuffer l{d.footprint.largest_allocation, d.footprint.largest_what};
  const auto ranges = CogVideoXVae::frame_batches(input[2], batch);
  if (ranges.size() > 1) {
    for (auto [s, e] : ranges) {
      Shape band = input;
      band[2] = e - s;
      l.offer(band, "frame batch copied out of the input");
    }
    l.offer(d.result, encode ? "moments" : "decoded frames");
  }
  if (encode && posterior) {
    Shape half = d.result;
    half[1] /= 2;
    l.offer(half, "posterior mean / std");
  }
  d.footprint.largest_allocation = l.bytes;
  d.footprint.largest_what = l.what;
  return d;
}

// The distinct sizes of the tiles run_tiled cuts from an extent: `tile` at each multiple of `stride`, clipped
// at the end (an interior size and an edge size at most).
std::vector<int64_t> tile_extents(int64_t extent, int64_t tile, int64_t stride) {
  std::vector<int64_t> out;
  for (int64_t i = 0; i < extent; i += stride) {
    const int64_t e = std::min(tile, extent - i);
    if (std::find(out.begin(), out.end(), e) == out.end()) out.push_back(e);
  }
  return out;
}

// A tiled call: every distinct tile shape through the untiled call (without the posterior), each tile's
// upload, and the blended result uploaded whole (plus the posterior for encode). The blended result keeps
// limit_h x limit_w of each tile's output.
VaeFootprint tiled_call(const nlohmann::json& config, const Shape& input, const TilePlan& plan, bool encode, int64_t batch) {
  if (plan.stride_h <= 0 || plan.stride_w <= 0) throw Error("VAE tiling: the tile overlap leaves no stride");
  const int64_t H = input[3], W = input[4];
  VaeFootprint f;
  LargestBuffer l;
  std::map<std::pair<int64_t, int64_t>, Shape> outputs;  // tile size -> its output
  for (int64_t th : tile_extents(H, plan.tile_in_h, plan.stride_h))
    for (int64_t tw : tile_extents(W, plan.tile_in_w, plan.stride_w)) {
      Shape tile = input;
      tile[3] = th, tile[4] = tw;
      const DryRun d = whole_call(config, tile, encode, batch, false);
      f.working = std::max(f.working, d.footprint.working);
      f.largest_tensor = std::max(f.largest_tensor, d.footprint.largest_tensor);
      l.offer(d.footprint.largest_allocation, d.footprint.largest_what + " (one tile)");
      l.offer(tile, "tile uploaded");
      outputs[{th, tw}] = d.result;
    }
  Shape blended;
  int64_t out_h = 0, out_w = 0;
  for (int64_t i = 0; i < H; i += plan.stride_h) {
    const Shape& o = outputs.at({std::min(plan.tile_in_h, H - i), std::min(plan.tile_in_w, W)});
    out_h += std::min(plan.limit_h, o[3]);
    blended = o;
  }
  for (int64_t j = 0; j < W; j += plan.stride_w)
    out_w += std::min(plan.limit_w, outputs.at({std::min(plan.tile_in_h, H), std::min(plan.tile_in_w, W - j)})[4]);
  blended[3] = out_h, blended[4] = out_w;
  l.offer(blended, encode ? "blended moments" : "blended decoded frames");
  if (encode) {
    Shape half = blended;
    half[1] /= 2;
    l.offer(half, "posterior mean / std");
  }
  f.largest_allocation = l.bytes;
  f.largest_what = l.what;
  return f;
}

}  // namespace

VaeFootprint CogVideoXVae::encode_footprint(const nlohmann::json& config, const Shape& video, int64_t frames_batch,
                                            bool posterior) {
  return whole_call(config, video, true, frames_batch, posterior).footprint;
}

VaeFootprint CogVideoXVae::decode_footprint(const nlohmann::json& config, const Shape& z, int64_t latent_batch) {
  return whole_call(config, z, false, latent_batch, false).footprint;
}

VaeFootprint CogVideoXVae::encode_tiled_footprint(const nlohmann::json& config, const Shape& video, const VaeTiling& tiling,
                                                  int64_t frames_batch) {
  const TilePlan plan = TilePlan::for_encode(VaeConfig::from_json(config), tiling);
  if (!(video.size() == 5 && (video[4] > plan.tile_in_w || video[3] > plan.tile_in_h)))
    return encode_footprint(config, video, frames_batch, true);  // encode_tiled falls back to encode
  return tiled_call(config, video, plan, true, frames_batch);
}

VaeFootprint CogVideoXVae::decode_tiled_footprint(const nlohmann::json& config, const Shape& z, const VaeTiling& tiling,
                                                  int64_t latent_batch) {
  const TilePlan plan = TilePlan::for_decode(VaeConfig::from_json(config), tiling);
  if (!(z.size() == 5 && (z[4] > plan.tile_in_w || z[3] > plan.tile_in_h))) return decode_footprint(config, z, latent_batch);
  return tiled_call(config, z, plan, false, latent_batch);
}

uint64_t CogVideoXVae::encode_working_bytes(const nlohmann::json& config, const Shape& video, int64_t frames_batch) {
  return dry_run(config, video, true, frames_batch).footprint.working;
}

uint64_t CogVideoXVae::decode_working_bytes(const nlohmann::json& config, const Shape& z, int64_t latent_batch) {
  return dry_run(config, z, false, latent_batch).footprint.working;
}

// ---- tiling ---------------------------------------------------------------------------------------------------

VaePosterior CogVideoXVae::encode_tiled(const Tensor& video, const VaeTiling& tiling) {
  check_video("encode_tiled", video, cfg_.in_channels);
  const TilePlan plan = TilePlan::for_encode(cfg_, tiling);
  const int64_t H = video.dim(3), W = video.dim(4);
  if (!(W > plan.tile_in_w || H > plan.tile_in_h)) return encode(video);
  check_allocations("tiled encode", encode_tiled_footprint(weights_.config(), video.shape(), tiling, sample_frames_batch));
  HostTensor host = video.download(ctx_);
  HostTensor moments = run_tiled(plan, host, [&](const HostTensor& tile) {
    return encode_moments(Tensor::upload(ctx_, tile, "vae tile")).download(ctx_);
  });
  return posterior_of(Tensor::upload(ctx_, moments, "vae moments"));
}

Tensor CogVideoXVae::decode_tiled(const Tensor& z, const VaeTiling& tiling) {
  check_video("decode_tiled", z, cfg_.latent_channels);
  const TilePlan plan = TilePlan::for_decode(cfg_, tiling);
  const int64_t H = z.dim(3), W = z.dim(4);
  if (!(W > plan.tile_in_w || H > plan.tile_in_h)) return decode(z);
  check_allocations("tiled decode", decode_tiled_footprint(weights_.config(), z.shape(), tiling, latent_frames_batch));
  HostTensor host = z.download(ctx_);
  HostTensor frames = run_tiled(plan, host, [&](const HostTensor& tile) {
    return decode(Tensor::upload(ctx_, tile, "vae tile")).download(ctx_);
  });
  return Tensor::upload(ctx_, frames, "vae frames");
}

// ---- scaling --------------------------------------------------------------------------------------------------

void CogVideoXVae::to_diffusion_latent(vk::Recorder& rec, const Tensor& z, const Tensor& y) const {
  ops::scale(rec, z, y, float(cfg_.scaling_factor));
}

void CogVideoXVae::from_diffusion_latent(vk::Recorder& rec, const Tensor& x, const Tensor& z) const {
  // diffusers divides (latents / scaling_factor); multiplying by the reciprocal can differ by 1 ulp.
  ops::scale(rec, x, z, float(1.0 / cfg_.scaling_factor));
}

void CogVideoXVae::sample(vk::Recorder& rec, const VaePosterior& p, const Tensor& noise, const Tensor& out) {
  ops::mul(rec, p.std, noise, out);  // torch: mean + std * sample, the product rounded first
  ops::add(rec, out, p.mean, out);
}

}  // namespace dvs::models
