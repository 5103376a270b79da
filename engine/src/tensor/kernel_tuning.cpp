#include "tensor/kernel_tuning.hpp"

#include <array>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <map>
#include <mutex>
#include <span>
#include <sstream>

#include "dvs/error.hpp"
#include "tensor/coopmat_layout.hpp"

namespace dvs::ops {
namespace {

// One row per device class: how to recognise it, and what it runs. Measured figures are in the commit
// messages, bench/results/ and dvs-bench's output.
struct TuningEntry {
  const char* name;
  bool (*matches)(const vk::DeviceCaps&);
  void (*fill)(DeviceTuning&, const vk::DeviceCaps&);
};

bool f16_f32_subgroup(const vk::CooperativeMatrixShape& s) {
  return s.scope == VK_SCOPE_SUBGROUP_KHR && s.a == VK_COMPONENT_TYPE_FLOAT16_KHR &&
         s.b == VK_COMPONENT_TYPE_FLOAT16_KHR && s.c == VK_COMPONENT_TYPE_FLOAT32_KHR &&
         s.result == VK_COMPONENT_TYPE_FLOAT32_KHR;
}
bool fragment_side(uint32_t v) { return v == 8 || v == 16 || v == 32; }

// The tensor-core shape the coopmat kernels use: fp16 A/B, fp32 C/result, subgroup scope; the first listed
// with M = N = 16 and K 16 or 8 (the shapes the kernels were measured with on GPUs: the H200's 16x16x16). On a
// CPU driver, which runs the coopmat entry only when a test forces it, else the first with sides of 8, 16 or
// 32 (lavapipe lists 8x8x8 only). Undefined when none qualifies.
CoopmatShape pick_coopmat_shape(const vk::DeviceCaps& c) {
  if (!c.cooperative_matrix) return {};
  for (const vk::CooperativeMatrixShape& s : c.cooperative_matrix_shapes)
    if (f16_f32_subgroup(s) && s.m == 16 && s.n == 16 && (s.k == 16 || s.k == 8)) return {s.m, s.n, s.k};
  if (c.type != VK_PHYSICAL_DEVICE_TYPE_CPU) return {};
  for (const vk::CooperativeMatrixShape& s : c.cooperative_matrix_shapes)
    if (f16_f32_subgroup(s) && fragment_side(s.m) && fragment_side(s.n) && fragment_side(s.k)) return {s.m, s.n, s.k};
  return {};
}

// The tensor-core kernels' layouts, best first: per kernel select_tuning takes the first that the device holds
// at its subgroup size and fragment (tensor/coopmat_layout.hpp checks shared memory, invocations, subgroups).
// The first rows are the layouts the H200 and H100 ran (bench/results/, 2026-11-27): 8 subgroups of 32 lanes
// over 128 x 128 x 32 at 16x16x16 (linear: 2 x 4 subgroups of 4 x 2 fragments, 48 KiB; conv: 4 x 2 of 2 x 4,
// 28 KiB) and 4 subgroups of 16 query rows with 64-key tiles (40 KiB at head_dim 64 then, 44 KiB since its rows
// are padded against bank conflicts). The same rows hold
// lavapipe's 8 lanes and 32 KiB at its 8x8x8 fragment (tiles of 64 x 64, 32 query rows); at a forced 16x16x16
// lavapipe takes the smaller rows (linear 64 x 64, attention 2 subgroups).
// Measured on the H200 (2026-11-29, bench/results/h200-2026-11-29*, TFLOP/s at the transformer's four GEMM shapes):
// 2x2x4x4x32 (a 64x64 tile per subgroup, 128x128 per workgroup) 172-193, 2x4x4x2x32 (the first row until then)
// 119-122, 2x2x4x2x32 125-129, 2x2x2x4x32 115-124, 2x2x4x4x16 136-145, 1x1x4x4x32 88-96; 4x2x4x4x32, 2x4x4x4x32 and
// 2x2x4x4x64 do not fit its 48 KiB (they ran tiled).
constexpr CoopmatTile kLinearCoopmatLayouts[] = {{2, 2, 4, 4, 32}, {2, 4, 4, 2, 32}, {2, 2, 2, 2, 32}, {1, 1, 2, 2, 32}};
constexpr CoopmatTile kConvCoopmatLayouts[] = {{4, 2, 2, 4, 32}, {2, 2, 2, 2, 32}, {1, 1, 2, 2, 32}};
constexpr int kAttentionCoopmatSubgroups[] = {4, 2, 1};
// The coopmat2 variant (no scores or P in shared memory) holds 16 subgroups: 256 query rows per K/V tile at
// 16x16x16. Measured on the H200 (2026-11-29, 2x48x17776, head_dim 64): 16 subgroups 160.3 TFLOP/s, 8 97.5-97.6,
// 4 62.7 (SDPA flash 312.6 in the same run).
constexpr int kAttentionCoopmat2Subgroups[] = {16, 8, 4, 2, 1};

// CPU drivers (lavapipe, SwiftShader): an 8- or 16-lane subgroup is one SIMD register and every per-lane
// load is a scalar loop, so register blocks that reuse each fetched texel many times win, as long as the
// accumulators (rows x cols registers) and the fetched texels fit the 32 vector registers of AVX-512
// (lavapipe on a 2-core Zen 5, per CPU-second of the FMA peak: 8x2 0.30-0.45, 8x3 0.20-0.30, 16x2 ~0.31,
// 8x4 ~0.33, 16x1 ~0.28; longer channel-loop trips (k_unroll 4) did not help). 8 x 2 (64 channels per
// workgroup with sg_m 2) also divides the VAE's 128/256/512 channels, where 8 x 3 wastes a third at 128.
// With rotations instead of broadcasts (conv_gemm.comp) 8x2 and 8x4 measured interleaved, twice each, over
// the VAE shapes: 0.28-0.33 and 0.21-0.36, 8x4 ahead on some shapes in one run and behind in the other.
// The conv input repack writes whole rows per invocation (a vector integer division is a scalar loop per
// lane: 11.1 -> 5.1 ms per call at 9x64x96, Mesa 22.3). Norms: one invocation per row. Attention: several
// query rows per invocation and K/V repacked head-major (H=48, L=2048 on lavapipe: 0.28 -> 0.51 of the FMA
// peak).
bool cpu_simd(const vk::DeviceCaps& c) { return c.type == VK_PHYSICAL_DEVICE_TYPE_CPU; }
void fill_cpu_simd(DeviceTuning& t, const vk::DeviceCaps&) {
  t.linear = t.attention = t.conv = KernelFamily::texel;
  t.conv_f32_weights = t.conv_16bit_weights = {8, 2, 2, 0, 1};
  t.conv_small = {4, 4, 1, 0, 1};
  t.conv_pack_columns = 0;
  t.norm_row_per_invocation = true;
  t.attention_rows_by_head_dim = true;
  t.attention_kv_workspace = true;
  t.eltwise_texel_inputs = true;
  t.reduce_min_chunk = 1024;
}

// GPUs with usable tensor cores (VK_KHR_cooperative_matrix with an fp16 x fp16 -> fp32 16x16 shape at
// subgroup scope): GEMM-shaped work on shared-memory tiles feeding cooperative matrices.
bool gpu_coopmat(const vk::DeviceCaps& c) { return c.type != VK_PHYSICAL_DEVICE_TYPE_CPU && pick_coopmat_shape(c).defined(); }
// Any other device: a GPU. Shared-memory tiles over storage buffers, fp32 FMA; few accumulators per thread
// keep occupancy; GPUs broadcast uniform loads. Norms: a workgroup per row.
bool any_device(const vk::DeviceCaps&) { return true; }
void fill_gpu(DeviceTuning& t, const vk::DeviceCaps&) {
  t.linear = t.attention = t.conv = KernelFamily::tiled;
  t.conv_f32_weights = t.conv_16bit_weights = {8, 2, 2, 0, 1};
  t.conv_small = {4, 2, 1, 0, 1};
  t.conv_pack_columns = 4;
  t.conv_pack_pixel_major = true;
  t.norm_row_per_invocation = false;
  t.attention_rows_by_head_dim = false;
  t.attention_kv_workspace = false;
  t.eltwise_texel_inputs = false;
  // Kept at the CPU's 1024, unmeasured on a GPU: the reductions (groupnorm statistics, sums) are a few
  // passes over activations the convolutions around them read many times, and a smaller floor would need
  // more scratch than memory plans size without a device (the field accepts 1024 and up).
  t.reduce_min_chunk = 1024;
  t.linear_tile_m = t.linear_tile_n = 64;
  t.linear_tile_k = 16;
  t.attention_block_q = t.attention_block_k = 64;
  t.conv_tile_m = 128, t.conv_tile_n = 64;  // 8 x 4 fp32 accumulators per invocation
}
// The tensor-core kernels wherever they fit (their layouts: select_tuning, after the overrides).
void fill_gpu_coopmat(DeviceTuning& t, const vk::DeviceCaps& c) {
  fill_gpu(t, c);
  t.linear = t.attention = t.conv = KernelFamily::coopmat;
}

// Every layout field the entry and the overrides left unset: the first row of its table the device holds (or
// the first row, where none does; the family then runs tiled for that reason). Lanes: 32 where the device runs
// compute at 32 (the size the GPU rows were measured at), else its subgroup size (lavapipe: 8); where it has no
// tensor cores only the fp32 twins run, emulating the GPUs' 32.
void choose_coopmat_layouts(DeviceTuning& t, const vk::DeviceCaps& c) {
  const bool can_32 = c.subgroup_size == 32 || (c.subgroup_size_control && c.compute_required_subgroup_size &&
                                                 c.min_subgroup_size <= 32 && c.max_subgroup_size >= 32);
  if (!t.coopmat_lanes) t.coopmat_lanes = t.coopmat.defined() && !can_32 && c.subgroup_size ? int(c.subgroup_size) : 32;
  if (!t.linear_coopmat.defined()) {
    t.linear_coopmat = kLinearCoopmatLayouts[0];
    for (const CoopmatTile& l : kLinearCoopmatLayouts)
      if (linear_coopmat_unfit(c, {t.coopmat, t.coopmat_lanes, l}).empty()) {
        t.linear_coopmat = l;
        break;
      }
  }
  if (!t.conv_coopmat.defined()) {
    t.conv_coopmat = kConvCoopmatLayouts[0];
    for (const CoopmatTile& l : kConvCoopmatLayouts)
      if (conv_coopmat_unfit(c, {t.coopmat, t.coopmat_lanes, l}, false).empty()) {
        t.conv_coopmat = l;
        break;
      }
  }
  if (!t.attention_coopmat_subgroups) {
    const AttentionKernel kernel = attention_coopmat_kernel(c, t);
    const std::span<const int> rows = kernel == AttentionKernel::coopmat2 ? std::span<const int>(kAttentionCoopmat2Subgroups)
                                                                           : std::span<const int>(kAttentionCoopmatSubgroups);
    t.attention_coopmat_subgroups = rows[0];
    for (int sg : rows)
      if (attention_coopmat_unfit(c, {t.coopmat, t.coopmat_lanes, sg, t.attention_block_k}, 0, kernel).empty()) {
        t.attention_coopmat_subgroups = sg;
        break;
      }
  }
}

const std::array<TuningEntry, 3> kTable = {{
    {"cpu-simd", cpu_simd, fill_cpu_simd},
    {"gpu-coopmat", gpu_coopmat, fill_gpu_coopmat},
    {"gpu", any_device, fill_gpu},
}};

// --- overrides -------------------------------------------------------------------------------------------

struct Field {
  const char* name;
  const char* values;  // accepted values, for errors and dvs info
  std::function<bool(DeviceTuning&, const std::string&)> set;  // false: bad value
};

bool parse_int(const std::string& v, int64_t lo, int64_t hi, int64_t& out) {
  if (v.empty()) return false;
  char* end = nullptr;
  long long x = std::strtoll(v.c_str(), &end, 10);
  if (*end || x < lo || x > hi) return false;
  out = x;
  return true;
}
bool parse_bool(const std::string& v, bool& out) {
  if (v == "on" || v == "1" || v == "true" || v == "yes") return out = true, true;
  if (v == "off" || v == "0" || v == "false" || v == "no") return out = false, true;
  return false;
}
bool parse_family(const std::string& v, KernelFamily& out) {
  if (v == "texel") return out = KernelFamily::texel, true;
  if (v == "tiled") return out = KernelFamily::tiled, true;
  if (v == "coopmat") return out = KernelFamily::coopmat, true;
  return false;
}

// "AxBx..." with `count` positive integers up to `hi`.
bool parse_dims(const std::string& v, size_t count, int64_t hi, std::vector<int64_t>& out) {
  out.clear();
  std::stringstream ss(v);
  for (std::string part; std::getline(ss, part, 'x');) {
    int64_t x;
    if (!parse_int(part, 1, hi, x)) return false;
    out.push_back(x);
  }
  return out.size() == count && v.back() != 'x';
}

// A tile of `count` "x"-separated positive integers up to 1024, handed to `assign`.
Field dims_field(const char* name, const char* values, size_t count,
                 void (*assign)(DeviceTuning&, const std::vector<int64_t>&)) {
  return {name, values, [count, assign](DeviceTuning& t, const std::string& v) {
            std::vector<int64_t> d;
            if (!parse_dims(v, count, 1024, d)) return false;
            assign(t, d);
            return true;
          }};
}

Field coopmat_tile_field(const char* name, CoopmatTile DeviceTuning::*m) {
  return {name, "SGMxSGNxFMxFNxK (subgroups along M and N, fragments per subgroup along M and N, K per step)",
          [m](DeviceTuning& t, const std::string& v) {
            std::vector<int64_t> d;
            if (!parse_dims(v, 5, 256, d)) return false;
            t.*m = {int(d[0]), int(d[1]), int(d[2]), int(d[3]), int(d[4])};
            return true;
          }};
}

// The per-shape tile table as DVS_TUNING writes it: "none", or rows "COND:SGMxSGNxFMxFNxK" joined by '+', COND
// "n>=N", "m<=M" or "n>=N&m<=M".
bool parse_linear_rules(const std::string& v, std::vector<LinearCoopmatRule>& out) {
  out.clear();
  if (v == "none") return true;
  std::stringstream rows(v);
  for (std::string row; std::getline(rows, row, '+');) {
    const size_t colon = row.find(':');
    if (colon == std::string::npos) return false;
    LinearCoopmatRule r;
    std::stringstream conds(row.substr(0, colon));
    for (std::string c; std::getline(conds, c, '&');) {
      int64_t x;
      if (c.rfind("n>=", 0) == 0 && !r.min_n && parse_int(c.substr(3), 1, int64_t(1) << 31, x)) r.min_n = x;
      else if (c.rfind("m<=", 0) == 0 && !r.max_m && parse_int(c.substr(3), 1, int64_t(1) << 40, x)) r.max_m = x;
      else return false;
    }
    std::vector<int64_t> d;
    if ((!r.min_n && !r.max_m) || !parse_dims(row.substr(colon + 1), 5, 256, d)) return false;
    r.tile = {int(d[0]), int(d[1]), int(d[2]), int(d[3]), int(d[4])};
    out.push_back(r);
  }
  return !out.empty() && v.back() != '+';
}

std::string describe_linear_rule(const LinearCoopmatRule& r) {
  std::string cond = r.min_n ? "n>=" + std::to_string(r.min_n) : "";
  if (r.max_m) cond += (cond.empty() ? "" : "&") + std::string("m<=") + std::to_string(r.max_m);
  const CoopmatTile& t = r.tile;
  return cond + ":" + std::to_string(t.sg_m) + "x" + std::to_string(t.sg_n) + "x" + std::to_string(t.frags_m) + "x" +
         std::to_string(t.frags_n) + "x" + std::to_string(t.k);
}

Field family_field(const char* name, KernelFamily DeviceTuning::*m) {
  return {name, "texel|tiled|coopmat", [m](DeviceTuning& t, const std::string& v) { return parse_family(v, t.*m); }};
}
Field bool_field(const char* name, bool DeviceTuning::*m) {
  return {name, "on|off", [m](DeviceTuning& t, const std::string& v) { return parse_bool(v, t.*m); }};
}
Field int_field(const char* name, int DeviceTuning::*m, int lo, int hi, const char* values) {
  return {name, values, [m, lo, hi](DeviceTuning& t, const std::string& v) {
            int64_t x;
            if (!parse_int(v, lo, hi, x)) return false;
            t.*m = int(x);
            return true;
          }};
}

const std::vector<Field>& fields() {
  static const std::vector<Field> f = {
      family_field("linear", &DeviceTuning::linear),
      family_field("attention", &DeviceTuning::attention),
      family_field("conv", &DeviceTuning::conv),
      // A forced shape is for testing: lavapipe lists only 8x8x8 but computes 16x16x16 correctly (the
      // validation layer then reports the unlisted shape; tests/run_on_mesa_coopmat.sh filters that one).
      {"coopmat", "off (every coopmat family becomes tiled) | MxNxK of 8, 16 or 32 (forced, even if unlisted)",
       [](DeviceTuning& t, const std::string& v) {
         std::vector<int64_t> d;
         if (parse_dims(v, 3, 32, d)) {
           for (int64_t x : d)
             if (!fragment_side(uint32_t(x))) return false;
           t.coopmat = {uint32_t(d[0]), uint32_t(d[1]), uint32_t(d[2])};
           return true;
         }
         bool on;
         if (!parse_bool(v, on) || on) return false;
         t.coopmat = {};
         return true;
       }},
      // Lanes other than the device's subgroup size: for the fp32 twins (which emulate them); the tensor-core
      // kernels then refuse to run (their pipelines require the subgroup size).
      {"coopmat_lanes", "4..128, a power of two (default: 32 where the device runs compute at 32, else its subgroup size)",
       [](DeviceTuning& t, const std::string& v) {
         int64_t x;
         if (!parse_int(v, 4, 128, x) || (x & (x - 1))) return false;
         t.coopmat_lanes = int(x);
         return true;
       }},
      coopmat_tile_field("linear_coopmat", &DeviceTuning::linear_coopmat),
      coopmat_tile_field("conv_coopmat", &DeviceTuning::conv_coopmat),
      {"linear_coopmat_by_shape",
       "none, or rows COND:SGMxSGNxFMxFNxK joined by '+', COND n>=N, m<=M or n>=N&m<=M (the first matching row's "
       "layout instead of linear_coopmat)",
       [](DeviceTuning& t, const std::string& v) { return parse_linear_rules(v, t.linear_coopmat_by_shape); }},
      bool_field("linear_coopmat_vector_loads", &DeviceTuning::linear_coopmat_vector_loads),
      bool_field("linear_coopmat2", &DeviceTuning::linear_coopmat2),
      dims_field("linear_coopmat2_tile", "BMxBNxBKxWG (output rows, columns, K per step, invocations)", 4,
                 [](DeviceTuning& t, const std::vector<int64_t>& d) {
                   t.linear_coopmat2_tile = {int(d[0]), int(d[1]), int(d[2]), int(d[3])};
                 }),
      bool_field("linear_weights_fp16", &DeviceTuning::linear_weights_fp16),
      bool_field("linear_activations_fp16", &DeviceTuning::linear_activations_fp16),
      bool_field("conv_coopmat_double_buffer", &DeviceTuning::conv_coopmat_double_buffer),
      bool_field("conv_coopmat_vector_loads", &DeviceTuning::conv_coopmat_vector_loads),
      bool_field("conv_coopmat2", &DeviceTuning::conv_coopmat2),
      bool_field("conv_shifted_gemm", &DeviceTuning::conv_shifted_gemm),
      dims_field("conv_coopmat2_tile",
                 "PHxPWxBNxBKxWG (output rows and columns of a patch, output channels, K per step, invocations)", 5,
                 [](DeviceTuning& t, const std::vector<int64_t>& d) {
                   t.conv_coopmat2_tile = {int(d[0]), int(d[1]), int(d[2]), int(d[3]), int(d[4])};
                 }),
      bool_field("conv_pack_pixel_major", &DeviceTuning::conv_pack_pixel_major),
      bool_field("conv_pack_tiled", &DeviceTuning::conv_pack_tiled),
      bool_field("conv_activations_fp16", &DeviceTuning::conv_activations_fp16),
      bool_field("conv_weights_fp16", &DeviceTuning::conv_weights_fp16),
      int_field("linear_coopmat_group_m", &DeviceTuning::linear_coopmat_group_m, 1, 64, "1..64"),
      {"linear_coopmat_ablation", "none|no_global_loads|no_mma (measurements only: the results are wrong)",
       [](DeviceTuning& t, const std::string& v) {
         const char* names[] = {"none", "no_global_loads", "no_mma"};
         for (int i = 0; i < 3; ++i)
           if (v == names[i]) {
             t.linear_coopmat_ablation = i;
             return true;
           }
         return false;
       }},
      int_field("attention_coopmat_subgroups", &DeviceTuning::attention_coopmat_subgroups, 1, 32, "1..32"),
      bool_field("attention_coopmat2", &DeviceTuning::attention_coopmat2),
      int_field("linear_tile_m", &DeviceTuning::linear_tile_m, 16, 256, "16..256"),
      int_field("linear_tile_n", &DeviceTuning::linear_tile_n, 16, 256, "16..256"),
      int_field("linear_tile_k", &DeviceTuning::linear_tile_k, 8, 64, "8..64"),
      bool_field("linear_f32_weights_16x2", &DeviceTuning::linear_f32_weights_16x2),
      int_field("attention_block_q", &DeviceTuning::attention_block_q, 16, 256, "16..256"),
      int_field("attention_block_k", &DeviceTuning::attention_block_k, 16, 256, "16..256"),
      bool_field("attention_rows_by_head_dim", &DeviceTuning::attention_rows_by_head_dim),
      bool_field("attention_kv_workspace", &DeviceTuning::attention_kv_workspace),
      bool_field("attention_coopmat_twin", &DeviceTuning::attention_coopmat_twin),
      {"conv_tile_m", "32|64|128", [](DeviceTuning& t, const std::string& v) {
         int64_t x;
         if (!parse_int(v, 32, 128, x) || (x != 32 && x != 64 && x != 128)) return false;
         t.conv_tile_m = int(x);
         return true;
       }},
      {"conv_tile_n", "32|64|128", [](DeviceTuning& t, const std::string& v) {
         int64_t x;
         if (!parse_int(v, 32, 128, x) || (x != 32 && x != 64 && x != 128)) return false;
         t.conv_tile_n = int(x);
         return true;
       }},
      int_field("conv_pack_columns", &DeviceTuning::conv_pack_columns, 0, 1 << 20, "0 (whole rows) or pixels"),
      bool_field("norm_row_per_invocation", &DeviceTuning::norm_row_per_invocation),
      bool_field("eltwise_texel_inputs", &DeviceTuning::eltwise_texel_inputs),
      // Not below 1024: scratch sized without a device (ops_reduce.cpp's kScratchMinChunk) must bound every
      // tuning's partial count.
      {"reduce_min_chunk", "1024..1048576 (a multiple of 4)",
       [](DeviceTuning& t, const std::string& v) {
         int64_t x;
         if (!parse_int(v, 1024, 1 << 20, x) || x % 4) return false;
         t.reduce_min_chunk = x;
         return true;
       }},
  };
  return f;
}

std::string g_scoped_override;

std::string env_override() {
  const char* e = std::getenv("DVS_TUNING");
  return e ? e : "";
}

std::string joined(const std::string& a, const std::string& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  return a + "," + b;
}

}  // namespace

const char* kernel_family_name(KernelFamily k) {
  switch (k) {
    case KernelFamily::texel: return "texel";
    case KernelFamily::tiled: return "tiled";
    case KernelFamily::coopmat: return "coopmat";
  }
  return "?";
}

std::string tuning_field_names() {
  std::ostringstream o;
  o << "  an entry:";
  for (const TuningEntry& e : kTable) o << " " << e.name;
  o << "\n";
  for (const Field& f : fields()) o << "  " << f.name << "=" << f.values << "\n";
  return o.str();
}

DeviceTuning select_tuning(const vk::DeviceCaps& caps, const std::string& overrides) {
  DeviceTuning t;
  const TuningEntry* entry = nullptr;
  for (const TuningEntry& e : kTable)
    if (e.matches(caps)) {
      entry = &e;
      break;
    }
  // An entry named in the overrides replaces the matched one (the first item without '=').
  std::vector<std::string> items;
  {
    std::stringstream ss(overrides);
    for (std::string item; std::getline(ss, item, ',');)
      if (!item.empty()) items.push_back(item);
  }
  for (const std::string& item : items) {
    if (item.find('=') != std::string::npos) continue;
    entry = nullptr;
    for (const TuningEntry& e : kTable)
      if (item == e.name) entry = &e;
    if (!entry)
      throw Error("DVS_TUNING: no tuning entry '" + item + "'. Entries and fields:\n" + tuning_field_names());
  }
  t.entry = entry->name;
  t.overrides = overrides;
  t.gemm_lanes = (caps.subgroup_shuffle && caps.subgroup_size == 8) ? 0
                 : (caps.subgroup_shuffle && caps.subgroup_size >= 8 && caps.subgroup_size <= 64 &&
                    caps.subgroup_size % 8 == 0)
                     ? 1
                     : 2;
  t.coopmat = pick_coopmat_shape(caps);
  const bool device_shape = t.coopmat.defined();
  entry->fill(t, caps);
  for (const std::string& item : items) {
    const size_t eq = item.find('=');
    if (eq == std::string::npos) continue;
    const std::string name = item.substr(0, eq), value = item.substr(eq + 1);
    const Field* f = nullptr;
    for (const Field& c : fields())
      if (name == c.name) f = &c;
    if (!f) throw Error("DVS_TUNING: no field '" + name + "'. Entries and fields:\n" + tuning_field_names());
    if (!f->set(t, value))
      throw Error("DVS_TUNING: " + name + "=" + value + " is not one of " + f->values);
  }
  // Tensor cores only where the device has a usable shape and holds the kernel's layout: elsewhere a coopmat
  // family runs tiled, and why is kept (ops note it with every call they run: kernel_census.hpp). coopmat=off
  // asks for tiled, which is no fallback.
  const bool turned_off = device_shape && !t.coopmat.defined();
  if (!caps.cooperative_matrix) t.coopmat = {};  // a forced shape needs the extension all the same
  choose_coopmat_layouts(t, caps);
  const std::string no_shape =
      "no fp16 x fp16 + fp32 cooperative-matrix shape at subgroup scope on " + caps.name +
      " (VK_KHR_cooperative_matrix with vulkanMemoryModel on Vulkan 1.3)";
  auto settle = [&](KernelFamily& k, std::string& unfit, const std::string& why) {
    if (k != KernelFamily::coopmat) return;
    if (!turned_off) unfit = t.coopmat.defined() ? why : no_shape;
    if (turned_off || !unfit.empty()) k = KernelFamily::tiled;
  };
  settle(t.linear, t.linear_unfit, linear_coopmat_unfit(caps, linear_coopmat_layout(t)));
  if (t.linear == KernelFamily::coopmat)
    for (const LinearCoopmatRule& r : t.linear_coopmat_by_shape) {
      const std::string why = linear_coopmat_unfit(caps, {t.coopmat, t.coopmat_lanes, r.tile});
      if (!why.empty())
        throw Error("DVS_TUNING: linear_coopmat_by_shape row " + describe_linear_rule(r) + " does not fit " +
                    caps.name + ": " + why);
    }
  if (t.linear_coopmat2)
    t.linear_coopmat2_unfit = linear_coopmat2_unfit(caps, t.linear_coopmat2_tile);
  settle(t.conv, t.conv_unfit, conv_coopmat_unfit(caps, conv_coopmat_layout(t), false));
  settle(t.attention, t.attention_unfit,
         attention_coopmat_unfit(caps, attention_coopmat_layout(t), 0, attention_coopmat_kernel(caps, t)));
  return t;
}

const DeviceTuning& device_tuning(const vk::DeviceCaps& caps) {
  static std::mutex mutex;
  static std::map<std::string, DeviceTuning> cache;
  const std::string overrides = joined(env_override(), g_scoped_override);
  std::string key(reinterpret_cast<const char*>(caps.pipeline_cache_uuid), VK_UUID_SIZE);
  // Every property an entry or field reads (faked caps in tests differ in only one of them).
  const CoopmatShape shape = pick_coopmat_shape(caps);
  for (uint64_t v : {uint64_t(caps.type), uint64_t(caps.subgroup_size), uint64_t(caps.subgroup_shuffle),
                     uint64_t(caps.cooperative_matrix), uint64_t(shape.m), uint64_t(shape.n), uint64_t(shape.k),
                     uint64_t(caps.max_compute_shared_memory), uint64_t(caps.max_workgroup_invocations),
                     uint64_t(caps.subgroup_size_control), uint64_t(caps.compute_required_subgroup_size),
                     uint64_t(caps.min_subgroup_size), uint64_t(caps.max_subgroup_size),
                     uint64_t(caps.max_compute_workgroup_subgroups)})
    key.append(reinterpret_cast<const char*>(&v), sizeof v);  // raw bytes: called per op, kept cheap
  key += caps.name + '\n' + overrides;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(key);
  if (it == cache.end()) it = cache.emplace(key, select_tuning(caps, overrides)).first;
  return it->second;
}

std::string describe_tuning(const DeviceTuning& t) {
  std::ostringstream o;
  auto tile = [](const GemmTile& g) {
    return std::to_string(g.rows) + "x" + std::to_string(g.cols) + " sg_m " + std::to_string(g.sg_m);
  };
  auto unfit = [](const std::string& why) { return why.empty() ? std::string() : " (coopmat does not fit: " + why + ")"; };
  o << "Kernel tuning: entry \"" << t.entry << "\"" << (t.overrides.empty() ? "" : " with overrides \"" + t.overrides + "\"")
    << " (DVS_TUNING overrides)\n"
    << "  linear:     " << kernel_family_name(t.linear) << unfit(t.linear_unfit);
  if (t.linear == KernelFamily::tiled)
    o << ", tile " << t.linear_tile_m << "x" << t.linear_tile_n << "x" << t.linear_tile_k;
  if (t.linear == KernelFamily::coopmat) {
    o << ", tile " << linear_coopmat_layout(t).describe();
    for (const LinearCoopmatRule& r : t.linear_coopmat_by_shape) o << " (" << describe_linear_rule(r) << ")";
    o << ", bands of " << t.linear_coopmat_group_m << " tile rows"
      << (t.linear_coopmat_vector_loads ? ", 16-byte loads where aligned" : ", element loads")
      << (t.linear_weights_fp16 ? ", bf16 weights kept fp16" : ", bf16 weights converted in the loads")
      << (t.linear_activations_fp16 ? ", norm and GELU outputs written fp16" : ", norm and GELU outputs f32")
      << (!t.linear_coopmat2 ? std::string()
          : t.linear_coopmat2_unfit.empty()
              ? ", VK_NV_cooperative_matrix2 kernel (tile " + std::to_string(t.linear_coopmat2_tile.m) + "x" +
                    std::to_string(t.linear_coopmat2_tile.n) + "x" + std::to_string(t.linear_coopmat2_tile.k) + ", " +
                    std::to_string(t.linear_coopmat2_tile.invocations) + " invocations) for fp16 X and W"
              : ", VK_NV_cooperative_matrix2 kernel not on this device: " + t.linear_coopmat2_unfit)
      << (t.linear_coopmat_ablation == 1   ? ", ABLATED: no global loads (wrong results)"
          : t.linear_coopmat_ablation == 2 ? ", ABLATED: no MMA (wrong results)"
                                           : "");
  }
  o << "\n  attention:  " << kernel_family_name(t.attention) << unfit(t.attention_unfit);
  if (t.attention == KernelFamily::tiled) o << ", blocks " << t.attention_block_q << " queries x " << t.attention_block_k << " keys";
  if (t.attention == KernelFamily::coopmat)
    o << ", blocks " << attention_coopmat_layout(t).describe()
      << (t.attention_coopmat2 ? ", softmax in the matrices where VK_NV_cooperative_matrix2 allows" : "");
  o << (t.attention_kv_workspace ? ", K/V repacked head-major when offered a workspace" : "") << "\n"
    << "  conv:       " << kernel_family_name(t.conv) << unfit(t.conv_unfit) << ", texel tiles " << tile(t.conv_16bit_weights) << " (small "
    << tile(t.conv_small) << ")" << (t.conv == KernelFamily::tiled ? ", tiled " + std::to_string(t.conv_tile_m) + "x" + std::to_string(t.conv_tile_n) : std::string())
    << (t.conv == KernelFamily::coopmat ? ", tile " + conv_coopmat_layout(t).describe() +
                                              (t.conv_coopmat_double_buffer ? ", two operand stages where they fit" : "") +
                                              (t.conv_coopmat_vector_loads ? ", 16-byte gathers where they apply" : "") +
                                              (t.conv_coopmat2 ? ", VK_NV_cooperative_matrix2 kernel where the device and call allow" : "") +
                                              (t.conv_shifted_gemm ? ", same-size convolutions through the GEMM kernel where they allow" : "") +
                                              (t.conv_activations_fp16 ? ", input repacked fp16" : ", input repacked f32") +
                                              (t.conv_weights_fp16 ? ", bf16 weights kept fp16" : "")
                                        : std::string())
    << ", repack " << (t.conv_pack_columns ? std::to_string(t.conv_pack_columns) + " pixels" : "whole rows")
    << " per invocation" << (t.conv_pack_pixel_major ? ", neighbouring invocations on neighbouring pixels" : "")
    << (t.conv_pack_tiled ? ", or transposed through shared memory where a dispatch owns whole vec4s" : "") << "\n"
    << "  norms:      " << (t.norm_row_per_invocation ? "one invocation per row" : "one workgroup per row") << "\n"
    << "  elementwise: " << (t.eltwise_texel_inputs ? "texel-buffer inputs" : "storage-buffer inputs")
    << "; reductions: partials of at least " << t.reduce_min_chunk << " elements\n"
    << "  lanes:      " << (t.gemm_lanes == 0 ? "subgroups of 8" : t.gemm_lanes == 1 ? "clusters of 8 in wider subgroups" : "no subgroup shuffles") << "\n"
    << "  tensor cores: "
    << (t.coopmat.defined() ? std::to_string(t.coopmat.m) + "x" + std::to_string(t.coopmat.n) + "x" +
                                  std::to_string(t.coopmat.k) + " f16*f16+f32 (VK_KHR_cooperative_matrix)"
                            : std::string("none")) << "\n";
  return o.str();
}

ScopedTuningOverride::ScopedTuningOverride(std::string overrides) : previous_(g_scoped_override) {
  g_scoped_override = std::move(overrides);
}
ScopedTuningOverride::~ScopedTuningOverride() { g_scoped_override = previous_; }

int gemm_lanes(const vk::DeviceCaps& c) { return device_tuning(c).gemm_lanes; }

GemmTile conv_tile(const vk::DeviceCaps& caps, DType wdt, int64_t outputs, int64_t out_channels,
                   std::string* device_class) {
  const DeviceTuning& e = device_tuning(caps);
  GemmTile t = wdt == DType::f32 ? e.conv_f32_weights : e.conv_16bit_weights;
  if (outputs < 8 * t.rows) t = e.conv_small;
  t.lanes = e.gemm_lanes;
  // Few output channels (the decoder's conv_out has 3): all 8 clusters along the pixels and one or two
  // 8-channel columns, instead of a 64-channel tile that is mostly padding.
  if (out_channels <= 16) {
    t.sg_m = 8;
    t.cols = out_channels <= 8 ? 1 : 2;
  }
  if (device_class) *device_class = e.entry;
  return t;
}

int conv_pack_columns(const vk::DeviceCaps& caps) { return device_tuning(caps).conv_pack_columns; }

}  // namespace dvs::ops
