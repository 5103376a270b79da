#version 450
// Stochastic Latent Modulation: reduces the renderer's pixel mask (and disparity) over each latent cell's
// footprint. Latent frame 0 covers pixel frame 0 alone; latent frame j >= 1 covers pixel frames 4j-3 .. 4j.
// MODE 0 (paper): out[0] = mean of (1 - clamp(mask, 0, 1)) over the 8x8 pixels of those frames (the hole
//   fraction); out[1] = mean of disparity / frame_max over the same pixels (0 where the frame max is 0), or 0
//   without depth.
// MODE 1 (official downsize_mask): temporal mean of the frames by pairs, then three times "zero-pad right and
//   bottom by 1, 3x3 average pool with stride 2". All stages are linear, so each latent cell is the sum over
//   the 27x27 (row path, column path) combinations of the pixel they reach, divided by 9^3; paths through
//   the zero padding contribute nothing. With masks in {0, 1/4, ..., 1} the sum is exact. out[0] = V.
// One invocation per latent cell of latent frames [first_latent, end_latent); out is [2, Fl, Hl, Wl] (MODE 1
// writes the first plane only). mask and depth are bound from pixel frame pixel_frame0 on (a window of whole
// frames: clips over one binding run in windows of latent frames); frame_max is bound whole.
#extension GL_GOOGLE_include_directive : require

layout(constant_id = 0) const uint MODE = 0;
layout(local_size_x = 64) in;
#include "index.glsl"

layout(std430, binding = 0) readonly buffer Mask { float mask[]; };        // [Fp, H, W], 1 = visible
layout(std430, binding = 1) readonly buffer Depth { float depth[]; };      // [Fp, H, W] (dummy without depth)
layout(std430, binding = 2) readonly buffer FrameMax { float frame_max[]; };  // [Fp]
layout(std430, binding = 3) writeonly buffer Out { float out_[]; };
layout(push_constant) uniform Push {
  uint latent_frames, lh, lw;  // latent grid
  uint height, width;          // pixel size (multiples of 8)
  uint has_depth, metric;
  uint first_latent, end_latent, pixel_frame0;
} p;

float disparity(float x) {
  if (p.metric != 0u) return x > 0.0 ? 1.0 / x : 0.0;
  return x > 0.0 ? x : 0.0;
}

// Pixel index reached by path t (0..26 = three base-3 digits a, b, c) from latent index i through the three
// pad-1 / k3 / s2 stages of a dimension of n pixels: r = 2(2(2i + a) + b) + c, or ~0u when a stage's
// index falls into its zero padding. Summing over all 27 paths counts each pixel with its multiplicity.
uint path_pixel(uint i, uint t, uint n) {
  uint a = t / 9u, b = (t / 3u) % 3u, c = t % 3u;
  uint j2 = 2u * i + a;
  if (j2 >= n / 4u) return ~0u;
  uint j1 = 2u * j2 + b;
  if (j1 >= n / 2u) return ~0u;
  uint r = 2u * j1 + c;
  return r < n ? r : ~0u;
}

void main() {
  uint cells = p.latent_frames * p.lh * p.lw;
  uint cell = p.first_latent * p.lh * p.lw + flat_index();
  if (cell >= p.end_latent * p.lh * p.lw) return;
  uint w = cell % p.lw, h = (cell / p.lw) % p.lh, f = cell / (p.lw * p.lh);
  uint first = f == 0u ? 0u : 4u * f - 3u;
  uint nf = f == 0u ? 1u : 4u;
  uint plane = p.height * p.width;

  if (MODE == 0u) {
    float holes = 0.0, disp = 0.0;
    for (uint t = 0u; t < nf; ++t) {
      uint fb = (first + t - p.pixel_frame0) * plane;
      float fm = p.has_depth != 0u ? frame_max[first + t] : 0.0;
      for (uint y = 0u; y < 8u; ++y) {
        uint row = fb + (8u * h + y) * p.width + 8u * w;
        for (uint x = 0u; x < 8u; ++x) {
          holes += 1.0 - clamp(mask[row + x], 0.0, 1.0);
          if (fm > 0.0) disp += disparity(depth[row + x]) / fm;
        }
      }
    }
    float n = float(nf * 64u);
    out_[cell] = holes / n;
    out_[cells + cell] = disp / n;
  } else {
    // Loops over paths, not unrolled pixel windows: keeps the shader small for lavapipe's LLVM.
    float acc = 0.0;
    for (uint ty = 0u; ty < 27u; ++ty) {
      uint y = path_pixel(h, ty, p.height);
      if (y == ~0u) continue;
      for (uint tx = 0u; tx < 27u; ++tx) {
        uint x = path_pixel(w, tx, p.width);
        if (x == ~0u) continue;
        uint o = y * p.width + x + (first - p.pixel_frame0) * plane;
        float m;
        if (f == 0u) {
          m = mask[o];
        } else {  // pairs first, as the encoder's two time-compressing calls do
          uint b = o;
          m = ((mask[b] + mask[b + plane]) * 0.5 + (mask[b + 2u * plane] + mask[b + 3u * plane]) * 0.5) * 0.5;
        }
        acc += m;
      }
    }
    out_[cell] = acc / 729.0;
  }
}
