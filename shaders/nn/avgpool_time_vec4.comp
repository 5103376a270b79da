#version 450
// avgpool_time.comp for planes whose size H*W is a multiple of 4: the same arithmetic on vec4s (a quarter
// of the memory instructions, which lavapipe runs per lane).
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer X { vec4 x[]; };
layout(std430, binding = 1) writeonly buffer Y { vec4 y[]; };

layout(push_constant) uniform Push {
  uint hw4;     // H * W / 4
  uint frames;  // F
  uint frames_out;
  uint bc_begin;  // first b*C + c of this dispatch
  uint fo_begin;  // first output frame of this dispatch
  uint x_base, y_base;  // element (vec4 in the vec4 variant) of x / y at the start of the bound views
} p;

void main() {
  uint s = gl_GlobalInvocationID.x;
  if (s >= p.hw4) return;
  uint fo = p.fo_begin + gl_WorkGroupID.y;
  uint bc = p.bc_begin + gl_WorkGroupID.z;
  uint src = bc * p.frames * p.hw4 + s - p.x_base;
  bool odd = (p.frames & 1u) != 0u;
  vec4 v;
  if (odd && fo == 0u) {
    v = x[src];
  } else {
    uint first = odd ? 2u * fo - 1u : 2u * fo;
    v = (x[src + first * p.hw4] + x[src + (first + 1u) * p.hw4]) / 2.0;
  }
  y[(bc * p.frames_out + fo) * p.hw4 + s - p.y_base] = v;
}
