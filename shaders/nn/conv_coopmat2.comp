#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int32 : require
#extension GL_EXT_shader_16bit_storage : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_KHR_cooperative_matrix : require
#extension GL_NV_cooperative_matrix2 : require
// The convolution on tensor cores through VK_NV_cooperative_matrix2 (DeviceTuning::conv_coopmat2, where the device
// has workgroup-scope matrices with flexible dimensions and tensor addressing: NVIDIA's): the implicit GEMM of
// conv_coopmat.comp over the same repacked operands and push constants (conv_push.glsl), with the gather done by
// tensor addressing. A workgroup computes a PH x PW patch of output pixels of one frame (BM = PH·PW matrix rows)
// times BN output channels; per tap of the kernel and per BK input channels it loads the input patch the tap
// reads as a 4-D slice [1 frame][PH rows][PW columns][BK channels] of the packed chunk [frames][rows][columns][CP]
// (fp16, channels-last), whose clamp-to-constant mode reads the padding as zeros (rows and columns outside the
// chunk are exactly the image's padding), and nearest x2 upsampling as a block size of 2 on rows and columns (each
// source row and column addressed twice); the weights' BN x BK slice of [Cout][taps·CP] read transposed. The driver
// stages both through shared memory. Epilogue: bias (first input-channel chunk) or y's partial sum (later ones)
// per element, then one tensor store into channels-first y through a view that puts the channels outermost.
// The host takes it for stride 1, an fp16 repack, fp16 weights, channels a multiple of BK and a y whose rows and
// columns nest inside its channel stride (conv_coopmat2_fits); the KHR kernel (conv_coopmat.comp) elsewhere, and
// as this kernel's twin on devices without coopmat2 (lavapipe among them: compiled and validated there, never run).
// fp16 operands, fp32 sums, as conv_coopmat.
layout(local_size_x_id = 0) in;              // WG: the invocations the device's workgroup-scope shape needs
layout(constant_id = 1) const uint PH = 4;   // output rows per workgroup
layout(constant_id = 2) const uint PW = 32;  // output columns per workgroup
layout(constant_id = 3) const uint BN = 128; // output channels per workgroup
layout(constant_id = 4) const uint BK = 32;  // input channels per step (the host checks CP % BK == 0)
layout(constant_id = 5) const int BTYPE = 2; // bias storage (conv_bias.glsl): 0 f32, 1 f16, 2 bf16
const uint BM = PH * PW;

layout(std430, binding = 0) readonly buffer X { float16_t x[]; };  // the packed chunk (+ its zero pixel, unused here)
layout(std430, binding = 1) readonly buffer W { float16_t w[]; };  // packed weights [Cout][taps·CP]
layout(std430, binding = 2) readonly buffer Bias { uint bias[]; };
layout(std430, binding = 3) buffer Y { float y[]; };
#include "conv_push.glsl"
#include "conv_bias.glsl"

// The output value of the tile's element (row, col): pixel (r0 + row / PW, c0 + row % PW) of chunk frame f, channel
// n0 + col, with the bias or added to y's partial sum; outside the chunk the value is left (the store drops it).
float conv_epilogue(const in uint32_t row, const in uint32_t col, const in float v, const in uint32_t f,
                    const in uint32_t r0, const in uint32_t c0, const in uint32_t n0) {
  const uint r = r0 + row / PW, c = c0 + row % PW, n = n0 + col;
  if (r >= p.rows || c >= p.wo || n >= p.N) return v;
  if (p.accumulate != 0u) return y[p.y_base + f * p.ys_f + r * p.ys_h + c * p.ys_w + n * p.ys_c] + v;
  return p.has_bias != 0u ? v + w_bias(p.n_base + n) : v;
}

