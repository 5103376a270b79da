#include "tensor/coopmat_layout.hpp"

#include <algorithm>
#include <numeric>

#include "dvs/error.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {
namespace {

std::string shape_text(CoopmatShape s) {
  return std::to_string(s.m) + "x" + std::to_string(s.n) + "x" + std::to_string(s.k);
}

bool power_of_two(int64_t v) { return v > 0 && (v & (v - 1)) == 0; }

// The device limits every layout meets: invocations, subgroups per workgroup, shared memory and, for the
// tensor-core kernels (not the twins), the subgroup size and the fragment shape. `field` is the DVS_TUNING field
// that changes the layout.
std::string device_unfit(const vk::DeviceCaps& caps, CoopmatShape frag, int lanes, int subgroups, uint64_t shared,
                         bool twin, const char* field) {
  const std::string fix = std::string(" (a smaller layout in DVS_TUNING: ") + field + ")";
  const uint32_t invocations = uint32_t(subgroups * lanes);
  if (invocations > caps.max_workgroup_invocations)
    return std::to_string(subgroups) + " subgroups of " + std::to_string(lanes) + " lanes are " +
           std::to_string(invocations) + " invocations; " + caps.name + " allows " +
           std::to_string(caps.max_workgroup_invocations) + " per workgroup (maxComputeWorkGroupInvocations)" + fix;
  if (shared > caps.max_compute_shared_memory)
    return "needs " + std::to_string(shared) + " bytes of shared memory; " + caps.name + " has " +
           std::to_string(caps.max_compute_shared_memory) + " (maxComputeSharedMemorySize)" + fix;
  if (twin) return "";
  if (!frag.defined()) return "no fp16 x fp16 + fp32 cooperative-matrix shape at subgroup scope on " + caps.name;
  const bool sized = caps.subgroup_size_control && caps.compute_required_subgroup_size &&
                     uint32_t(lanes) >= caps.min_subgroup_size && uint32_t(lanes) <= caps.max_subgroup_size;
  if (!sized && uint32_t(lanes) != caps.subgroup_size)
    return "laid out for subgroups of " + std::to_string(lanes) + " lanes; " + caps.name + " has " +
           std::to_string(caps.subgroup_size) + " (DVS_TUNING: coopmat_lanes)";
  if (caps.max_compute_workgroup_subgroups && uint32_t(subgroups) > caps.max_compute_workgroup_subgroups)
    return std::to_string(subgroups) + " subgroups per workgroup; " + caps.name + " allows " +
           std::to_string(caps.max_compute_workgroup_subgroups) + " (maxComputeWorkgroupSubgroups)" + fix;
  return "";
}

// The gather of a GEMM operand tile of `rows` x BK by `wg` invocations (conv_coopmat.comp): one row each and
// several 4-element groups of K (wg >= rows), or several rows each and every group (wg < rows).
bool gather_maps(int64_t rows, int64_t wg, int64_t k) {
  if (wg >= rows) return wg % rows == 0 && (k / 4) % (wg / rows) == 0;
  return rows % wg == 0;
}

}  // namespace

std::string CoopmatGemm::describe() const {
  return std::to_string(tile_m()) + "x" + std::to_string(tile_n()) + "x" + std::to_string(tile.k) + " (" +
         std::to_string(tile.sg_m) + "x" + std::to_string(tile.sg_n) + " subgroups of " + std::to_string(lanes) +
         " lanes, " + std::to_string(tile.frags_m) + "x" + std::to_string(tile.frags_n) + " fragments of " +
         shape_text(frag) + " each)";
}

std::string CoopmatAttention::describe() const {
  return std::to_string(rows()) + " query rows x " + std::to_string(block_k) + " keys (" + std::to_string(subgroups) +
         " subgroups of " + std::to_string(lanes) + " lanes, fragments " + shape_text(frag) + ")";
}

// The device's shape; where it has none (the twins' devices), the GPUs' 16x16x16.
CoopmatShape layout_fragment(const DeviceTuning& t) { return t.coopmat.defined() ? t.coopmat : CoopmatShape{16, 16, 16}; }

