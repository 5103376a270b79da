// Convolution weights packed once at load (ops_conv_weights.hpp, ComponentWeights::packed_conv) and the bias read in
// its own dtype. The packed layout against a plain-C++ packing (every dtype, shapes whose Cin is not a multiple of 8,
// whole and in chunks under a small binding, nothing written outside); every conv path of the VAE (causal 3x3x3 with
// and without a cache, 3x3, stride-2 downsample, 1x1, the fused x2 upsample) with packed weights against the same
// call with the stored weights, bit for bit: whole (the group bound in place: one dispatch fewer per call), with the
// packed tensor at an unaligned offset (a slice repacked from the packed layout), with the input channels split
// (binding=4KiB at 37 channels: slices of the packed layout) and the output channels in groups. Runs the device's
// own conv family (texel on lavapipe; the tiled and tensor-core passes run it with theirs).
#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/weights.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "support/vae_conv_paths.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"
#include "tensor/ops_elementwise.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs {
namespace {

// Values that every dtype holds exactly (multiples of 2^-10 within +-0.25, nonzero): a weight rounded to fp16 from
// bf16 is the same value, so any difference in y is the kernels', not the conversion's.
HostTensor exact_values(const Shape& s, uint32_t seed, DType dt) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> d(-256, 256);
  HostTensor h(s, dt);
  for (int64_t i = 0; i < h.numel(); ++i) {
    int k = d(rng);
    const float v = float(k == 0 ? 1 : k) / 1024.0f;
    if (dt == DType::bf16) h.as<uint16_t>()[i] = f32_to_bf16(v);
    else if (dt == DType::f16) h.as<uint16_t>()[i] = f32_to_f16(v);
    else h.as<float>()[i] = v;
  }
  return h;
}

size_t elem_bytes(DType dt) { return dt == DType::f32 ? 4 : 2; }

// The packed layout computed on the host: [Cout][tap][CP], CP = Cin rounded up to 8, zero past Cin; raw bytes.
std::vector<uint8_t> host_pack(const HostTensor& w) {
  const int64_t cout = w.shape[0], cin = w.shape[1], cp = (cin + 7) / 8 * 8;
  int64_t taps = 1;
  for (size_t i = 2; i < w.shape.size(); ++i) taps *= w.shape[i];
  const size_t eb = elem_bytes(w.dtype);
  std::vector<uint8_t> out(size_t(cout * taps * cp) * eb, 0);
  for (int64_t co = 0; co < cout; ++co)
    for (int64_t t = 0; t < taps; ++t)
      for (int64_t ci = 0; ci < cin; ++ci)
        std::memcpy(&out[size_t((co * taps + t) * cp + ci) * eb], &w.data[size_t((co * cin + ci) * taps + t) * eb], eb);
  return out;
}

std::vector<uint32_t> bits_of(vk::Context& c, const Tensor& t) {
  const HostTensor h = t.download(c);
  std::vector<uint32_t> v(size_t(h.numel()));
  std::memcpy(v.data(), h.data.data(), v.size() * 4);
  return v;
}