void main() {
  // The workgroup's patch: x walks the chunk's column tiles, then row tiles, then frames.
  const uint tiles_w = (p.wo + PW - 1u) / PW, tiles_h = (p.rows + PH - 1u) / PH;
  const uint tw = gl_WorkGroupID.x % tiles_w, th = (gl_WorkGroupID.x / tiles_w) % tiles_h;
  const uint f = gl_WorkGroupID.x / (tiles_w * tiles_h), n0 = gl_WorkGroupID.y * BN;
  const uint r0 = th * PH, c0 = tw * PW;  // chunk-relative output row and column

  // The packed chunk as [frames][rows][columns][CP]; upsampled, as [frames][2·rows][2·columns][CP] in blocks of 2.
  const uint up = p.up == 2u ? 2u : 1u, taps = p.kt * p.kh * p.kw, K = taps * p.cp;
  tensorLayoutNV<4, gl_CooperativeMatrixClampModeConstantNV> lx = createTensorLayoutNV(4, gl_CooperativeMatrixClampModeConstantNV);
  lx = setTensorLayoutBlockSizeNV(lx, 1, up, up, 1);
  lx = setTensorLayoutDimensionNV(lx, f + p.kt, p.src_rows * up, p.src_w * up, p.cp);
  lx = setTensorLayoutStrideNV(lx, p.src_rows * p.src_w * p.cp, p.src_w * p.cp, p.cp, 1);
  // The patch's first input row and column for tap (0, 0), in the chunk's (upsampled) coordinates.
  const int ir = int(p.oh0 + r0) - p.pad_top - int(p.src_r0 * up);
  const int ic = int(p.ow0 + c0) - p.pad_left - int(p.src_c0 * up);
  tensorLayoutNV<2, gl_CooperativeMatrixClampModeConstantNV> lw = createTensorLayoutNV(2, gl_CooperativeMatrixClampModeConstantNV);
  lw = setTensorLayoutDimensionNV(lw, p.N, K);
  lw = setTensorLayoutStrideNV(lw, K, 1);
  tensorViewNV<2, false, 1, 0> transposed = createTensorViewNV(2, false, 1, 0);  // B[k][n] = W[n][k]

  coopmat<float, gl_ScopeWorkgroup, BM, BN, gl_MatrixUseAccumulator> acc =
      coopmat<float, gl_ScopeWorkgroup, BM, BN, gl_MatrixUseAccumulator>(0.0);
  uint k = 0u;  // the weights' column of (tap, channel): taps in the packed order (frame, row, column)
  for (uint at = 0u; at < p.kt; ++at)
    for (uint u = 0u; u < p.kh; ++u)
      for (uint v = 0u; v < p.kw; ++v)
        for (uint c = 0u; c < p.cp; c += BK, k += BK) {
          coopmat<float16_t, gl_ScopeWorkgroup, BM, BK, gl_MatrixUseA> a;
          coopmat<float16_t, gl_ScopeWorkgroup, BK, BN, gl_MatrixUseB> b;
          coopMatLoadTensorNV(a, x, 0, sliceTensorLayoutNV(lx, int(f + at), 1, ir + int(u), PH, ic + int(v), PW, int(c), BK));
          coopMatLoadTensorNV(b, w, 0, sliceTensorLayoutNV(lw, int(n0), BN, int(k), BK), transposed);
          acc = coopMatMulAdd(a, b, acc);
        }

  coopmat<float, gl_ScopeWorkgroup, BM, BN, gl_MatrixUseAccumulator> out_tile;
  coopMatPerElementNV(out_tile, acc, conv_epilogue, f, r0, c0, n0);
  // y as [channels][rows][columns] of frame f from its element y_base + f·ys_f (16-byte aligned, and the strides
  // nesting with columns innermost: the host checks both per dispatch); the tile's rows (pixels, row-major) and
  // columns (channels) are put in that order by a view of the slice [BN][PH][PW] whose innermost matrix index runs
  // over channels.
  tensorLayoutNV<3, gl_CooperativeMatrixClampModeConstantNV> ly = createTensorLayoutNV(3, gl_CooperativeMatrixClampModeConstantNV);
  ly = setTensorLayoutDimensionNV(ly, p.N, p.rows, p.wo);
  ly = setTensorLayoutStrideNV(ly, p.ys_c, p.ys_h, p.ys_w);
  tensorViewNV<3, false, 1, 2, 0> channels_inner = createTensorViewNV(3, false, 1, 2, 0);
  coopMatStoreTensorNV(out_tile, y, p.y_base + f * p.ys_f, sliceTensorLayoutNV(ly, int(n0), BN, int(r0), PH, int(c0), PW),
                       channels_inner);
}
