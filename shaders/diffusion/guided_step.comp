#version 450
#extension GL_GOOGLE_include_directive : require
// One whole DDIM step after the model call, in one dispatch (the combine and the two linear maps were three
// dispatches; on small latents the dispatch overhead dominated the step's non-model time):
//   ĝ       = u + s·(c − u)  with v = [u; c] (n elements each), or ĝ = v when guidance is off;
//             s = dynamic_scale where positions ≠ 0 (official position-wise rule, docs/design.md §6.7),
//             s = scale elsewhere (constant guidance: no positions, s = scale everywhere);
//   pred_x0 = px·x + pv·ĝ ;   x_next = nx·x + nv·ĝ.
layout(local_size_x = 64) in;
#include "index.glsl"

layout(std430, binding = 0) readonly buffer V { float v[]; };
layout(std430, binding = 1) readonly buffer X { float x[]; };
layout(std430, binding = 2) readonly buffer P { float positions[]; };  // bound to v when unused
layout(std430, binding = 3) writeonly buffer Next { float x_next[]; };
layout(std430, binding = 4) writeonly buffer Pred { float pred_x0[]; };
layout(std430, binding = 5) readonly buffer V1 { float v1[]; };  // v's second row, from element v1_off
layout(push_constant) uniform Push {
  uint n;
  uint flags;  // 1: v has two rows (guidance); 2: use positions; 4: write pred_x0
  float scale, dynamic_scale;
  float px, pv, nx, nv;
  uint v1_off;  // a split call binds each row of v (and every other tensor) per chunk
} p;

void main() {
  uint i = flat_index();
  if (i >= p.n) return;
  float g = v[i];
  if ((p.flags & 1u) != 0u) {
    float s = ((p.flags & 2u) != 0u && positions[i] != 0.0) ? p.dynamic_scale : p.scale;
    g = g + s * (v1[p.v1_off + i] - g);
  }
  float xi = x[i];
  x_next[i] = p.nx * xi + p.nv * g;
  if ((p.flags & 4u) != 0u) pred_x0[i] = p.px * xi + p.pv * g;
}
