// Eight consecutive packed weights widened to f32, for the kernels that read their weights through a
// uniform texel buffer (linalg/linear.comp, nn/conv_gemm.comp). The including shader declares
//   layout(constant_id = ...) const int WTYPE;  // weight storage: 0 f32, 1 f16, 2 bf16
//   layout(binding = ...) uniform utextureBuffer Wt;  // RGBA32UI: 4 f32 words, or 8 packed 16-bit values
// before including this file. f32 weights take two texels, 16-bit ones one (no 16-bit storage needed); a bf16
// is the top half of an f32, so widening it is a shift (the low half of each word holds the first value).

// Weights e .. e + 7 (e a multiple of 8).
void w_step(uint e, out float w[8]) {
  if (WTYPE == 0) {
    uvec4 a = texelFetch(Wt, int(e >> 2)), b = texelFetch(Wt, int(e >> 2) + 1);
    w[0] = uintBitsToFloat(a.x); w[1] = uintBitsToFloat(a.y); w[2] = uintBitsToFloat(a.z); w[3] = uintBitsToFloat(a.w);
    w[4] = uintBitsToFloat(b.x); w[5] = uintBitsToFloat(b.y); w[6] = uintBitsToFloat(b.z); w[7] = uintBitsToFloat(b.w);
  } else {
    uvec4 t = texelFetch(Wt, int(e >> 3));
    if (WTYPE == 1) {
      vec2 a = unpackHalf2x16(t.x), b = unpackHalf2x16(t.y), c = unpackHalf2x16(t.z), d = unpackHalf2x16(t.w);
      w[0] = a.x; w[1] = a.y; w[2] = b.x; w[3] = b.y; w[4] = c.x; w[5] = c.y; w[6] = d.x; w[7] = d.y;
    } else {
      w[0] = uintBitsToFloat(t.x << 16); w[1] = uintBitsToFloat(t.x & 0xffff0000u);
      w[2] = uintBitsToFloat(t.y << 16); w[3] = uintBitsToFloat(t.y & 0xffff0000u);
      w[4] = uintBitsToFloat(t.z << 16); w[5] = uintBitsToFloat(t.z & 0xffff0000u);
      w[6] = uintBitsToFloat(t.w << 16); w[7] = uintBitsToFloat(t.w & 0xffff0000u);
    }
  }
}
