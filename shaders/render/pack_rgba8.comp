#version 450
// A rendered frame packed for display: render f32 [3,H,W] in [−1,1] + mask f32 [H,W] -> RGBA8 [H,W,4] (one u32
// per pixel, R in the low byte). Each channel is quantised as dvs's video writer does (io/pixel_levels.hpp:
// round((x + 1)·127.5) clamped to 0..255, halves away from zero); alpha 255 where mask > 0, else the pixel is
// black with alpha 0. The rounding is written out with floor and the exact fraction rather than round() (whose
// halves are implementation-defined) or floor(u + 0.5) (u + 0.5 can round up in float), so every pixel equals
// the host rule. With mask_only the mask alone is packed for display: opaque white where visible, opaque black
// elsewhere (an RGBA8 mask image an application can draw as it is).
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Render { float render[]; };
layout(std430, binding = 1) readonly buffer Mask { float mask[]; };
layout(std430, binding = 2) writeonly buffer Packed { uint packed[]; };
layout(push_constant) uniform Push {
  uint pixels;     // H·W
  uint mask_only;  // 1: pack the mask alone (white / black, alpha 255)
} p;
#include "index.glsl"

uint level(float x) {
  precise float u = clamp((x + 1.0) * 127.5, 0.0, 255.0);
  precise float whole = floor(u);
  precise float frac = u - whole;  // exact: u and floor(u) share the exponent range
  return uint(whole) + (frac >= 0.5 ? 1u : 0u);
}

void main() {
  const uint i = flat_index();
  if (i >= p.pixels) return;
  if (p.mask_only != 0u) {
    packed[i] = mask[i] > 0.0 ? 0xFFFFFFFFu : 0xFF000000u;
    return;
  }
  if (!(mask[i] > 0.0)) {
    packed[i] = 0u;
    return;
  }
  const uint r = level(render[i]), g = level(render[p.pixels + i]), b = level(render[2u * p.pixels + i]);
  packed[i] = r | (g << 8) | (b << 16) | (255u << 24);
}
