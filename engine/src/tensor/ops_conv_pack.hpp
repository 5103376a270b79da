// A convolution chunk's input repacked channels-last (shaders/nn/conv_pack_input.comp, or its transpose through shared
// memory shaders/nn/conv_pack_input_tiled.comp where DeviceTuning::conv_pack_tiled is on) for the GEMM kernels that
// read it: frames of the time-padded axis (causal prefix, cache, upsampled time), a range of source rows and columns,
// channels rounded up to 8, fp16 or f32, and one zero pixel after; optionally on a zero-padded grid (a halo of rows
// and columns around the source ones: the shifted-GEMM convolution, ops_conv_shifted.cpp).
#pragma once
#include <cstdint>

#include "tensor/ops_conv_job.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops::conv {

// The packed grid around the source rows and columns: halo_top zero rows before them and rows_p rows in all,
// halo_left zero columns before them and cols_p in all. Default (rows_p = cols_p = 0): no halo. up 2: the rows and
// columns (pack_input's r0, rows, col0, wc and this grid) are those of x's nearest x2 spatial upsampling.
struct PackGrid {
  int64_t halo_top = 0, rows_p = 0, halo_left = 0, cols_p = 0, up = 1;
};

// Repacks input channels [c0, c0 + cc) (cpc of them with the zero channels) of padded frames [tp0, tp0 + nframes),
// source rows [r0, r0 + rows) and columns [col0, col0 + wc) of batch item b into `packed`, laid out
// [frame][row][column][cpc] over the grid (+ the zero pixel; fp16 where `f16`, else f32): one dispatch when x's part
// fits one texel view, else one per group of channels (and of frames). pack_columns: pixels of a row per invocation
// (0: the whole row).
void pack_input(vk::Recorder& rec, const char* op, const ConvJob& j, const Tensor& x, const ConvLimits& l, int64_t b,
                int64_t c0, int64_t cc, int64_t cpc, int64_t tp0, int64_t nframes, int64_t r0, int64_t rows,
                int64_t col0, int64_t wc, bool f16, const vk::BufferView& packed, int64_t pack_columns,
                const PackGrid& grid = {});

}  // namespace dvs::ops::conv
