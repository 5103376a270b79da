// dvs-bench group "gpu": the device stage's cases at the real shapes, beside bench/gpu/torch_ref.py's
// PyTorch figures (bench/gpu/summarize.py joins them by case and shape):
//   gemm       X f32 [M, K] · W bf16 [N, K]ᵀ, M = 2 x 17,776; K x N = 3072x3072, 3072x9216, 3072x12288, 12288x3072;
//              X and W in fp16 where the model keeps them so (ops::gemm_activation_dtype, gemm_weight_dtype: the
//              coopmat family)
//   attention  B=2, H=48, D=64, S=17,776; q|k|v fused [B, S, 3·H·D] f32, or for the coopmat family where the model
//              keeps its GEMM operands fp16: q, k, v fp16 head-major [B, H, S, D] as the transformer gives them
//   conv3d     causal 3x3x3 at the VAE decoder's shapes, 4 output frames, bf16 weights
//   copy       vkCmdCopyBuffer 256 MiB (bytes read + written)
//   mma_rate   register-only cooperative-matrix rate (shaders/bench/coopmat_mma_rate.comp), where it exists
//   block      the torch script's 1-layer transformer folder (env DVS_GPU_BENCH_DIR) through the production
//              loader; its output goes to <dir>/out_dvs_<family>.npy for bench/gpu/compare_block.py
// Each case runs once per kernel family the device offers (texel = the kernels every device ran before,
// tiled, coopmat with tensor cores), forced with ops::ScopedTuningOverride; a family whose kernel is
// missing runs what the op falls back to, and the row names the shaders that actually ran (from the
// profiler's labels). Times are GPU timestamps around each dispatch (the median of a few runs; one run
// when a run exceeds ~1.5 s, so the old kernels' "before" rows stay within ~5 s per case). Inputs are
// random; every result is checked against a CPU reference on a few hundred sampled outputs, so a wrong
// kernel shows as "check":"FAIL", not as a time. One JSON line per case on stdout as it ends, and appended
// (flushed) to the file DVS_GPU_BENCH_JSON when set. Smoke mode (--quick or DVS_GPU_BENCH_SMOKE=1): tiny
// odd shapes that run on lavapipe in seconds.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "harness.hpp"
#include "io/npy.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/weights.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_attention.hpp"
#include "tensor/ops_conv.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/ops_norm.hpp"
#include "tensor/tensor.hpp"
#include "vk/pipeline.hpp"
#include "vk/pipeline_statistics.hpp"
#include "vk/profiler.hpp"
#include "vk/recorder.hpp"
#include "vk/transfer.hpp"

namespace dvs::bench {
namespace {

bool smoke(const Bench& b) {
  const char* e = std::getenv("DVS_GPU_BENCH_SMOKE");
  return b.quick() || (e && std::string(e) == "1");
}

// Fast deterministic random numbers (hundreds of millions of inputs at the real shapes).
struct Rng {
  uint64_t s;
  explicit Rng(uint64_t seed) : s(seed * 0x9E3779B97F4A7C15ull + 1) {}
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  float uniform() { return float(next() >> 40) * (2.0f / 16777216.0f) - 1.0f; }  // [-1, 1)
  size_t below(size_t n) { return size_t(next() % n); }
};

HostTensor random_host(Shape s, DType dt, uint64_t seed, float scale = 1.0f) {
  HostTensor h(s, dt);
  Rng r(seed);
  const int64_t n = h.numel();
  if (dt == DType::f32)
    for (int64_t i = 0; i < n; ++i) h.as<float>()[i] = scale * r.uniform();
  else
    for (int64_t i = 0; i < n; ++i)
      h.as<uint16_t>()[i] = dt == DType::bf16 ? f32_to_bf16(scale * r.uniform()) : f32_to_f16(scale * r.uniform());
  return h;
}

float value(const HostTensor& h, int64_t i) {
  switch (h.dtype) {
    case DType::bf16: return bf16_to_f32(h.as<uint16_t>()[i]);
    case DType::f16: return f16_to_f32(h.as<uint16_t>()[i]);
    default: return h.as<float>()[i];
  }
}

// Sampled comparison: relative L2 error over the samples, and whether every sample is finite.
struct Check {
  double num = 0, den = 0;
  bool finite = true;
  void add(double got, double ref) {
    if (!std::isfinite(got)) finite = false;
    num += (got - ref) * (got - ref);
    den += ref * ref;
  }
  double rel() const { return finite ? std::sqrt(num / std::max(den, 1e-300)) : INFINITY; }
};

std::string json_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '"' || c == '\\') o += '\\';
    if (c == '\n') o += "\\n";
    else o += c;
  }
  return o;
}