class PackedConvOps : public test::GpuTest {
 protected:
  struct Result {
    std::vector<std::vector<uint32_t>> y;
    std::vector<uint32_t> dispatches;  // per conv call
    std::vector<std::string> names;
  };
  // y of every conv path on a [1, cin, F, H, W] input with `cout` output channels, the weights as stored (mode 0),
  // packed (1) or packed at an unaligned offset (2), under `limits` (nullptr: none).
  Result all_convs(int64_t cin, int64_t cout, int64_t F, int64_t H, int64_t W, int mode, const char* limits) {
    vk::Context& c = ctx();
    const Tensor x = Tensor::upload(c, exact_values({1, cin, F, H, W}, 1, DType::f32));
    const Tensor cache = Tensor::upload(c, exact_values({1, cin, 2, H, W}, 2, DType::f32));
    const Tensor w3 = Tensor::upload(c, exact_values({cout, cin, 3, 3, 3}, 3, DType::bf16));
    const Tensor w2 = Tensor::upload(c, exact_values({cout, cin, 3, 3}, 4, DType::bf16));
    const Tensor w1 = Tensor::upload(c, exact_values({cout, cin, 1, 1, 1}, 5, DType::f32));
    const Tensor b = Tensor::upload(c, exact_values({cout}, 6, DType::bf16));
    std::vector<std::unique_ptr<ops::PackedConvWeights>> keep;
    std::vector<Tensor> buffers;  // what the non-owning packed views lie in
    auto weights = [&](const Tensor& w) -> ops::ConvWeights {
      if (mode == 0) return w;
      const Shape ps = ops::packed_conv_weights_shape(w.shape());
      const uint64_t bytes = uint64_t(shape_numel(ps)) * elem_bytes(w.dtype()), skew = mode == 2 ? 4 : 0;
      buffers.push_back(Tensor::empty(c, {int64_t(bytes + skew)}, DType::u8));
      vk::BufferView v = buffers.back().buffer();
      v.offset += skew;
      v.size = bytes;
      keep.push_back(std::make_unique<ops::PackedConvWeights>(ops::PackedConvWeights{Tensor::on(v, ps, w.dtype()), w.shape()}));
      ops::run_now(c, [&](vk::Recorder& rec) { ops::pack_conv_weights(rec, w, keep.back()->packed); });
      return *keep.back();
    };
    const ops::ConvWeights p3 = weights(w3), p2 = weights(w2), p1 = weights(w1);
    Result r;
    for (const test::VaeConvPath& path : test::vae_conv_paths(x, cache, p3, p2, p1, b)) {
      r.names.push_back(path.name);
      const Tensor o = Tensor::empty(c, path.out, DType::f32);
      {
        std::unique_ptr<test::ScopedLimits> scope;
        if (limits) scope = std::make_unique<test::ScopedLimits>(c, limits);
        ops::run_now(c, [&](vk::Recorder& rec) {
          path.call(rec, o);
          r.dispatches.push_back(rec.dispatch_count());
        });
      }
      r.y.push_back(bits_of(c, o));
    }
    return r;
  }
};

TEST_F(PackedConvOps, LayoutIsTheKernelsForEveryDtypeAndSplit) {
  vk::Context& c = ctx();
  const Shape shapes[] = {{7, 5, 3, 3, 3}, {9, 37, 3, 3}, {6, 16, 1, 1, 1}, {5, 3}};
  for (const Shape& s : shapes)
    for (DType dt : {DType::f32, DType::bf16, DType::f16})
      for (const char* limits : {static_cast<const char*>(nullptr), "binding=2KiB"}) {
        const std::string where = "[" + shape_str(s) + "] " + dtype_name(dt) + (limits ? std::string(" under ") + limits : "");
        const HostTensor w = exact_values(s, 11, dt);
        const Tensor wt = Tensor::upload(c, w);
        const Shape ps = ops::packed_conv_weights_shape(s);
        const std::vector<uint8_t> want = host_pack(w);
        ASSERT_EQ(uint64_t(shape_numel(ps)) * elem_bytes(dt), want.size()) << where;
        // The packed tensor 256 bytes into a buffer of sentinel bytes: nothing may be written around it.
        const size_t pad = 256, total = pad + want.size() + pad;
        HostTensor sentinel({int64_t(total)}, DType::u8);
        std::memset(sentinel.data.data(), 0xa5, total);
        const Tensor buf = Tensor::upload(c, sentinel);
        vk::BufferView view = buf.buffer();
        view.offset += pad;
        view.size = want.size();
        const Tensor packed = Tensor::on(view, ps, dt);
        {
          std::unique_ptr<test::ScopedLimits> scope;
          if (limits) scope = std::make_unique<test::ScopedLimits>(c, limits);
          ops::run_now(c, [&](vk::Recorder& rec) { ops::pack_conv_weights(rec, wt, packed); });
        }
        const HostTensor got = buf.download(c);
        size_t differ = 0, outside = 0;
        for (size_t i = 0; i < want.size(); ++i) differ += got.data[pad + i] != want[i];
        for (size_t i = 0; i < pad; ++i) outside += (got.data[i] != 0xa5) + (got.data[pad + want.size() + i] != 0xa5);
        EXPECT_EQ(differ, 0u) << where << ": bytes that differ from the host's packing";
        EXPECT_EQ(outside, 0u) << where << ": bytes written outside the packed tensor";
      }
  // A packed tensor of the wrong shape or dtype is refused.
  const Tensor w = Tensor::upload(c, exact_values({4, 5, 3, 3}, 1, DType::bf16));
  const Tensor wrong = Tensor::empty(c, ops::packed_conv_weights_shape(w.shape()), DType::f16);
  EXPECT_THROW(ops::run_now(c, [&](vk::Recorder& rec) { ops::pack_conv_weights(rec, w, wrong); }), Error);
}


