#include "tensor/ops_position.hpp"

#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include "tensor/binding_split.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {
namespace {

// torch.linspace(start, end, steps) in float32 as the CPU kernel computes it: the first half counts up
// from start, the second half down from end.
std::vector<float> linspace_f32(double start_d, double end_d, int64_t steps) {
  std::vector<float> v(size_t(std::max<int64_t>(steps, 0)));
  if (steps == 1) v[0] = float(start_d);
  if (steps <= 1) return v;
  const float start = float(start_d), end = float(end_d);
  const float step = (end - start) / float(steps - 1);
  const int64_t halfway = steps / 2;
  for (int64_t i = 0; i < steps; ++i) {
    volatile float prod = step * float(i < halfway ? i : steps - i - 1);  // no fused multiply-add
    v[size_t(i)] = i < halfway ? start + prod : end - prod;
  }
  return v;
}

// get_1d_rotary_pos_embed frequencies: 1 / theta^(arange(0, dim, 2) / dim), fp32.
std::vector<float> rope_freqs(int64_t dim) {
  std::vector<float> f(size_t(dim / 2));
  for (int64_t j = 0; j < dim / 2; ++j) {
    float e = float(2 * j) / float(dim);
    f[size_t(j)] = 1.0f / std::pow(10000.0f, e);
  }
  return f;
}

// Python's round(): half to even.
int64_t py_round(double v) { return int64_t(std::nearbyint(v)); }

}  // namespace

RopeTables cogvideox_rope_tables(int64_t head_dim, int64_t frames, int64_t grid_h, int64_t grid_w, int64_t base_h,
                                 int64_t base_w) {
  if (head_dim < 16 || head_dim % 16 != 0)
    throw Error("rope: head_dim " + std::to_string(head_dim) + " must be a positive multiple of 16");
  if (frames < 1 || grid_h < 1 || grid_w < 1 || base_h < 1 || base_w < 1)
    throw Error("rope: empty token grid or base size");
  // get_resize_crop_region_for_grid((grid_h, grid_w), base_w, base_h)
  const double th = double(base_h), tw = double(base_w), h = double(grid_h), w = double(grid_w);
  int64_t resize_h, resize_w;
  if (h / w > th / tw) {
    resize_h = base_h;
    resize_w = py_round(th / h * w);
  } else {
    resize_w = base_w;
    resize_h = py_round(tw / w * h);
  }
  const int64_t top = py_round((th - double(resize_h)) / 2.0), left = py_round((tw - double(resize_w)) / 2.0);
  const int64_t bottom = top + resize_h, right = left + resize_w;

  // get_3d_rotary_pos_embed, grid_type "linspace".
  std::vector<float> gh = linspace_f32(double(top), double(bottom) * double(grid_h - 1) / double(grid_h), grid_h);
  std::vector<float> gw = linspace_f32(double(left), double(right) * double(grid_w - 1) / double(grid_w), grid_w);
  std::vector<float> gt = linspace_f32(0.0, double(frames) * double(frames - 1) / double(frames), frames);
  const int64_t dt = head_dim / 4, dh = head_dim / 8 * 3, dw = head_dim / 8 * 3;
  const std::vector<float> ft = rope_freqs(dt), fh = rope_freqs(dh), fw = rope_freqs(dw);

  const int64_t n = frames * grid_h * grid_w;
  RopeTables out{HostTensor({n, head_dim}, DType::f32), HostTensor({n, head_dim}, DType::f32)};
  float* c = out.cos.as<float>();
  float* s = out.sin.as<float>();
  auto put = [&](int64_t row, int64_t col0, float pos, const std::vector<float>& freqs) {
    for (size_t j = 0; j < freqs.size(); ++j) {
      float a = pos * freqs[j];  // torch.outer, fp32
      float cv = std::cos(a), sv = std::sin(a);
      size_t at = size_t(row * head_dim + col0) + 2 * j;
      c[at] = c[at + 1] = cv;
      s[at] = s[at + 1] = sv;
    }
  };
  for (int64_t f = 0; f < frames; ++f)
    for (int64_t y = 0; y < grid_h; ++y)
      for (int64_t x = 0; x < grid_w; ++x) {
        const int64_t row = (f * grid_h + y) * grid_w + x;
        put(row, 0, gt[size_t(f)], ft);
        put(row, dt, gh[size_t(y)], fh);
        put(row, dt + dh, gw[size_t(x)], fw);
      }
  return out;
}

RopeTables cogvideox_rope_tables_for_video(int64_t height, int64_t width, int64_t latent_frames,
                                           int64_t vae_scale_spatial, int64_t patch_size, int64_t sample_height,
                                           int64_t sample_width, int64_t head_dim) {
  if (vae_scale_spatial < 1 || patch_size < 1) throw Error("rope: VAE scale and patch size must be positive");
  const int64_t grid_h = height / (vae_scale_spatial * patch_size), grid_w = width / (vae_scale_spatial * patch_size);
  return cogvideox_rope_tables(head_dim, latent_frames, grid_h, grid_w, sample_height / patch_size,
                               sample_width / patch_size);
}

