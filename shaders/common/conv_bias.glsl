// The convolution's bias [Cout] as the conv GEMM kernels read it (conv_gemm, conv_tiled, conv_coopmat): in its own
// dtype BTYPE (0 f32, 1 f16, 2 bf16, a spec constant of the includer), independent of the weights' (weights packed
// at load in the tensor cores' fp16 keep a bf16 bias exact). Needs `bias[]`, uints (16-bit values two per word).
float w_bias(uint n) {
  if (BTYPE == 0) return uintBitsToFloat(bias[n]);
  uint u = bias[n >> 1], bits = (n & 1u) == 0u ? (u & 0xffffu) : (u >> 16);
  return BTYPE == 1 ? unpackHalf2x16(bits).x : uintBitsToFloat(bits << 16);
}