TEST_F(PackedConvOps, EveryPathGivesTheStoredWeightsBits) {
  struct Run {
    int64_t cin, cout, frames, h, w;
    const char* limits;
  };
  // binding=4KiB: at 37 channels one pixel's repacked input (27 taps x 40 x 4 B) splits the input channels (a
  // smaller input there: it also runs pixel by pixel); at 13 output channels the weights of a call split the output
  // channels into groups.
  const Run runs[] = {{5, 7, 5, 13, 11, nullptr},      {37, 7, 5, 13, 11, nullptr},   {64, 7, 5, 13, 11, nullptr},
                      {5, 7, 5, 13, 11, "texels=256"}, {37, 7, 2, 5, 3, "binding=4KiB"}, {5, 13, 5, 13, 11, "binding=4KiB"}};
  for (const Run& run : runs) {
    const std::string where = "Cin " + std::to_string(run.cin) + ", Cout " + std::to_string(run.cout) +
                              (run.limits ? std::string(" under ") + run.limits : "");
    const Result stored = all_convs(run.cin, run.cout, run.frames, run.h, run.w, 0, run.limits);
    const Result packed = all_convs(run.cin, run.cout, run.frames, run.h, run.w, 1, run.limits);
    const Result unaligned = all_convs(run.cin, run.cout, run.frames, run.h, run.w, 2, run.limits);
    ASSERT_EQ(stored.y.size(), packed.y.size());
    for (size_t i = 0; i < stored.y.size(); ++i) {
      size_t differ = 0, differ_unaligned = 0;
      for (size_t k = 0; k < stored.y[i].size(); ++k) {
        differ += stored.y[i][k] != packed.y[i][k];
        differ_unaligned += stored.y[i][k] != unaligned.y[i][k];
      }
      EXPECT_EQ(differ, 0u) << stored.names[i] << ", " << where << ": elements that differ from the stored weights'";
      EXPECT_EQ(differ_unaligned, 0u) << stored.names[i] << ", " << where << ", packed at an unaligned offset";
      // Unsplit, the packed group is bound in place: one weight repack fewer. Unaligned, it is repacked as stored
      // weights are. (Limits forced on the whole run, DVS_LIMITS, may split a call's weight repack: counts only
      // without them.)
      if (!run.limits && !ctx().caps().forced_limits.any()) {
        EXPECT_EQ(packed.dispatches[i] + 1, stored.dispatches[i]) << stored.names[i] << ", " << where << ": dispatches";
        EXPECT_EQ(unaligned.dispatches[i], stored.dispatches[i]) << stored.names[i] << ", " << where << ": dispatches";
      }
    }
  }
}

