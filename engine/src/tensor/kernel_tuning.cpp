#include "tensor/kernel_tuning.hpp"

#include <array>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>

#include "dvs/error.hpp"

namespace dvs::ops {
namespace {

// One row per device class: how to recognise it, and what it runs. Measured figures are in the commit
// messages, bench/results/ and dvs-bench's output.
struct TuningEntry {
  const char* name;
  bool (*matches)(const vk::DeviceCaps&);
  void (*fill)(DeviceTuning&, const vk::DeviceCaps&);
};

// The tensor-core shape the coopmat kernels use: fp16 A/B, fp32 C/result, subgroup scope, M and N 16
// (the kernels' fragment), K 16 or 8; the first the device lists. Undefined when none qualifies.
CoopmatShape pick_coopmat_shape(const vk::DeviceCaps& c) {
  if (!c.cooperative_matrix) return {};
  for (const vk::CooperativeMatrixShape& s : c.cooperative_matrix_shapes)
    if (s.scope == VK_SCOPE_SUBGROUP_KHR && s.a == VK_COMPONENT_TYPE_FLOAT16_KHR &&
        s.b == VK_COMPONENT_TYPE_FLOAT16_KHR && s.c == VK_COMPONENT_TYPE_FLOAT32_KHR &&
        s.result == VK_COMPONENT_TYPE_FLOAT32_KHR && s.m == 16 && s.n == 16 && (s.k == 16 || s.k == 8))
      return {s.m, s.n, s.k};
  return {};
}

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
// Where a coopmat kernel's fixed layout fits the device. All three split their workgroup into subgroups of
// 32 lanes (attention_flash_coopmat: 4 x 16 query rows, 2 lanes a row; conv_coopmat and linear_coopmat: 8
// subgroups); linear_coopmat also double-buffers its 128x128x32 tile in 48 KiB of shared memory. Elsewhere the
// op runs its tiled kernel (checked after the overrides too, so forcing a family cannot pick a misfit).
bool coopmat_fits(KernelFamily DeviceTuning::*op, const vk::DeviceCaps& c) {
  if (c.subgroup_size != 32) return false;
  return op != &DeviceTuning::linear || c.max_compute_shared_memory >= 48 * 1024;
}

void fill_gpu_coopmat(DeviceTuning& t, const vk::DeviceCaps& c) {
  fill_gpu(t, c);
  t.linear = t.attention = t.conv = KernelFamily::coopmat;
  // linalg/linear_coopmat's tile; where it does not fit, the tiled kernel keeps the gpu entry's tile.
  if (coopmat_fits(&DeviceTuning::linear, c)) {
    t.linear_tile_m = t.linear_tile_n = 128;
    t.linear_tile_k = 32;
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
      // A forced shape is for testing: sid's lavapipe lists only 8x8x8 but computes 16x16 correctly (the
      // validation layer then reports the unlisted shape; tests/run_on_mesa_coopmat.sh filters that one).
      {"coopmat", "off (every coopmat family becomes tiled) | 16x16x16 | 16x16x8 (forced, even if unlisted)",
       [](DeviceTuning& t, const std::string& v) {
         if (v == "16x16x16" || v == "16x16x8") return t.coopmat = {16, 16, v == "16x16x16" ? 16u : 8u}, true;
         bool on;
         if (!parse_bool(v, on) || on) return false;
         t.coopmat = {};
         return true;
       }},
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
  // Tensor cores only where the device has a usable shape: a coopmat family becomes tiled without one.
  if (!caps.cooperative_matrix) t.coopmat = {};  // a forced shape needs the extension all the same
  if (!t.coopmat.defined())
    for (KernelFamily* k : {&t.linear, &t.attention, &t.conv})
      if (*k == KernelFamily::coopmat) *k = KernelFamily::tiled;
  for (KernelFamily DeviceTuning::*op : {&DeviceTuning::linear, &DeviceTuning::attention, &DeviceTuning::conv})
    if (t.*op == KernelFamily::coopmat && !coopmat_fits(op, caps)) t.*op = KernelFamily::tiled;
  return t;
}

const DeviceTuning& device_tuning(const vk::DeviceCaps& caps) {
  static std::mutex mutex;
  static std::map<std::string, DeviceTuning> cache;
  const std::string overrides = joined(env_override(), g_scoped_override);
  std::string key(reinterpret_cast<const char*>(caps.pipeline_cache_uuid), VK_UUID_SIZE);
  // Every property an entry or field reads (faked caps in tests differ in only one of them).
  key += caps.name + '\n' + std::to_string(caps.type) + '\n' + std::to_string(caps.subgroup_size) +
         (caps.subgroup_shuffle ? "s\n" : "\n") + (caps.cooperative_matrix ? "c" : "") +
         std::to_string(pick_coopmat_shape(caps).k) + '\n' + overrides;
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
  o << "Kernel tuning: entry \"" << t.entry << "\"" << (t.overrides.empty() ? "" : " with overrides \"" + t.overrides + "\"")
    << " (DVS_TUNING overrides)\n"
    << "  linear:     " << kernel_family_name(t.linear);
  if (t.linear != KernelFamily::texel)
    o << ", tile " << t.linear_tile_m << "x" << t.linear_tile_n << "x" << t.linear_tile_k;
  o << "\n  attention:  " << kernel_family_name(t.attention);
  if (t.attention != KernelFamily::texel) o << ", blocks " << t.attention_block_q << " queries x " << t.attention_block_k << " keys";
  o << (t.attention_kv_workspace ? ", K/V repacked head-major when offered a workspace" : "") << "\n"
    << "  conv:       " << kernel_family_name(t.conv) << ", texel tiles " << tile(t.conv_16bit_weights) << " (small "
    << tile(t.conv_small) << ")" << (t.conv == KernelFamily::tiled ? ", tiled " + std::to_string(t.conv_tile_m) + "x" + std::to_string(t.conv_tile_n) : std::string())
    << ", repack " << (t.conv_pack_columns ? std::to_string(t.conv_pack_columns) + " pixels" : "whole rows")
    << " per invocation\n"
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
