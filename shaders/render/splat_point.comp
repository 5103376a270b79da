#version 450
// Hard z-buffer point mode (nearest point wins), two passes selected by PASS, both zero-initialised keys:
//  PASS 0: every point in front of the camera goes to its nearest pixel (round(u), round(v)) inside the
//          image; zkey[pixel] = atomicMax(0xFFFFFFFF − floatBits(z2)) keeps the nearest depth.
//  PASS 1: the points whose depth equals the pixel's nearest depth write idkey[pixel] =
//          atomicMax(0xFFFFFFFF − source pixel index), so the lowest index wins ties (deterministic).
// The same code computes z2 in both passes (`precise`), so the equality test is exact.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(constant_id = 0) const uint PASS = 0;
layout(std430, binding = 0) readonly buffer Depth { float depth[]; };
layout(std430, binding = 1) buffer ZKey { uint zkey[]; };
layout(std430, binding = 2) buffer IdKey { uint idkey[]; };
#include "splat_common.glsl"

void main() {
  uint x, y, i;
  if (!source_pixel(x, y, i)) return;
  precise MovedPoint m = move_point(x, y, depth[i]);
  const vec3 X2 = m.X2;
  if (isnan(X2.x) || isnan(X2.y) || isinf(X2.x) || isinf(X2.y) || !(X2.z > 0.0) || isinf(X2.z)) return;
  vec2 uv = project_point(x, y, m);
  if (isnan(uv.x) || isnan(uv.y)) return;
  vec2 r = floor(uv + 0.5);
  if (r.x < 0.0 || r.y < 0.0 || r.x >= float(p.W) || r.y >= float(p.H)) return;
  uint q = (p.frame * p.H + uint(r.y)) * p.W + uint(r.x);
  uint key = 0xFFFFFFFFu - floatBitsToUint(X2.z);
  if (PASS == 0u) {
    atomicMax(zkey[q], key);
  } else if (zkey[q] == key) {
    atomicMax(idkey[q], 0xFFFFFFFFu - (y * p.W + x));
  }
}