// One JSON line: stdout, and the file named by DVS_GPU_BENCH_JSON (flushed per line).
// DVS_GPU_BENCH_VARIANT (the device stage's sweep, with DVS_TUNING set to it): every line says which variant.
void emit(std::map<std::string, std::string> fields) {
  if (const char* v = std::getenv("DVS_GPU_BENCH_VARIANT"); v && *v) fields["variant"] = "\"" + json_escape(v) + "\"";
  std::string j = "{\"source\":\"dvs\"";
  for (const auto& [k, v] : fields) j += ",\"" + k + "\":" + v;
  j += "}";
  std::printf("%s\n", j.c_str());
  std::fflush(stdout);
  if (const char* path = std::getenv("DVS_GPU_BENCH_JSON")) {
    std::ofstream f(path, std::ios::app);
    f << j << "\n";
  }
}
std::string str(const std::string& s) { return "\"" + json_escape(s) + "\""; }
std::string num(double v) {
  if (!std::isfinite(v)) return "null";
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

// The kernel families to run: texel and tiled everywhere, coopmat where the device has a usable shape.
std::vector<std::string> families(vk::Context& ctx) {
  std::vector<std::string> f = {"texel", "tiled"};
  if (ops::device_tuning(ctx.caps()).coopmat.defined()) f.push_back("coopmat");
  if (const char* only = std::getenv("DVS_GPU_BENCH_FAMILIES")) {  // e.g. "tiled,coopmat" for a short run
    std::vector<std::string> keep;
    for (auto& x : f)
      if ((std::string(",") + only + ",").find("," + x + ",") != std::string::npos) keep.push_back(x);
    f = keep;
  }
  return f;
}

struct Timing {
  double gpu_ms = 0, wall_ms = 0;
  int runs = 0;
  std::string shaders;  // the profiler labels of the dispatches (which shaders ran)
  // GPU ms per label, the mean over the timed runs (the first run where it was the figure): which dispatch of an
  // op takes the time (e.g. a convolution's input repack, weight repack and GEMM). Empty without timestamps.
  std::map<std::string, double> shader_ms;
};

// Records with timestamps around each dispatch, submits once (warm: first touch; two more warm-ups when
// that took under 0.3 s), then times submits: at most 10 (2 when a run takes over 0.3 s), or until ~1 s, or
// the first run alone when it took over 1.5 s. GPU time = the sum of the dispatches'
// timestamp pairs of one submit (wall time where the device has no timestamps).
Timing time_recorded(vk::Context& ctx, const std::function<void(vk::Recorder&)>& record) {
  vk::Profiler& prof = ctx.profiler();
  const bool was = prof.enabled();
  prof.set_enabled(true);
  prof.clear();
  vk::Recorder rec(ctx);
  rec.begin();
  record(rec);
  rec.end();
  using clock = std::chrono::steady_clock;
  auto w0 = clock::now();
  rec.submit();
  const double first = std::chrono::duration<double, std::milli>(clock::now() - w0).count();
  Timing t;
  std::set<std::string> labels;
  double first_ns = 0;
  for (const auto& [label, e] : prof.entries()) labels.insert(label), first_ns += e.total_ns;
  for (const auto& l : labels) t.shaders += (t.shaders.empty() ? "" : " ") + l;
  if (first > 1500) {  // a slow old kernel: its first run is the figure (~5 s cap per case)
    if (ctx.caps().timestamps)
      for (const auto& [label, e] : prof.entries()) t.shader_ms[label] = e.total_ns * 1e-6;
    t.gpu_ms = ctx.caps().timestamps && first_ns > 0 ? first_ns * 1e-6 : first;
    t.wall_ms = first;
    t.runs = 1;
    prof.clear();
    prof.set_enabled(was);
    return t;
  }
  if (first <= 300) rec.submit(), rec.submit();  // 3 warm-ups in all where they are cheap
  std::vector<double> gpu, wall;
  const auto start = clock::now();
  const int max_runs = first > 300 ? 2 : 10;  // the old kernels' rows stay short
  while (int(gpu.size()) < max_runs && (gpu.size() < 2 || std::chrono::duration<double>(clock::now() - start).count() < 1.0)) {
    prof.clear();
    auto a = clock::now();
    rec.submit();
    wall.push_back(std::chrono::duration<double, std::milli>(clock::now() - a).count());
    double ns = 0;
    for (const auto& [label, e] : prof.entries()) {
      ns += e.total_ns;
      if (ctx.caps().timestamps) t.shader_ms[label] += e.total_ns * 1e-6;
    }
    gpu.push_back(ctx.caps().timestamps && ns > 0 ? ns * 1e-6 : wall.back());
  }
  for (auto& [label, ms] : t.shader_ms) ms /= double(gpu.size());
  prof.clear();
  prof.set_enabled(was);
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  t.gpu_ms = median(gpu);
  t.wall_ms = median(wall);
  t.runs = int(gpu.size());
  return t;
}

void report(Bench& b, const std::string& c, const std::string& shape, const std::string& family, const Timing& t,
            double flops, double bytes, const Check* check, double tolerance, std::map<std::string, std::string> extra = {}) {
  extra["case"] = str(c);
  extra["shape"] = str(shape);
  extra["family"] = str(family);
  extra["shaders"] = str(t.shaders);
  if (!t.shader_ms.empty()) {
    std::string o;
    for (const auto& [label, ms] : t.shader_ms) o += (o.empty() ? "{" : ",") + str(label) + ":" + num(ms);
    extra["shader_ms"] = o + "}";
  }
  extra["ms"] = num(t.gpu_ms);
  extra["ms_wall"] = num(t.wall_ms);
  extra["runs"] = std::to_string(t.runs);
  if (flops > 0) extra["tflops"] = num(flops / (t.gpu_ms * 1e9));
  if (bytes > 0) extra["gbps"] = num(bytes / (t.gpu_ms * 1e6));
  std::string verdict = "n/a";
  if (check) {
    extra["rel_err"] = num(check->rel());
    extra["tolerance"] = num(tolerance);
    verdict = check->rel() <= tolerance ? "ok" : "FAIL";
    extra["check"] = str(verdict);
  }
  emit(extra);
  b.report({"gpu_" + c + "_" + family, shape, t.gpu_ms, flops > 0 ? flops / (t.gpu_ms * 1e6) : 0,
            bytes > 0 ? bytes / (t.gpu_ms * 1e6) : 0, "check " + verdict + "; " + t.shaders});
}

void report_error(const std::string& c, const std::string& shape, const std::string& family, const std::string& what) {
  emit({{"case", str(c)}, {"shape", str(shape)}, {"family", str(family)}, {"error", str(what)}});
  std::printf("gpu_%s_%s %s: error: %s\n", c.c_str(), family.c_str(), shape.c_str(), what.c_str());
}

// One row of a tensor viewed as [rows, row_len] (sampled checks download a few rows, not gigabytes).
std::vector<float> download_row(vk::Context& ctx, const Tensor& t, int64_t row_len, int64_t row) {
  const HostTensor h = t.reshape({t.numel() / row_len, row_len}).rows(row, 1).download(ctx);
  return h.to_f32();
}

// Tolerances of the sampled checks: fp32 arithmetic on fp32 / bf16 inputs lands far under 1e-4;
// the coopmat family rounds activations to fp16 (|x| > 65504 would become inf), ~1e-3.
double tolerance_for(const std::string& family) { return family == "coopmat" ? 1e-2 : 1e-4; }

// ---------------------------------------------------------------------------------------------------- GEMM
void gemm_cases(Bench& b) {
  vk::Context& ctx = b.ctx();
  const bool s = smoke(b);
  const int64_t M = s ? 37 : 2 * 17776;
  const std::vector<std::pair<int64_t, int64_t>> kn =
      s ? std::vector<std::pair<int64_t, int64_t>>{{24, 45}, {72, 40}}
        : std::vector<std::pair<int64_t, int64_t>>{{3072, 3072}, {3072, 9216}, {3072, 12288}, {12288, 3072}};
  int64_t have_k = 0;
  HostTensor hx;
  Tensor x, x_f16;  // x_f16: X as a LayerNorm writes it where the tensor cores run the GEMMs
  for (auto [K, N] : kn) {
    char shape[64];
    std::snprintf(shape, sizeof shape, "%lldx%lldx%lld", (long long)M, (long long)K, (long long)N);
    try {
      if (have_k != K) {
        x = x_f16 = Tensor();
        hx = random_host({M, K}, DType::f32, 11 + uint64_t(K));
        x = Tensor::upload(ctx, hx, "gpu bench x");
        have_k = K;
      }
      const HostTensor hw = random_host({N, K}, DType::bf16, 12 + uint64_t(N), 1.0f / std::sqrt(float(K)));
      Tensor w = Tensor::upload(ctx, hw, "gpu bench w");
      Tensor w_f16;  // the same values as the model keeps them where the tensor cores run its GEMMs
      Tensor y = Tensor::empty(ctx, {M, N}, DType::f32, "gpu bench y");
      for (const std::string& fam : families(ctx)) {
        try {
          ops::ScopedTuningOverride ov("linear=" + fam);
          const bool f16 = ops::gemm_weight_dtype(ctx.caps()) == DType::f16;
          const bool x16 = ops::gemm_activation_dtype(ctx.caps()) == DType::f16;
          // The f16 copy of `src`, made on first use.
          auto half_copy = [&](const Tensor& src, Tensor& copy, const char* what) -> const Tensor& {
            if (!copy.defined()) {
              copy = Tensor::empty(ctx, src.shape(), DType::f16, what);
              ops::run_now(ctx, [&](vk::Recorder& r) { ops::cast(r, src, copy); });
            }
            return copy;
          };
          const Tensor& xs = x16 ? half_copy(x, x_f16, "gpu bench x f16") : x;
          const Tensor& ws = f16 ? half_copy(w, w_f16, "gpu bench w f16") : w;
          ops::run_now(ctx, [&](vk::Recorder& r) { r.fill_zero(y.buffer()); });  // poison: unwritten outputs fail
          Timing t = time_recorded(ctx, [&](vk::Recorder& r) { ops::linear(r, xs, ws, y); });
          Check c;
          Rng pick(99);
          for (int i = 0; i < 32; ++i) {  // 32 rows x 8 columns
            const int64_t m = int64_t(pick.below(size_t(M)));
            const std::vector<float> row = download_row(ctx, y, N, m);
            for (int j = 0; j < 8; ++j) {
              const int64_t n = int64_t(pick.below(size_t(N)));
              double ref = 0;
              for (int64_t k = 0; k < K; ++k) ref += double(hx.as<float>()[m * K + k]) * value(hw, n * K + k);
              c.add(row[size_t(n)], ref);
            }
          }
          report(b, "gemm", shape, fam, t, 2.0 * M * N * K, 0, &c, tolerance_for(fam),
                 {{"dtype", str(std::string(x16 ? "x f16" : "x f32") + (f16 ? ", w bf16 kept f16" : ", w bf16"))}});
        } catch (const std::exception& e) {
          report_error("gemm", shape, fam, e.what());
        }
      }
    } catch (const std::exception& e) {
      report_error("gemm", shape, "-", e.what());
    }
  }
}

// ----------------------------------------------------------------------------------------------- attention
void attention_cases(Bench& b) {
  vk::Context& ctx = b.ctx();
  const bool s = smoke(b);
  const int64_t B = 2, H = s ? 3 : 48, D = 64, S = s ? 45 : 17776;
  char shape[64];
  std::snprintf(shape, sizeof shape, "%lldx%lldx%lldx%lld", (long long)B, (long long)H, (long long)S, (long long)D);
  try {
    const HostTensor hqkv = random_host({B, S, 3 * H * D}, DType::f32, 21);
    Tensor qkv = Tensor::upload(ctx, hqkv, "gpu bench qkv");
    Tensor out = Tensor::empty(ctx, {B, S, H * D}, DType::f32, "gpu bench attention out");
    ops::AttentionShape sh;
    sh.batch = B;
    sh.heads = H;
    sh.head_dim = D;
    sh.q_len = sh.kv_len = S;
    ops::AttentionOptions opt;
    opt.scale = 1.0f / std::sqrt(float(D));
    // q, k and v as the transformer gives them to the tensor cores' attention: fp16, head-major [B, H, S, D], each
    // written by ops::attention_heads (here without norm and RoPE) from its own f32 [B, S, H·D]; made on first use.
    Tensor heads16[3];
    for (const std::string& fam : families(ctx)) {
      try {
        ops::ScopedTuningOverride ov("attention=" + fam);
        const bool f16_heads = fam == "coopmat" && ops::gemm_activation_dtype(ctx.caps()) == DType::f16;
        if (f16_heads && !heads16[0].defined()) {
          for (int64_t which = 0; which < 3; ++which) {
            HostTensor part({B, S, H * D}, DType::f32);
            for (int64_t row = 0; row < B * S; ++row)
              std::copy_n(hqkv.as<float>() + (row * 3 + which) * H * D, H * D, part.as<float>() + row * H * D);
            const Tensor x = Tensor::upload(ctx, part, "gpu bench q/k/v f32");
            heads16[which] = Tensor::empty(ctx, {B, H, S, D}, DType::f16, "gpu bench q/k/v f16 head-major");
            ops::run_now(ctx, [&](vk::Recorder& r) { ops::attention_heads(r, x, heads16[which], H, {}); });
          }
        }
        auto operand = [&](int which) {
          return f16_heads ? ops::AttentionOperand{heads16[which], 0, 0, true}
                           : ops::fused_qkv_operand(qkv, which, H, D);
        };
        ops::run_now(ctx, [&](vk::Recorder& r) { r.fill_zero(out.buffer()); });
        Timing t = time_recorded(ctx, [&](vk::Recorder& r) {
          ops::attention(r, sh, operand(0), operand(1), operand(2), {out, 0, 0}, opt);
        });
        Check c;
        Rng pick(98);
        const float* q = hqkv.as<float>();
        std::vector<double> p(size_t(S), 0.0);
        for (int i = 0; i < (s ? 16 : 24); ++i) {  // whole output rows of sampled (b, h, query) triples
          const int64_t bb = int64_t(pick.below(size_t(B))), h = int64_t(pick.below(size_t(H))),
                        r = int64_t(pick.below(size_t(S)));
          const float* qr = q + (bb * S + r) * 3 * H * D + h * D;
          double mx = -1e300, sum = 0;
          for (int64_t j = 0; j < S; ++j) {
            const float* kr = q + (bb * S + j) * 3 * H * D + H * D + h * D;
            double d = 0;
            for (int64_t e = 0; e < D; ++e) d += double(qr[e]) * kr[e];
            p[size_t(j)] = d * opt.scale;
            mx = std::max(mx, p[size_t(j)]);
          }
          for (int64_t j = 0; j < S; ++j) sum += (p[size_t(j)] = std::exp(p[size_t(j)] - mx));
          const std::vector<float> orow = download_row(ctx, out, H * D, bb * S + r);
          for (int64_t e = 0; e < D; ++e) {
            double ref = 0;
            for (int64_t j = 0; j < S; ++j) ref += p[size_t(j)] * q[(bb * S + j) * 3 * H * D + 2 * H * D + h * D + e];
            c.add(orow[size_t(h * D + e)], ref / sum);
          }
        }
        report(b, "attention", shape, fam, t, 4.0 * B * H * double(S) * S * D, 0, &c, tolerance_for(fam),
               {{"layout", str(f16_heads ? "q k v f16 head-major [B,H,S,D] (the transformer's)" : "fused qkv [B,S,3HD], f32")}});
      } catch (const std::exception& e) {
        report_error("attention", shape, fam, e.what());
      }
    }
  } catch (const std::exception& e) {
    report_error("attention", shape, "-", e.what());
  }
}

// ------------------------------------------------------------------------------------------------- conv3d
void conv_cases(Bench& b) {
  vk::Context& ctx = b.ctx();
  const bool s = smoke(b);
  struct C { int64_t c, h, w; };
  const std::vector<C> shapes = s ? std::vector<C>{{12, 10, 14}} : std::vector<C>{{128, 480, 720}, {256, 240, 360}, {512, 60, 90}};
  const int64_t Fr = s ? 3 : 4;
  for (const C& cs : shapes) {
    char shape[64];
    std::snprintf(shape, sizeof shape, "%lld->%lld@%lldx%lldxF%lld", (long long)cs.c, (long long)cs.c, (long long)cs.h,
                  (long long)cs.w, (long long)Fr);
    try {
      const int64_t C = cs.c, H = cs.h, W = cs.w;
      const HostTensor hx = random_host({1, C, Fr, H, W}, DType::f32, 31 + uint64_t(C));
      const HostTensor hw = random_host({C, C, 3, 3, 3}, DType::bf16, 32 + uint64_t(C), 1.0f / std::sqrt(27.0f * C));
      const HostTensor hb = random_host({C}, DType::bf16, 33, 0.1f);
      Tensor x = Tensor::upload(ctx, hx, "gpu bench conv x");
      Tensor w = Tensor::upload(ctx, hw, "gpu bench conv w");
      Tensor bias = Tensor::upload(ctx, hb, "gpu bench conv bias");
      Tensor y = Tensor::empty(ctx, {1, C, Fr, H, W}, DType::f32, "gpu bench conv y");
      for (const std::string& fam : families(ctx)) {
        try {
          ops::ScopedTuningOverride ov("conv=" + fam);
          ops::run_now(ctx, [&](vk::Recorder& r) { r.fill_zero(y.buffer()); });
          // The weights as the VAE holds them: packed once at load, in the family's operand type (bf16 kept fp16
          // where the tensor cores read fp16: ComponentWeights::packed_conv), so the time is the call's alone.
          models::ComponentWeights cw(ctx, nlohmann::json{{"_class_name", "NoSchema"}}, {{"conv.weight", w}}, "gpu bench conv");
          const ops::PackedConvWeights& pw = cw.packed_conv("conv.weight");
          Timing t = time_recorded(ctx, [&](vk::Recorder& r) { ops::causal_conv3d(r, x, pw, &bias, y); });
          Check c;
          Rng pick(97);
          std::vector<float> row;
          int64_t co = 0, f = 0, yy = 0;
          for (int i = 0; i < 256; ++i) {  // 64 output rows x 4 pixels
            if (i % 4 == 0) {
              co = int64_t(pick.below(size_t(C))), f = int64_t(pick.below(size_t(Fr))), yy = int64_t(pick.below(size_t(H)));
              row = download_row(ctx, y, W, (co * Fr + f) * H + yy);
            }
            const int64_t xx = int64_t(pick.below(size_t(W)));
            double ref = value(hb, co);
            for (int64_t ci = 0; ci < C; ++ci)
              for (int64_t kt = 0; kt < 3; ++kt) {
                const int64_t fi = std::max<int64_t>(f + kt - 2, 0);  // causal: frame 0 repeated in front
                for (int64_t ky = 0; ky < 3; ++ky)
                  for (int64_t kx = 0; kx < 3; ++kx) {
                    const int64_t iy = yy + ky - 1, ix = xx + kx - 1;
                    if (iy < 0 || iy >= H || ix < 0 || ix >= W) continue;
                    ref += double(hx.as<float>()[((ci * Fr + fi) * H + iy) * W + ix]) *
                           value(hw, (((co * C + ci) * 3 + kt) * 3 + ky) * 3 + kx);
                  }
              }
            c.add(row[size_t(xx)], ref);
          }
          const bool x16 = fam == "coopmat" && ops::device_tuning(ctx.caps()).conv_activations_fp16;
          const std::string wdt = std::string("w ") + dtype_name(pw.packed.dtype()) + " packed at load";
          report(b, "conv3d", shape, fam, t, 2.0 * C * C * 27 * Fr * H * W, 0, &c, tolerance_for(fam),
                 {{"dtype", str((x16 ? "x f32 repacked f16, " : "x f32, ") + wdt)}});
        } catch (const std::exception& e) {
          report_error("conv3d", shape, fam, e.what());
        }
      }
    } catch (const std::exception& e) {
      report_error("conv3d", shape, "-", e.what());
    }
  }
}

// ------------------------------------------------------------------------------------------ copy, MMA rate
// vkCmdCopyBuffer and a shader copy (bench/copy: vec4 loads and stores, a grid-stride loop, split at the device's
// binding limit) of the same bytes, both timed by GPU timestamps around each command (the profiler's pairs; wall
// time only where the queue has no timestamps). Each checks 16 rows of the destination against the source.
void copy_case(Bench& b) {
  vk::Context& ctx = b.ctx();
  const uint64_t n = smoke(b) ? (1u << 20) : (256ull << 20);
  const std::string shape = std::to_string(n >> 20) + "MiB";
  auto check_copy = [&](const Tensor& src, const Tensor& dst) {
    Check c;
    const int64_t rows = int64_t(n / 4 / 1024);
    for (int64_t r = 0; r < rows; r += std::max<int64_t>(1, rows / 16)) {  // 16 rows of 1024 values
      const std::vector<float> a = download_row(ctx, src, 1024, r), d = download_row(ctx, dst, 1024, r);
      for (size_t i = 0; i < a.size(); ++i) c.add(d[i], a[i]);
    }
    return c;
  };
  try {
    Tensor src = Tensor::upload(ctx, random_host({int64_t(n / 4)}, DType::f32, 41), "gpu bench copy src");
    {
      Tensor dst = Tensor::empty(ctx, {int64_t(n / 4)}, DType::f32, "gpu bench copy dst");
      Timing t = time_recorded(ctx, [&](vk::Recorder& rec) { rec.copy(src.buffer(), dst.buffer(), n); });
      const Check c = check_copy(src, dst);
      report(b, "copy", shape, "transfer", t, 0, 2.0 * double(n), &c, 0.0);
    }
    {
      Tensor dst = Tensor::empty(ctx, {int64_t(n / 4)}, DType::f32, "gpu bench copy dst");
      const vk::Pipeline& copy = ctx.pipelines().get("bench/copy");
      const uint64_t chunk = std::min<uint64_t>(n, ctx.caps().max_storage_buffer_range / 16 * 16);
      Timing t = time_recorded(ctx, [&](vk::Recorder& rec) {
        for (uint64_t off = 0; off < n; off += chunk) {
          const uint64_t bytes = std::min(chunk, n - off);
          const uint32_t n4 = uint32_t(bytes / 16);
          rec.dispatch(copy, {src.buffer().sub(off, bytes), dst.buffer().sub(off, bytes)}, &n4, 4,
                       std::min({65536u, (n4 + 63) / 64, ctx.caps().max_workgroup_count[0]}));
        }
      });
      const Check c = check_copy(src, dst);
      report(b, "copy", shape, "shader", t, 0, 2.0 * double(n), &c, 0.0);
    }
  } catch (const std::exception& e) {
    report_error("copy", shape, "-", e.what());
  }
}

void mma_rate_case(Bench& b) {
  vk::Context& ctx = b.ctx();
  const ops::CoopmatShape cm = ops::device_tuning(ctx.caps()).coopmat;
  if (!cm.defined() || cm.m != 16 || cm.n != 16) {  // the probe's fragments are 16 x 16 (lavapipe lists 8x8x8)
    emit({{"case", str("mma_rate")}, {"skipped", str("device has no usable 16x16 cooperative-matrix shape")}});
    return;
  }
  try {
    const uint32_t spec[] = {cm.k};
    const vk::Pipeline& p = ctx.pipelines().get("bench/coopmat_mma_rate", spec);
    const uint32_t sg = std::max(1u, ctx.caps().subgroup_size), groups = 1056, iters = smoke(b) ? 64 : 16384;
    vk::Buffer out = ctx.allocator().allocate(uint64_t(groups) * (256 / sg) * 4 * 256 * 4);
    Timing t = time_recorded(ctx, [&](vk::Recorder& r) { r.dispatch(p, {out.view()}, &iters, 4, groups); });
    const double flops = double(groups) * (256 / sg) * iters * 4 * 2.0 * 16 * 16 * cm.k;
    report(b, "mma_rate", "16x16x" + std::to_string(cm.k) + " f16->f32", "coopmat", t, flops, 0, nullptr, 0);
  } catch (const std::exception& e) {
    emit({{"case", str("mma_rate")}, {"skipped", str(std::string("shader bench/coopmat_mma_rate: ") + e.what())}});
  }
}

// -------------------------------------------------------------------------------------------------- block
void block_case(Bench& b) {
  const char* dir_env = std::getenv("DVS_GPU_BENCH_DIR");
  if (!dir_env || !*dir_env) {
    emit({{"case", str("block")}, {"skipped", str("DVS_GPU_BENCH_DIR not set (torch_ref.py writes the folder)")}});
    return;
  }
  vk::Context& ctx = b.ctx();
  const std::filesystem::path dir(dir_env);
  try {
    const HostTensor latent = read_npy(dir / "latent.npy"), text = read_npy(dir / "text.npy"),
                     ts = read_npy(dir / "timestep.npy");
    const std::vector<float> steps = ts.to_f32();
    models::CogVideoXTransformer model(ctx, dir / "transformer");
    Tensor dl = Tensor::upload(ctx, latent, "block latent"), dt = Tensor::upload(ctx, text, "block text");
    const auto& cfg = model.config();
    const int64_t B = latent.shape[0], Fr = latent.shape[1], H = latent.shape[3], W = latent.shape[4];
    const int64_t L = text.shape[1], D = cfg.dim(), S = L + Fr * (H / cfg.patch_size) * (W / cfg.patch_size);
    const double flops = double(B) * S * 24.0 * D * D * cfg.num_layers + 4.0 * B * cfg.heads * double(S) * S * cfg.head_dim * cfg.num_layers;
    const std::string shape = std::to_string(cfg.num_layers) + " layer, " + shape_str(latent.shape) + ", text " + std::to_string(L);
    std::vector<std::string> fams = families(ctx);
    fams.insert(fams.begin(), "default");  // the device's own entry, what `dvs run` would use
    for (const std::string& fam : fams) {
      try {
        std::unique_ptr<ops::ScopedTuningOverride> ov;
        if (fam != "default") ov = std::make_unique<ops::ScopedTuningOverride>("linear=" + fam + ",attention=" + fam + ",conv=" + fam);
        auto w0 = std::chrono::steady_clock::now();
        Tensor out = model.forward(dl, dt, steps);  // warm: pipelines, RoPE / positional tables, arena
        const double warm_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count();
        write_npy(dir / ("out_dvs_" + fam + ".npy"), out.download(ctx));
        const int max_runs = warm_ms > 3000 ? 1 : 5;  // slow old kernels: one timed run
        // Timestamps around each dispatch of whole forward calls (recording included in the wall time).
        vk::Profiler& prof = ctx.profiler();
        const bool was = prof.enabled();
        prof.set_enabled(true);
        std::vector<double> gpu, wall;
        std::map<std::string, double> shader_ms;  // summed over the runs: where the block's time goes
        const auto start = std::chrono::steady_clock::now();
        while (int(gpu.size()) < max_runs && (gpu.size() < 2 || std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < 3.0)) {
          prof.clear();
          auto a = std::chrono::steady_clock::now();
          out = model.forward(dl, dt, steps);
          wall.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
          double ns = 0;
          for (const auto& [label, e] : prof.entries()) ns += e.total_ns, shader_ms[label] += e.total_ns * 1e-6;
          gpu.push_back(ctx.caps().timestamps && ns > 0 ? ns * 1e-6 : wall.back());
          if (wall.back() > 1500) break;
        }
        prof.clear();
        prof.set_enabled(was);
        std::sort(gpu.begin(), gpu.end());
        std::sort(wall.begin(), wall.end());
        Timing t;
        t.gpu_ms = gpu[gpu.size() / 2];
        t.wall_ms = wall[wall.size() / 2];
        t.runs = int(gpu.size());
        for (const auto& [label, ms] : shader_ms) {
          t.shaders += (t.shaders.empty() ? "" : " ") + label;
          if (ctx.caps().timestamps) t.shader_ms[label] = ms / double(gpu.size());  // mean of the runs
        }
        report(b, "block", shape, fam, t, flops, 0, nullptr, 0,
               {{"output", str((dir / ("out_dvs_" + fam + ".npy")).string())},
                {"entry", str(ops::device_tuning(ctx.caps()).entry)}});
      } catch (const std::exception& e) {
        report_error("block", shape, fam, e.what());
      }
    }
    model.release_call_memory();
  } catch (const std::exception& e) {
    report_error("block", dir.string(), "-", e.what());
  }
}

// The compiled-code statistics of every kernel the cases created (VK_KHR_pipeline_executable_properties: NVIDIA
// reports registers, spills, shared memory): one JSON line per pipeline, or one line saying why there are none.
void pipeline_statistics_lines(vk::Context& ctx) {
  if (!ctx.caps().pipeline_executable_info) {
    emit({{"case", str("pipeline_stats")},
          {"skipped", str(ctx.caps().name + " has no VK_KHR_pipeline_executable_properties (pipelineExecutableInfo)")}});
    return;
  }
  ctx.pipelines().for_each([&](const vk::Pipeline& p) {
    const std::vector<vk::PipelineStatistic> stats = vk::pipeline_statistics(ctx, p);
    if (stats.empty()) return;
    std::string obj = "{";
    for (const vk::PipelineStatistic& s : stats)
      obj += (obj.size() > 1 ? "," : "") + str(s.executable + ": " + s.name) + ":" + str(s.value);
    obj += "}";
    emit({{"case", str("pipeline_stats")}, {"shader", str(p.name)}, {"stats", obj}});
  });
}

void gpu(Bench& b) {
  vk::Context& ctx = b.ctx();
  const auto& caps = ctx.caps();
  ctx.pipelines().set_capture_statistics(true);  // the kernels the cases create report their statistics at the end
  std::string fams;
  for (auto& f : families(ctx)) fams += (fams.empty() ? "" : ",") + f;
  emit({{"case", str("dvs_info")}, {"device", str(caps.name)}, {"driver", str(caps.driver_name)},
        {"entry", str(ops::device_tuning(caps).entry)}, {"families", str(fams)},
        {"subgroup_size", std::to_string(caps.subgroup_size)}, {"timestamps", caps.timestamps ? "true" : "false"},
        {"smoke", smoke(b) ? "true" : "false"}});
  // Cheapest and most telling first; the block last (it needs the torch script's folder). DVS_GPU_BENCH_CASES
  // (e.g. "gemm" for one variant of the sweep) runs only the cases it lists.
  const char* only = std::getenv("DVS_GPU_BENCH_CASES");
  auto wanted = [&](const char* c) { return !only || !*only || (std::string(",") + only + ",").find(std::string(",") + c + ",") != std::string::npos; };
  if (wanted("copy")) copy_case(b);
  if (wanted("mma_rate")) mma_rate_case(b);
  if (wanted("gemm")) gemm_cases(b);
  if (wanted("attention")) attention_cases(b);
  if (wanted("conv3d")) conv_cases(b);
  if (wanted("block")) block_case(b);
  pipeline_statistics_lines(ctx);
  ctx.pipelines().set_capture_statistics(false);
}

Registration reg("gpu", 60, gpu);

}  // namespace
}  // namespace dvs::bench