// The bias in its own dtype (the GEMM kernels' BTYPE): f16 weights with a bf16 bias, and bf16 weights with an f32
// one, give the bits of the weights and bias all in bf16 (every value here is exact in each dtype).
TEST_F(PackedConvOps, BiasReadInItsOwnDtype) {
  vk::Context& c = ctx();
  const Tensor x = Tensor::upload(c, exact_values({1, 6, 3, 7, 5}, 1, DType::f32));
  const Shape ws = {5, 6, 3, 3, 3};
  const Tensor w16 = Tensor::upload(c, exact_values(ws, 2, DType::bf16)), h16 = Tensor::upload(c, exact_values(ws, 2, DType::f16));
  const Tensor b16 = Tensor::upload(c, exact_values({5}, 3, DType::bf16)), b32 = Tensor::upload(c, exact_values({5}, 3, DType::f32));
  auto y_of = [&](const Tensor& w, const Tensor& b) {
    const Tensor y = Tensor::empty(c, {1, 5, 3, 7, 5}, DType::f32);
    ops::run_now(c, [&](vk::Recorder& rec) { ops::causal_conv3d(rec, x, w, &b, y); });
    return bits_of(c, y);
  };
  const std::vector<uint32_t> ref = y_of(w16, b16);
  EXPECT_EQ(y_of(h16, b16), ref) << "f16 weights, bf16 bias";
  EXPECT_EQ(y_of(w16, b32), ref) << "bf16 weights, f32 bias";
  // And the bias is applied at all: without it y differs.
  const Tensor y = Tensor::empty(c, {1, 5, 3, 7, 5}, DType::f32);
  ops::run_now(c, [&](vk::Recorder& rec) { ops::causal_conv3d(rec, x, w16, nullptr, y); });
  EXPECT_NE(bits_of(c, y), ref);
}

// A model's conv weights (ComponentWeights::packed_conv): packed once, in fp16 where the conv kernel reads fp16
// (the tensor-core family; its fp32 twin here when the device has none) and conv_weights_fp16 is on, else as stored.
TEST_F(PackedConvOps, ModelWeightsPackedOnceInTheKernelsOperandType) {
  vk::Context& c = ctx();
  const bool twin = !ops::device_tuning(c.caps()).coopmat.defined();
  ops::ConvRegisterBlock blk;
  blk.coopmat_twin = twin;
  const HostTensor w = exact_values({4, 5, 3, 3, 3}, 7, DType::bf16), w32 = exact_values({3, 2, 3, 3}, 8, DType::f32);
  for (bool fp16 : {true, false}) {
    ops::ScopedTuningOverride tune(std::string(twin ? "" : "conv=coopmat,") + "conv_weights_fp16=" + (fp16 ? "on" : "off"));
    ops::set_conv_register_block(blk);
    std::map<std::string, Tensor> tensors;
    tensors.emplace("conv.weight", Tensor::upload(c, w));
    tensors.emplace("f32conv.weight", Tensor::upload(c, w32));
    models::ComponentWeights cw(c, nlohmann::json{{"_class_name", "NoSchema"}}, std::move(tensors), "in memory");
    const ops::PackedConvWeights& p = cw.packed_conv("conv.weight");
    ops::set_conv_register_block({});
    EXPECT_EQ(&cw.packed_conv("conv.weight"), &p) << "packed once";
    EXPECT_EQ(p.shape, w.shape);
    EXPECT_EQ(p.packed.dtype(), fp16 ? DType::f16 : DType::bf16);
    HostTensor as_stored = w;
    if (fp16) {
      as_stored = HostTensor(w.shape, DType::f16);
      for (int64_t i = 0; i < w.numel(); ++i) as_stored.as<uint16_t>()[i] = f32_to_f16(bf16_to_f32(w.as<uint16_t>()[i]));
    }
    const HostTensor got = p.packed.download(c);
    EXPECT_EQ(got.data, host_pack(as_stored)) << (fp16 ? "fp16" : "bf16");
    EXPECT_EQ(cw.packed_conv("f32conv.weight").packed.dtype(), DType::f32) << "f32 weights stay f32";
    EXPECT_TRUE(cw.has("conv.weight"));
    EXPECT_THROW(cw.get("conv.weight"), Error) << "the stored copy lived only on the device and was dropped";
  }
}