void rope(vk::Recorder& rec, const Tensor& x, const Tensor& y, int64_t batch, int64_t seq_len, int64_t first,
          int64_t heads, int64_t head_dim, int64_t col_offset, const Tensor& cos, const Tensor& sin) {
  const char* op = "rope";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect_shape(op, "y", y, x.shape());
  expect_dtype(op, "cos", cos, DType::f32);
  expect_dtype(op, "sin", sin, DType::f32);
  if (x.rank() != 2 || x.dim(0) != batch * seq_len)
    throw Error("internal: rope: x must be [batch*seq_len, row_stride] = [" + std::to_string(batch * seq_len) +
                ", ...], got " + x.describe());
  if (cos.rank() != 2 || cos.dim(1) != head_dim) throw Error("internal: rope: cos is " + cos.describe());
  expect_shape(op, "sin", sin, cos.shape());
  const int64_t n = cos.dim(0);
  if (head_dim < 2 || head_dim % 2 != 0 || heads < 1 || col_offset < 0 || col_offset + heads * head_dim > x.dim(1) ||
      first < 0 || first + n > seq_len)
    throw Error("internal: rope: " + std::to_string(heads) + "x" + std::to_string(head_dim) + " columns from " +
                std::to_string(col_offset) + ", tokens [" + std::to_string(first) + ", " + std::to_string(first + n) +
                ") do not fit " + x.describe() + " with sequence length " + std::to_string(seq_len));
  if (x.numel() > int64_t(UINT32_MAX)) throw Error("internal: rope: " + x.describe() + " too large");
  if (n == 0) return;
  // Too large for one binding: each batch's tokens in chunks, x/y rows and cos/sin rows bound per chunk. A
  // chunk's x/y window starts at the aligned row at or before it; the rows skipped go as `first`.
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint64_t cap = binding_capacity(caps, 0), row_bytes = uint64_t(x.dim(1)) * 4;
  if (x.bytes() > cap || cos.bytes() > cap) {
    const uint64_t align = binding_alignment(caps);
    const int64_t lead = int64_t(align / std::gcd(align, row_bytes));  // rows between aligned row starts
    int64_t per = rows_per_chunk(caps, op, {RowOperand{row_bytes, 0}, RowOperand{uint64_t(head_dim) * 4, 0}}, n);
    if (uint64_t(per + lead - 1) * row_bytes > cap) {  // keep room for the lead-in, chunks still aligned
      const int64_t step = std::lcm(lead, int64_t(align / std::gcd(align, uint64_t(head_dim) * 4)));
      per = (int64_t(cap / row_bytes) - lead + 1) / step * step;
    }
    if (per < 1) throw Error("internal: rope: a row of " + x.describe() + " leaves no room in one binding");
    rec.context().note_split(op);  // the chunks below recurse into the unsplit path
    for (int64_t b = 0; b < batch; ++b)
      for_each_chunk(n, per, [&](int64_t t0, int64_t nt) {
        const int64_t row = b * seq_len + first + t0, base = row / lead * lead;
        rope(rec, x.rows(base, row - base + nt), y.rows(base, row - base + nt), 1, row - base + nt, row - base,
             heads, head_dim, col_offset, cos.rows(t0, nt), sin.rows(t0, nt));
      });
    return;
  }
  struct {
    uint32_t B, L, first, n, H, Dh, row_stride, col_offset;
  } p{uint32_t(batch), uint32_t(seq_len), uint32_t(first), uint32_t(n), uint32_t(heads), uint32_t(head_dim),
      uint32_t(x.dim(1)), uint32_t(col_offset)};
  const bool vec4 = head_dim % 4 == 0 && x.dim(1) % 4 == 0 && col_offset % 4 == 0;
  uint32_t spec[] = {vec4 ? 1u : 0u};
  // Views are read as vec4 arrays: widen to whole 16-byte units (allocations are >= 64-byte aligned).
  auto v4 = [](const Tensor& t) {
    vk::BufferView v = t.buffer();
    v.size = (v.size + 15) / 16 * 16;
    return v;
  };
  Grid g = grid_1d(rec.context().caps(), batch * n * (head_dim / (vec4 ? 4 : 2)), 64);
  rec.dispatch(rec.context().pipelines().get("nn/rope", spec), {v4(x), v4(y), v4(cos), v4(sin)}, &p,
               sizeof p, g.x, g.y, 1, "rope");
}

void timestep_embedding(vk::Recorder& rec, const Tensor& timesteps, const Tensor& emb, bool flip_sin_to_cos,
                        float freq_shift, float scale) {
  const char* op = "timestep_embedding";
  expect_dtype(op, "timesteps", timesteps, DType::f32);
  expect_dtype(op, "emb", emb, DType::f32);
  if (timesteps.rank() != 1 || emb.rank() != 2 || emb.dim(0) != timesteps.dim(0) || emb.dim(1) < 2)
    throw Error("internal: timestep_embedding: timesteps " + timesteps.describe() + ", emb " + emb.describe());
  const int64_t B = emb.dim(0), D = emb.dim(1), half = D / 2;
  if (float(half) - freq_shift == 0.0f) throw Error("internal: timestep_embedding: half_dim equals freq_shift");
  struct {
    uint32_t B, D, half_dim, flip;
    float freq_shift, scale;
  } p{uint32_t(B), uint32_t(D), uint32_t(half), flip_sin_to_cos ? 1u : 0u, freq_shift, scale};
  Grid g = grid_1d(rec.context().caps(), B * half, 64);
  rec.dispatch(rec.context().pipelines().get("nn/timestep_embedding"), {timesteps.buffer(), emb.buffer()}, &p,
               sizeof p, g.x, g.y, 1, "timestep_embedding");
}

}  // namespace dvs::ops
