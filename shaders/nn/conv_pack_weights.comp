#version 450
#extension GL_GOOGLE_include_directive : require
// Convolution weights (any of f32/f16/bf16) repacked for the conv GEMM kernels to [Cout, taps, CP] in the same
// dtype (taps = kt*kh*kw, CP = the packed input channels rounded up to 8, the extra channels zero), so that 8
// consecutive input channels of one tap are one RGBA32UI texel (16-bit) or two (f32). Values are copied bit for
// bit. The source is read through strides (elements): the stored layout [Cout, Cin, taps] (s_co = Cin * taps,
// s_ci = taps, s_tap = 1), or weights packed once at load, [Cout, taps, CP'] (s_co = taps * CP', s_ci = 1,
// s_tap = CP'), of which a call takes a slice (some input channels, an unaligned group of output channels).
// One invocation writes one 32-bit word column (two 16-bit values or one f32) for every tap of one output channel:
// one division per invocation instead of three per word (a vector integer division is a scalar loop on CPU
// drivers, and it was what bounded this shader).
// Packed here: output channels [co0, co0 + groups' count) and input channels [ci0, ci0 + cc) (CP = cc rounded
// up to 8); one dispatch writes the columns [item0, item0 + items) (output channel * CP / per + word) at word
// dst_base of the bound output (a sub-view: the word index it starts at) and reads W through a sub-view starting
// at source element src_base (even for 16-bit weights).
layout(local_size_x = 64) in;
#include "index.glsl"
layout(constant_id = 0) const uint WDT = 2;  // 0 f32, 1 f16, 2 bf16

layout(std430, binding = 0) readonly buffer W { uint w[]; };
layout(std430, binding = 1) writeonly buffer Out { uint o[]; };

layout(push_constant) uniform Push {
  uint items;  // word columns of this dispatch
  uint s_co, s_ci, s_tap, taps, cp;
  uint co0, ci0, cc, item0, src_base, dst_base;
} p;

uint element_bits(uint e) {  // source element e (relative to the whole W), as its bits
  if (WDT == 0) return w[e - p.src_base];
  uint word = w[(e - p.src_base) >> 1];
  return (e & 1u) == 0u ? (word & 0xffffu) : (word >> 16);
}

void main() {
  uint i = flat_index();
  if (i >= p.items) return;
  i += p.item0;
  const uint per = WDT == 0 ? 1u : 2u, cpw = p.cp / per;  // words per tap
  uint co = i / cpw, cw = i % cpw, ci = cw * per;
  uint src = (p.co0 + co) * p.s_co + (p.ci0 + ci) * p.s_ci;  // element (co, ci, tap 0)
  uint dst = co * p.taps * cpw + cw - p.dst_base;            // word (co, tap 0, ci)
  bool lo = ci < p.cc, hi = ci + 1u < p.cc;                  // past the channels packed: zero
  for (uint tap = 0; tap < p.taps; ++tap, dst += cpw, src += p.s_tap) {
    uint bits = lo ? element_bits(src) : 0u;
    if (WDT != 0u && hi) bits |= element_bits(src + p.s_ci) << 16;
    o[dst] = bits;
  }
}
