// The push constants of the convolution GEMM kernels that read the repacked operands (conv_coopmat.comp,
// conv_coopmat2.comp; the host's GemmPush in tensor/ops_conv.cpp), the whole output chunk's geometry:
//   M, N: the chunk's output pixels and channels; cp: packed input channels (a multiple of 8); kt, kh, kw: the
//   kernel; stride, up (1 or 2: nearest x2 upsampling of the input); wo, rows, oh0, ow0: the chunk's output
//   columns, rows and first row and column; pad_top, pad_left; in_h, in_w: the (upsampled) input's size; src_r0,
//   src_rows, src_w, src_c0: the packed chunk's first source row, its rows, columns and first column;
//   zero_texel: the zero pixel (4-channel units); y_base and ys_*: y's element of the chunk's first output and its
//   strides; has_bias, n_base (the bias of output channel 0), accumulate (add to y: a later input-channel chunk).
layout(push_constant) uniform Push {
  uint M, N, cp, kt, kh, kw, stride, up, wo, rows, oh0;
  int pad_top, pad_left;
  uint in_h, in_w, src_r0, src_rows, src_w, zero_texel, y_base;
  uint ys_f, ys_h, ys_w, ys_c, has_bias, n_base, accumulate, ow0, src_c0;
} p;
