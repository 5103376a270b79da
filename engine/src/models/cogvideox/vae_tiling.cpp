#include "models/cogvideox/vae_tiling.hpp"

#include <algorithm>
#include <vector>

#include "dvs/error.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"

namespace dvs::models {
namespace {

// Python's int() of a non-negative double.
int64_t trunc(double v) { return int64_t(v); }

void resolve(const VaeConfig& cfg, const VaeTiling& t, int64_t& sh, int64_t& sw) {
  sh = t.tile_sample_min_height > 0 ? t.tile_sample_min_height : cfg.sample_height / 2;
  sw = t.tile_sample_min_width > 0 ? t.tile_sample_min_width : cfg.sample_width / 2;
}

void check5(const HostTensor& t, const char* what) {
  if (t.shape.size() != 5 || t.dtype != DType::f32) throw Error(std::string("VAE tiling: ") + what + " must be f32 5-D");
}

// x[..., h0:h0+hn, w0:w0+wn] (clamped like Python slicing).
HostTensor crop(const HostTensor& x, int64_t h0, int64_t hn, int64_t w0, int64_t wn) {
  const int64_t H = x.shape[3], W = x.shape[4];
  const int64_t h1 = std::min(H, h0 + hn), w1 = std::min(W, w0 + wn);
  HostTensor out({x.shape[0], x.shape[1], x.shape[2], h1 - h0, w1 - w0}, DType::f32);
  const int64_t planes = x.shape[0] * x.shape[1] * x.shape[2];
  const float* src = x.as<float>();
  float* dst = out.as<float>();
  for (int64_t p = 0; p < planes; ++p)
    for (int64_t y = h0; y < h1; ++y)
      std::copy(src + (p * H + y) * W + w0, src + (p * H + y) * W + w1, dst + (p * (h1 - h0) + (y - h0)) * (w1 - w0));
  return out;
}

// diffusers' tiling, either way: tiles of in_h x in_w at strides of (1 - overlap) of that size, each giving an
// out_h x out_w result that blends `overlap` of its size with its neighbours' and keeps the rest.
TilePlan plan_tiles(int64_t in_h, int64_t in_w, int64_t out_h, int64_t out_w, const VaeTiling& t) {
  TilePlan p;
  p.tile_in_h = in_h;
  p.tile_in_w = in_w;
  p.stride_h = trunc(double(in_h) * (1.0 - t.tile_overlap_factor_height));
  p.stride_w = trunc(double(in_w) * (1.0 - t.tile_overlap_factor_width));
  p.blend_h = trunc(double(out_h) * t.tile_overlap_factor_height);
  p.blend_w = trunc(double(out_w) * t.tile_overlap_factor_width);
  p.limit_h = out_h - p.blend_h;
  p.limit_w = out_w - p.blend_w;
  return p;
}

}  // namespace

// Encode: sample tiles in, latent tiles out; decode the other way round.
TilePlan TilePlan::for_encode(const VaeConfig& cfg, const VaeTiling& t) {
  int64_t sh, sw;
  resolve(cfg, t, sh, sw);
  const int64_t r = cfg.spatial_ratio();
  return plan_tiles(sh, sw, trunc(double(sh) / double(r)), trunc(double(sw) / double(r)), t);
}

TilePlan TilePlan::for_decode(const VaeConfig& cfg, const VaeTiling& t) {
  int64_t sh, sw;
  resolve(cfg, t, sh, sw);
  const int64_t r = cfg.spatial_ratio();
  return plan_tiles(trunc(double(sh) / double(r)), trunc(double(sw) / double(r)), sh, sw, t);
}

void blend_rows(const HostTensor& a, HostTensor& b, int64_t extent) {
  check5(a, "blend input");
  check5(b, "blend input");
  const int64_t Ha = a.shape[3], Hb = b.shape[3], W = b.shape[4];
  if (a.shape[4] != W) throw Error("VAE tiling: blend_v of tiles of different widths");
  extent = std::min({Ha, Hb, extent});
  const int64_t planes = b.shape[0] * b.shape[1] * b.shape[2];
  const float* pa = a.as<float>();
  float* pb = b.as<float>();
  for (int64_t y = 0; y < extent; ++y) {
    // torch: a * (1 - y / e) + b * (y / e), the Python doubles rounded to the tensor's float32.
    const float wa = float(1.0 - double(y) / double(extent)), wb = float(double(y) / double(extent));
    for (int64_t p = 0; p < planes; ++p) {
      const float* ra = pa + (p * Ha + (Ha - extent + y)) * W;
      float* rb = pb + (p * Hb + y) * W;
      for (int64_t x = 0; x < W; ++x) {
        const float u = ra[x] * wa, v = rb[x] * wb;
        rb[x] = u + v;
      }
    }
  }
}

void blend_cols(const HostTensor& a, HostTensor& b, int64_t extent) {
  check5(a, "blend input");
  check5(b, "blend input");
  const int64_t Wa = a.shape[4], Wb = b.shape[4], H = b.shape[3];
  if (a.shape[3] != H) throw Error("VAE tiling: blend_h of tiles of different heights");
  extent = std::min({Wa, Wb, extent});
  const int64_t planes = b.shape[0] * b.shape[1] * b.shape[2];
  const float* pa = a.as<float>();
  float* pb = b.as<float>();
  for (int64_t x = 0; x < extent; ++x) {
    const float wa = float(1.0 - double(x) / double(extent)), wb = float(double(x) / double(extent));
    for (int64_t p = 0; p < planes; ++p)
      for (int64_t y = 0; y < H; ++y) {
        const float u = pa[(p * H + y) * Wa + (Wa - extent + x)] * wa, v = pb[(p * H + y) * Wb + x] * wb;
        pb[(p * H + y) * Wb + x] = u + v;
      }
  }
}

HostTensor run_tiled(const TilePlan& plan, const HostTensor& in, const std::function<HostTensor(const HostTensor&)>& run) {
  check5(in, "input");
  if (plan.stride_h <= 0 || plan.stride_w <= 0) throw Error("VAE tiling: the tile overlap leaves no stride");
  const int64_t H = in.shape[3], W = in.shape[4];
  std::vector<std::vector<HostTensor>> rows;
  for (int64_t i = 0; i < H; i += plan.stride_h) {
    std::vector<HostTensor> row;
    for (int64_t j = 0; j < W; j += plan.stride_w) {
      HostTensor out = run(crop(in, i, plan.tile_in_h, j, plan.tile_in_w));
      check5(out, "tile output");
      row.push_back(std::move(out));
    }
    rows.push_back(std::move(row));
  }
  // Blend in place, in diffusers' order, and keep the top-left limit_h x limit_w of each tile.
  std::vector<std::vector<HostTensor>> kept(rows.size());
  for (size_t i = 0; i < rows.size(); ++i)
    for (size_t j = 0; j < rows[i].size(); ++j) {
      if (i > 0) blend_rows(rows[i - 1][j], rows[i][j], plan.blend_h);
      if (j > 0) blend_cols(rows[i][j - 1], rows[i][j], plan.blend_w);
      kept[i].push_back(crop(rows[i][j], 0, plan.limit_h, 0, plan.limit_w));
    }
  // Concatenate: columns within a row, then rows.
  const HostTensor& first = kept[0][0];
  int64_t out_h = 0, out_w = 0;
  for (auto& row : kept) out_h += row[0].shape[3];
  for (auto& t : kept[0]) out_w += t.shape[4];
  HostTensor out({first.shape[0], first.shape[1], first.shape[2], out_h, out_w}, DType::f32);
  const int64_t planes = first.shape[0] * first.shape[1] * first.shape[2];
  float* dst = out.as<float>();
  int64_t y0 = 0;
  for (auto& row : kept) {
    int64_t x0 = 0;
    for (auto& t : row) {
      if (t.shape[3] != row[0].shape[3] || shape_numel({t.shape[0], t.shape[1], t.shape[2]}) != planes)
        throw Error("VAE tiling: tiles of one row differ in size");
      const int64_t th = t.shape[3], tw = t.shape[4];
      const float* src = t.as<float>();
      for (int64_t p = 0; p < planes; ++p)
        for (int64_t y = 0; y < th; ++y)
          std::copy(src + (p * th + y) * tw, src + (p * th + y) * tw + tw, dst + (p * out_h + y0 + y) * out_w + x0);
      x0 += tw;
    }
    if (x0 != out_w) throw Error("VAE tiling: rows of different widths");
    y0 += row[0].shape[3];
  }
  return out;
}

}  // namespace dvs::models