// The pack's VAE with every tensor cast to bf16 (the pack keeps its VAE f32, as diffusers' bf16 pipelines do; the
// CogVideoX-5B checkpoint's is bf16) encodes and decodes to the same bits with its conv
// weights kept fp16 (conv_weights_fp16, the default where the conv family is coopmat) as with them kept bf16, and
// the fp16 run's kernel read fp16 weights beside a bf16 bias. The tensor-core kernel where the device has one (the
// tensor-core pass), else its fp32 twin (which rounds its operands to fp16 the same way).
TEST_F(PackedConvOps, VaeKeepsBf16ConvWeightsFp16WithTheSameResult) {
  const std::filesystem::path dir = test::golden_path() / "model" / "vae";
  if (!std::filesystem::exists(dir / "config.json")) GTEST_SKIP() << "no " << dir;
  vk::Context& c = ctx();
  const bool twin = !ops::device_tuning(c.caps()).coopmat.defined();
  const std::string gemm = twin ? "nn/conv_coopmat_twin" : "nn/conv_coopmat";
  // Whether a conv kernel with (weights, bias) stored as (wcode, bcode) ran (0 f32, 1 f16, 2 bf16).
  auto ran = [&](uint32_t wcode, uint32_t bcode) {
    bool found = false;
    c.pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == gemm && pl.spec.size() == 15 && pl.spec[0] == wcode && pl.spec[13] == bcode) found = true;
    });
    return found;
  };
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> d(-1.f, 1.f);
  auto random = [&](const Shape& s) {
    std::vector<float> v(size_t(shape_numel(s)));
    for (float& x : v) x = d(rng);
    return Tensor::upload(c, HostTensor::from_f32(s, v));
  };
  const Tensor video = random({1, 3, 5, 16, 16}), z = random({1, 4, 2, 4, 4});
  std::vector<std::vector<uint32_t>> runs[2];
  for (int fp16 = 1; fp16 >= 0; --fp16) {
    ops::ScopedTuningOverride tune(std::string(twin ? "" : "conv=coopmat,") + "conv_weights_fp16=" + (fp16 ? "on" : "off"));
    ops::ConvRegisterBlock blk;
    blk.coopmat_twin = twin;
    ops::set_conv_register_block(blk);
    models::ComponentWeights stored(c, dir);
    std::map<std::string, Tensor> bf16;
    for (const std::string& name : stored.names()) {
      const Tensor& t = stored.get(name);
      Tensor b = Tensor::empty(c, t.shape(), DType::bf16, name);
      ops::run_now(c, [&](vk::Recorder& rec) { ops::cast(rec, t, b); });
      bf16.emplace(name, std::move(b));
    }
    models::CogVideoXVae vae(c, models::ComponentWeights(c, stored.config(), std::move(bf16), "the pack's VAE in bf16"));
    runs[fp16].push_back(bits_of(c, vae.encode(video).mean));
    runs[fp16].push_back(bits_of(c, vae.decode(z)));
    ops::set_conv_register_block({});
    if (fp16) EXPECT_TRUE(ran(1, 2)) << "no " << gemm << " read fp16 weights beside a bf16 bias";
  }
  EXPECT_TRUE(ran(2, 2)) << "no " << gemm << " read bf16 weights";
  ASSERT_EQ(runs[0].size(), 2u);
  ASSERT_EQ(runs[1].size(), 2u);
  EXPECT_EQ(runs[1][0], runs[0][0]) << "encode: the posterior's mean differs";
  EXPECT_EQ(runs[1][1], runs[0][1]) << "decode: the frames differ";
}

}  // namespace
}  // namespace dvs