CoopmatGemm linear_coopmat_layout(const DeviceTuning& t) { return {layout_fragment(t), t.coopmat_lanes, t.linear_coopmat}; }
CoopmatGemm linear_coopmat_layout(const DeviceTuning& t, int64_t m, int64_t n) {
  for (const LinearCoopmatRule& r : t.linear_coopmat_by_shape)
    if ((!r.min_n || n >= r.min_n) && (!r.max_m || m <= r.max_m)) return {layout_fragment(t), t.coopmat_lanes, r.tile};
  return linear_coopmat_layout(t);
}
CoopmatGemm conv_coopmat_layout(const DeviceTuning& t) { return {layout_fragment(t), t.coopmat_lanes, t.conv_coopmat}; }
CoopmatAttention attention_coopmat_layout(const DeviceTuning& t) {
  return {layout_fragment(t), t.coopmat_lanes, t.attention_coopmat_subgroups, t.attention_block_k};
}

uint64_t linear_coopmat_shared_bytes(const CoopmatGemm& g) {
  return 2ull * uint64_t(g.tile_m() + g.tile_n()) * uint64_t(g.tile.k + 8) * 2 +
         uint64_t(g.tile.subgroups()) * g.frag.m * g.frag.n * 4;
}

uint64_t conv_coopmat_shared_bytes(const CoopmatGemm& g, int stages) {
  return uint64_t(stages) * uint64_t(g.tile_m() + g.tile_n()) * uint64_t(g.tile.k + 8) * 2 +
         uint64_t(g.tile.subgroups()) * g.frag.m * g.frag.n * 4;
}

int conv_coopmat_stages(const vk::DeviceCaps& caps, const CoopmatGemm& g, bool double_buffer) {
  return double_buffer && conv_coopmat_shared_bytes(g, 2) <= caps.max_compute_shared_memory ? 2 : 1;
}

AttentionKernel attention_coopmat_kernel(const vk::DeviceCaps& caps, const DeviceTuning& t) {
  const CoopmatAttention a = attention_coopmat_layout(t);
  return t.attention_coopmat2 && caps.cooperative_matrix2_row_ops && a.frag.n == a.frag.k ? AttentionKernel::coopmat2
                                                                                           : AttentionKernel::khr;
}

// Rows padded as the shaders pad them (attention_flash_coopmat_decl.glsl: KP, SP, PP; attention_flash_coopmat2:
// OP).
uint64_t attention_coopmat_shared_bytes(const CoopmatAttention& a, int64_t D, AttentionKernel kernel) {
  const uint64_t bk = uint64_t(a.block_k), rows = uint64_t(a.rows()), kv = 2 * bk * uint64_t(D + 8) * 2;
  if (kernel == AttentionKernel::coopmat2) return kv + rows * (a.frag.n + 4) * 4;
  const uint64_t khr = kv + rows * (bk + 4) * 4 + rows * (bk + 8) * 2;
  if (kernel == AttentionKernel::khr) return khr;
  return khr + rows * uint64_t(D) * 2 + uint64_t(a.invocations()) * 4;
}

std::string linear_coopmat_unfit(const vk::DeviceCaps& caps, const CoopmatGemm& g) {
  const CoopmatTile& t = g.tile;
  if (!t.defined() || !g.frag.defined() || !power_of_two(g.lanes))
    return "layout " + g.describe() + " is incomplete (DVS_TUNING: linear_coopmat, coopmat, coopmat_lanes)";
  const int64_t wg = g.invocations();
  // The staging map: invocation i loads column i % K of rows i / K + (wg / K)·j of both tiles.
  if (t.k % 8 || t.k % int(g.frag.k) || wg % t.k || g.tile_m() % (wg / t.k) || g.tile_n() % (wg / t.k))
    return "layout " + g.describe() + " does not divide: K a multiple of 8 and of the fragment's K, the " +
           std::to_string(wg) + " invocations a multiple of K and M, N multiples of invocations / K " +
           "(DVS_TUNING: linear_coopmat)";
  return device_unfit(caps, g.frag, g.lanes, t.subgroups(), linear_coopmat_shared_bytes(g), false, "linear_coopmat");
}

