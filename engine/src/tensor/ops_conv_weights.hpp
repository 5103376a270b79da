// Convolution weights in the layout the conv GEMM kernels read, packed once at load (a model's weights) or by
// every call (weights given as stored), and the view the conv ops (ops_conv.hpp) take either way.
// The packed layout is [Cout, taps, CP]: taps = kt*kh*kw in (t, h, w) order, CP = Cin rounded up to 8 with zeros
// past Cin, so that 8 input channels of one tap are one 16-byte load; same dtype as the source, bit for bit. A
// model whose conv kernel reads fp16 (the tensor cores' operand type) converts bf16 weights before packing
// (conv_weight_dtype; models/weights.hpp's packed_conv).
#pragma once
#include <cstdint>
#include <string>

#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::vk {
struct DeviceCaps;
}

namespace dvs::ops {

// Weights packed at load: `packed` [Cout, taps * CP] and the stored weights' shape, [Cout, Cin, (kt,) kh, kw]
// (what every shape helper and check of the conv ops reads).
struct PackedConvWeights {
  Tensor packed;
  Shape shape;
};

// What a convolution reads its weights from: the stored tensor (each call repacks the part it needs into its
// staging) or weights packed at load (a call binds its group of output channels in place, and repacks only
// a slice it cannot bind: some of the input channels when they are split, an unaligned group).
class ConvWeights {
 public:
  ConvWeights(const Tensor& stored) : stored_(&stored) {}           // NOLINT(google-explicit-constructor)
  ConvWeights(const PackedConvWeights& packed) : packed_(&packed) {}  // NOLINT(google-explicit-constructor)
  bool packed() const { return packed_ != nullptr; }
  const Shape& shape() const { return packed_ ? packed_->shape : stored_->shape(); }
  int64_t dim(size_t i) const { return shape().at(i); }
  DType dtype() const { return tensor().dtype(); }
  const Tensor& tensor() const { return packed_ ? packed_->packed : *stored_; }  // the stored or the packed tensor
  std::string describe() const;

 private:
  const Tensor* stored_ = nullptr;
  const PackedConvWeights* packed_ = nullptr;
};

// [Cout, taps * CP] for stored weights of shape `w` ([Cout, Cin, (kt,) kh, kw] or [Cout, Cin]).
Shape packed_conv_weights_shape(const Shape& w);

// The dtype a device keeps bf16 conv weights in: f16 where its conv family is coopmat (the tensor cores' operand
// type, which the kernel otherwise converts per element in every tile's loads) and DeviceTuning::conv_weights_fp16
// is on; else bf16. Same bits either way.
DType conv_weight_dtype(const vk::DeviceCaps& caps);

// Packs stored weights `w` into `packed` (allocated by the caller: packed_conv_weights_shape(w.shape()), w's
// dtype), in as many dispatches as the limits in force need.
void pack_conv_weights(vk::Recorder& rec, const Tensor& w, const Tensor& packed);
// A model's load: `w` packed into a new tensor (named `what` + " (packed)"), recorded and submitted now.
PackedConvWeights packed_conv_weights_now(vk::Context& ctx, const Tensor& w, const std::string& what);

// For ops_conv.cpp: output channels [co0, co0 + ng) and input channels [ci0, ci0 + cc) of `w` (stored or packed)
// packed into `dst` ([ng, taps, cpc], cpc = cc rounded up to 8, w's dtype), in as many dispatches as the source's
// and dst's sub-views need.
void pack_conv_weight_slice(vk::Recorder& rec, const char* op, const ConvWeights& w, int64_t co0, int64_t ng,
                            int64_t ci0, int64_t cc, int64_t cpc, const vk::BufferView& dst);

}  // namespace dvs::ops
