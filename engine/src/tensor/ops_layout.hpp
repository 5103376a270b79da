// Data movement without arithmetic: concat/split on any axis, general permute (rank ≤ 6 after merging
// axes that stay adjacent), CogVideoX patchify/unpatchify, and row gather/scatter by int32 index lists.
// Element types of 4 bytes (f32, i32); concat/split also take 2-byte types when every band is an even
// number of elements. Outputs are allocated by the caller and must not overlap the inputs (except gather/
// scatter, see there).
#pragma once
#include <vector>

#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

// out = concatenation of inputs along `axis` (negative counts from the end); shapes equal elsewhere.
void concat(vk::Recorder& rec, const std::vector<Tensor>& inputs, const Tensor& out, int axis);
// The inverse: outputs[k] = the k-th band of `in` along `axis`.
void split(vk::Recorder& rec, const Tensor& in, const std::vector<Tensor>& outputs, int axis);

// out.shape[d] = in.shape[perm[d]], as torch.permute(perm).contiguous(). E.g. [B,F,C,H,W] -> [B,C,F,H,W]
// is perm {0, 2, 1, 3, 4}.
void permute(vk::Recorder& rec, const Tensor& in, const Tensor& out, const std::vector<int>& perm);

// [B, F, C, H, W] -> [B, F·Hp·Wp, C·p·p], tokens in (f, hp, wp) order and features in (c, i, j) order,
// where pixel (hp·p + i, wp·p + j): the input side of the p×p stride-p patch-embedding conv as a GEMM
// against its weight [D, C, p, p] viewed as [D, C·p·p]. H and W must be multiples of p.
void patchify(vk::Recorder& rec, const Tensor& in, const Tensor& out, int p);
// CogVideoX unpatchify: [B, F·Hp·Wp, C·p·p] with features in (c, i, j) order -> [B, F, C, Hp·p, Wp·p].
void unpatchify(vk::Recorder& rec, const Tensor& in, const Tensor& out, int p);

// Rows are slices of the outermost axis (reshape to [n, 1] for single elements). Indices are i32 tensors
// of any shape holding m values.
// gather:  out[i] = src[idx[i]] (out has m rows); an index outside [0, src rows) gives a zero row.
void gather_rows(vk::Recorder& rec, const Tensor& src, const Tensor& idx, const Tensor& out);
// scatter: dst[idx[i]] = src[i] (src has m rows); other rows of dst are kept; an index outside
// [0, dst rows) is skipped; with duplicate indices one of the rows wins.
void scatter_rows(vk::Recorder& rec, const Tensor& src, const Tensor& idx, const Tensor& dst);
// Both at once (Stochastic Latent Modulation): dst[dst_idx[i]] = src[src_idx[i]], i < m. src and dst may be
// the same tensor when no row is both read and written.
void gather_scatter_rows(vk::Recorder& rec, const Tensor& src, const Tensor& src_idx, const Tensor& dst_idx,
                         const Tensor& dst);

}  // namespace dvs::ops