std::string conv_coopmat_unfit(const vk::DeviceCaps& caps, const CoopmatGemm& g, bool twin) {
  const CoopmatTile& t = g.tile;
  if (!t.defined() || !g.frag.defined() || !power_of_two(g.lanes))
    return "layout " + g.describe() + " is incomplete (DVS_TUNING: conv_coopmat, coopmat, coopmat_lanes)";
  const int64_t wg = g.invocations();
  if (t.k % 8 || t.k % int(g.frag.k) || !gather_maps(g.tile_m(), wg, t.k) || !gather_maps(g.tile_n(), wg, t.k) ||
      (twin && (g.frag.m * g.frag.n) % uint32_t(g.lanes)))
    return "layout " + g.describe() + " does not divide: K a multiple of 8 and of the fragment's K; the " +
           std::to_string(wg) + " invocations a multiple of the tile's pixels and channels (with K / 4 a " +
           "multiple of the quotient) or dividing them" + (twin ? "; lanes dividing a fragment" : "") +
           " (DVS_TUNING: conv_coopmat)";
  return device_unfit(caps, g.frag, g.lanes, t.subgroups(), conv_coopmat_shared_bytes(g), twin, "conv_coopmat");
}

// head_dim steps: Q·Kᵀ reads D in fragment K steps, P·V writes it in fragment N columns, each of a row's lanes
// keeps D / lanes-per-row columns of O as vec4.
int64_t head_dim_step(const CoopmatAttention& a) {
  const int64_t lanes_per_row = std::max<int64_t>(1, a.lanes / int64_t(a.frag.m));
  return std::lcm(std::lcm(int64_t(a.frag.k), int64_t(a.frag.n)), 4 * lanes_per_row);
}

std::string attention_coopmat_head_dim_unfit(const CoopmatAttention& a, int64_t D) {
  const int64_t step = head_dim_step(a);
  // The P·V tile reuses the scores' shared memory: D at most the keys per tile.
  if (D % step || D > a.block_k)
    return "head_dim " + std::to_string(D) + ": the tensor-core kernel takes multiples of " + std::to_string(step) +
           " up to " + std::to_string(a.block_k) + " (fragments " + shape_text(a.frag) + ", " + std::to_string(a.lanes) +
           " lanes, " + std::to_string(a.block_k) + "-key tiles)";
  return "";
}

std::string attention_coopmat_unfit(const vk::DeviceCaps& caps, const CoopmatAttention& a, int64_t D,
                                    AttentionKernel kernel) {
  const bool twin = kernel == AttentionKernel::twin;
  if (!a.frag.defined() || !power_of_two(a.lanes) || a.subgroups < 1 || a.block_k < 1)
    return "layout " + a.describe() +
           " is incomplete (DVS_TUNING: attention_coopmat_subgroups, attention_block_k, coopmat, coopmat_lanes)";
  // The softmax: lanes per row (lanes > rows) or rows per lane, each lane an equal share of the row's keys.
  const int64_t rows = a.frag.m, lanes_per_row = std::max<int64_t>(1, a.lanes / rows);
  if ((a.lanes % rows && rows % a.lanes) || a.block_k % a.frag.n || a.block_k % a.frag.k ||
      a.block_k % lanes_per_row)
    return "layout " + a.describe() + " does not divide: lanes and fragment rows one a multiple of the other, " +
           "keys per tile a multiple of the fragment's N and K and of the lanes per row " +
           "(DVS_TUNING: attention_block_k, attention_coopmat_subgroups)";
  if (D == 0) {  // the largest head_dim the layout takes
    const int64_t step = head_dim_step(a);
    D = std::max<int64_t>(a.block_k / step * step, step);
  }
  if (const std::string why = attention_coopmat_head_dim_unfit(a, D); !why.empty()) return why;
  return device_unfit(caps, a.frag, a.lanes, a.subgroups,
                      attention_coopmat_shared_bytes(a, D, kernel), twin,
                      "attention_coopmat_subgroups, attention_block_k");
}

std::vector<uint32_t> linear_coopmat_spec(const CoopmatGemm& g, uint32_t weight_code, bool vector_loads,
                                          uint32_t group_m, uint32_t ablation, uint32_t x_code, bool y_f16) {
  const CoopmatTile& t = g.tile;
  return {uint32_t(t.sg_m), uint32_t(t.sg_n), weight_code, uint32_t(t.k), g.frag.k, uint32_t(t.frags_m),
          uint32_t(t.frags_n), g.frag.m, g.frag.n, g.invocations(), vector_loads ? 1u : 0u, group_m, ablation,
          x_code, y_f16 ? 1u : 0u};
}

