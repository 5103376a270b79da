#version 450
#extension GL_GOOGLE_include_directive : require
// Convolution weights [Cout, Cin, taps] (taps = kt*kh*kw, any of f32/f16/bf16) repacked for conv_gemm to
// [Cout, taps, CP] in the same dtype (CP = Cin rounded up to 8, the extra channels zero), so that 8
// consecutive input channels of one tap are one RGBA32UI texel (16-bit) or two (f32). One invocation
// writes one 32-bit word: two 16-bit values or one f32. Values are copied bit for bit.
// Packed here: output channels [co0, co0 + groups' count) and input channels [ci0, ci0 + cc) (CP = cc rounded
// up to 8); one dispatch writes packed words [word0, word0 + words) and reads W through a sub-view starting at
// source element src_base (even for 16-bit weights).
layout(local_size_x = 64) in;
#include "index.glsl"
layout(constant_id = 0) const uint WDT = 2;  // 0 f32, 1 f16, 2 bf16

layout(std430, binding = 0) readonly buffer W { uint w[]; };
layout(std430, binding = 1) writeonly buffer Out { uint o[]; };

layout(push_constant) uniform Push {
  uint words;  // words of this dispatch
  uint cin, taps, cp;
  uint co0, ci0, cc, word0, src_base;
} p;

uint element_bits(uint co, uint tap, uint ci) {  // source element (co, ci, tap), 0 past Cin
  if (ci >= p.cc) return 0u;
  uint e = ((p.co0 + co) * p.cin + p.ci0 + ci) * p.taps + tap;
  if (WDT == 0) return w[e - p.src_base];
  uint word = w[(e - p.src_base) >> 1];
  return (e & 1u) == 0u ? (word & 0xffffu) : (word >> 16);
}

void main() {
  uint i = flat_index();
  if (i >= p.words) return;
  i += p.word0;
  uint per = WDT == 0 ? 1u : 2u;
  uint e = i * per;  // first packed element of this word (cp is a multiple of 8, so a word never crosses a tap)
  uint ci = e % p.cp, t = e / p.cp;
  uint tap = t % p.taps, co = t / p.taps;
  if (WDT == 0) o[i] = element_bits(co, tap, ci);
  else o[i] = element_bits(co, tap, ci) | (element_bits(co, tap, ci + 1u) << 16);
}