std::vector<uint32_t> conv_coopmat_spec(const CoopmatGemm& g, uint32_t weight_code, int stages, bool x_f16,
                                        uint32_t bias_code, bool vec8) {
  const CoopmatTile& t = g.tile;
  return {weight_code, uint32_t(t.sg_m), uint32_t(t.sg_n), uint32_t(t.frags_m), uint32_t(t.frags_n), uint32_t(t.k),
          g.frag.m,    g.frag.n,         g.frag.k,         g.invocations(),    uint32_t(g.lanes),  uint32_t(stages),
          x_f16 ? 1u : 0u, bias_code == UINT32_MAX ? weight_code : bias_code, vec8 ? 1u : 0u};
}

std::string linear_coopmat2_unfit(const vk::DeviceCaps& caps, const DeviceTuning::Coopmat2Tile& t) {
  const std::string tile = std::to_string(t.m) + "x" + std::to_string(t.n) + "x" + std::to_string(t.k) + "x" +
                           std::to_string(t.invocations);
  if (!caps.cooperative_matrix2_gemm || !caps.cooperative_matrix2_facts)
    return "the device lacks VK_NV_cooperative_matrix2's workgroup scope, flexible dimensions and tensor addressing";
  const vk::CooperativeMatrix2Facts& f = *caps.cooperative_matrix2_facts;
  if (uint32_t(t.invocations) > f.workgroup_scope_max_workgroup_size ||
      uint32_t(std::max({t.m, t.n, t.k})) > f.flexible_dimensions_max_dimension)
    return "tile " + tile + " exceeds the workgroup scope's " + std::to_string(f.workgroup_scope_max_workgroup_size) +
           " invocations or its dimensions' " + std::to_string(f.flexible_dimensions_max_dimension) +
           " (DVS_TUNING: linear_coopmat2_tile)";
  for (const vk::CooperativeMatrixFlexibleShape& s : f.flexible_shapes)
    if (s.scope == VK_SCOPE_WORKGROUP_KHR && s.workgroup_invocations == uint32_t(t.invocations) &&
        s.a == VK_COMPONENT_TYPE_FLOAT16_KHR && s.b == VK_COMPONENT_TYPE_FLOAT16_KHR &&
        s.c == VK_COMPONENT_TYPE_FLOAT32_KHR && s.result == VK_COMPONENT_TYPE_FLOAT32_KHR && !s.saturating &&
        s.m_granularity && s.n_granularity && s.k_granularity && t.m % s.m_granularity == 0 &&
        t.n % s.n_granularity == 0 && t.k % s.k_granularity == 0)
      return "";
  return "tile " + tile + " matches none of the device's workgroup-scope fp16 x fp16 + fp32 shapes (their " +
         "invocations and granularities: dvs info) (DVS_TUNING: linear_coopmat2_tile)";
}

bool conv_coopmat_vec8_fits(const CoopmatGemm& g, int64_t cp, uint32_t weight_code, int64_t kh, int64_t kw, bool x_f16) {
  // The map: invocation i loads vector i % (K / 8) of rows i / (K / 8) + (invocations / (K / 8))·j, whole passes
  // over both tiles' rows.
  const int64_t k = g.tile.k, vectors = k / 8, rows = vectors ? g.invocations() / vectors : 0;
  return x_f16 && weight_code != 0 && k % 8 == 0 && cp % k == 0 && g.invocations() % vectors == 0 &&
         g.tile_m() % rows == 0 && g.tile_n() % rows == 0 && kh <= 16 && kw <= 16;
}

std::vector<uint32_t> attention_coopmat_spec(const CoopmatAttention& a, int64_t D, bool out_f16, bool kv_f16,
                                             bool q_f16) {
  return {uint32_t(D),       uint32_t(a.block_k), uint32_t(a.subgroups), a.frag.m,         a.frag.n, a.frag.k,
          uint32_t(a.lanes), a.invocations(),     out_f16 ? 1u : 0u,     kv_f16 ? 1u : 0u, q_f16 ? 1u : 0u};
}

const vk::Pipeline& coopmat_pipeline(vk::Context& ctx, const std::string& shader, std::span<const uint32_t> spec,
                                     uint32_t lanes, const std::string& unfit) {
  if (!unfit.empty()) throw Error(shader + ": " + unfit);
  return ctx.pipelines().get(shader, spec, lanes);
}

}  // namespace dvs::ops
