// The device-tuning seam: every device-dependent choice of the ops (kernel variant, tiles, lanes, rows per
// invocation, texel or storage inputs, chunk sizes, cooperative-matrix shapes) lives in one table
// (kernel_tuning.cpp), keyed by what the device reports (type, vendor, subgroup size, shared memory,
// cooperative-matrix properties). Op files ask `device_tuning(caps)` and hold no device-type, vendor or
// subgroup-size checks of their own.
//
// One override mechanism for A/B runs: the environment variable DVS_TUNING picks an entry and/or fields,
//   DVS_TUNING=gpu                                  the "gpu" entry on any device (e.g. forced on lavapipe)
//   DVS_TUNING=linear=tiled,attention=flash         fields of the entry the device would get
//   DVS_TUNING=gpu,coopmat=off                      an entry, then fields
//   DVS_TUNING=gpu-coopmat,coopmat=16x16x16         tensor cores with a forced shape (a GPU's fragment on
//                                                   lavapipe, which lists only 8x8x8: tests/run_on_mesa_coopmat.sh)
// (tuning_field_names() lists the fields; a bad name or value is an error that lists them). Tests and
// benchmarks use ScopedTuningOverride, the same string in-process. `dvs info` prints the entry chosen.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "tensor/tensor.hpp"
#include "vk/device_info.hpp"

namespace dvs::ops {

// Register blocking of conv_gemm: a cluster of 8 lanes computes `rows` output pixels x 8*`cols` output
// channels; `sg_m` of the workgroup's 8 clusters lie along the pixels. `lanes`: 0 subgroups of exactly 8,
// 1 clusters of 8 inside wider subgroups, 2 no subgroup shuffles (every lane fetches every pixel).
// `k_unroll`: 8-channel steps per trip of the channel loop (at most; 1, 2 or 4, as the channels allow).
struct GemmTile {
  int rows = 8, cols = 3, sg_m = 2, lanes = 0, k_unroll = 1;
};

// Which kernel family an op records.
//   texel:   register-blocked kernels reading inputs through uniform texel buffers (shaped for CPU drivers,
//            where a texel fetch is ~3x cheaper than a storage load; what every device ran before GPUs)
//   tiled:   shared-memory tiles over storage buffers, fp32 FMA (what GPUs without tensor cores want)
//   coopmat: shared-memory tiles feeding VK_KHR_cooperative_matrix (fp16 operands, fp32 accumulation)
enum class KernelFamily : uint8_t { texel = 0, tiled = 1, coopmat = 2 };
const char* kernel_family_name(KernelFamily k);

// A cooperative-matrix shape the device offers at subgroup scope for fp16 A/B and fp32 C/result: the
// fragment of every tensor-core kernel (C is m x n, A m x k, B k x n).
struct CoopmatShape {
  uint32_t m = 0, n = 0, k = 0;
  bool defined() const { return m && n && k; }
};

// The workgroup layout of a GEMM-shaped tensor-core kernel (linalg/linear_coopmat, nn/conv_coopmat):
// sg_m x sg_n subgroups, each owning frags_m x frags_n fragments of the device's shape, over k reduction
// elements per shared-memory step. Workgroup tile: (sg_m·frags_m·shape.m) x (sg_n·frags_n·shape.n);
// sg_m·sg_n·lanes invocations (tensor/coopmat_layout.hpp checks it against the device). All 0: not chosen yet
// (select_tuning picks the first layout of the table the device holds).
struct CoopmatTile {
  int sg_m = 0, sg_n = 0, frags_m = 0, frags_n = 0, k = 0;
  bool defined() const { return sg_m && sg_n && frags_m && frags_n && k; }
  int subgroups() const { return sg_m * sg_n; }
};

// One row of the GEMM's per-shape tile table: calls with N >= min_n and M <= max_m (0: any; M the rows of one batch
// item) use `tile` instead of DeviceTuning::linear_coopmat. The first matching row wins.
struct LinearCoopmatRule {
  int64_t min_n = 0, max_m = 0;
  CoopmatTile tile;
};

struct DeviceTuning {
  std::string entry;  // table entry name ("cpu-simd", "gpu", "gpu-coopmat", ...)
  std::string overrides;  // the DVS_TUNING / ScopedTuningOverride string applied ("" when none)

  // Subgroup use of the GEMM-shaped texel kernels (GemmTile::lanes): a property of the device's subgroups.
  int gemm_lanes = 0;

  // linear (tensor/ops_linear.cpp)
  KernelFamily linear = KernelFamily::texel;
  bool linear_f32_weights_16x2 = true;  // texel family: 16x2 tile for f32 weights at M >= 64
  int linear_tile_m = 64, linear_tile_n = 64, linear_tile_k = 16;  // tiled / coopmat workgroup tile

  // attention (tensor/ops_attention.cpp)
  KernelFamily attention = KernelFamily::texel;
  bool attention_rows_by_head_dim = true;  // texel family: several query rows per invocation (CPU drivers)
  bool attention_kv_workspace = true;      // repack K/V head-major when the caller offers a workspace
  int attention_block_q = 64, attention_block_k = 64;  // tiled / coopmat: query rows x keys per tile
  // Tests: where the tiled kernel would run, run the coopmat kernel's fp32 twin instead
  // (attention_flash_coopmat_twin.comp; head_dim a multiple of 16, its tiles within shared memory).
  bool attention_coopmat_twin = false;

  // convolutions (tensor/ops_conv.cpp)
  KernelFamily conv = KernelFamily::texel;
  GemmTile conv_f32_weights, conv_16bit_weights;  // large convolutions (texel family)
  GemmTile conv_small;                            // fewer than 8 * rows output pixels per chunk
  int conv_pack_columns = 0;  // pixels of a row per invocation of the input repack (0: the whole row)
  // The input repack's neighbouring invocations take neighbouring pixels of one channel group, so a subgroup's reads
  // of each channel plane are contiguous (its writes, 8 or 16 bytes a pixel, are then strided); off: neighbouring
  // channel groups of one pixel (contiguous writes, each read from another plane). On for GPUs (reads are the larger
  // half: f32 in, fp16 out), unmeasured there (the device script's sweep compares); off on CPUs. Same bits.
  bool conv_pack_pixel_major = false;
  // The input repack as a transpose through shared memory (conv_pack_input_tiled.comp: 32 channels x 64 columns a
  // workgroup, read along the planes' rows, written along the pixels' channels: both sides contiguous), where a
  // dispatch owns whole vec4s of channels. Off everywhere until a GPU has timed it (the H200, 2026-11-29: the repack
  // 4.1 ms beside the convolution's 48.6, ten times its bytes at the memory's rate); same bits.
  bool conv_pack_tiled = false;
  // tiled family (shaders/nn/conv_tiled.comp): workgroup tile of pixels x output channels, each 32, 64 or
  // 128 (16 x 16 invocations, each a tile/16 x tile/16 register block). The coopmat family's: conv_coopmat.
  int conv_tile_m = 64, conv_tile_n = 64;

  // norms, reductions, elementwise
  bool norm_row_per_invocation = false;  // layernorm/rmsnorm: one invocation per row (else a workgroup)
  int64_t reduce_min_chunk = 1024;       // elements per first-level partial of a reduction, at least
  bool eltwise_texel_inputs = true;      // vec4 elementwise ops read inputs through texel buffers

  // tensor cores: the shape the coopmat kernels use (undefined: the device has none usable; then no
  // family above may be coopmat)
  CoopmatShape coopmat;
  // The tensor-core kernels' layouts (the same shader code on every device, specialised with these):
  // coopmat_lanes, the subgroup size they are laid out for (the device's; required at pipeline creation);
  // per kernel the workgroup layout (M = output rows / pixels, N = output columns / channels) and, for
  // attention, the subgroups of coopmat.m query rows each per workgroup (keys per tile: attention_block_k).
  int coopmat_lanes = 0;
  CoopmatTile linear_coopmat, conv_coopmat;
  // The GEMM's per-shape tile table, checked against the device like linear_coopmat (a row that does not fit is
  // an error naming it). Empty in every entry until a device run measures a better tile for some shapes (the
  // sweep times each tile at each of the transformer's shapes); DVS_TUNING sets it for A/B runs.
  std::vector<LinearCoopmatRule> linear_coopmat_by_shape;
  // linear_coopmat's feed: 16-byte global loads where K, strides and offsets are multiples of 8 elements
  // (off: one guarded element per load everywhere, for A/B runs), and its workgroup order, bands of this many
  // tile rows walked column by column so a W panel is reused from L2 (1: the grid's row-by-row order). Band 8:
  // Triton's default grouping, unmeasured on a GPU here (the device script's sweep compares 1 and 8).
  bool linear_coopmat_vector_loads = true;
  int linear_coopmat_group_m = 8;
  // The GEMM through VK_NV_cooperative_matrix2 (linalg/linear_coopmat2.comp: workgroup-scope matrices loaded with
  // tensor addressing, the driver's own shared-memory staging) where the device has its workgroup scope, flexible
  // dimensions and tensor addressing, X and W are fp16 and the tile fits the device's workgroup-scope shapes; the
  // KHR kernel elsewhere. Off until a device run has checked it by value and timed it (lavapipe cannot run it).
  bool linear_coopmat2 = false;
  // Its tile: output rows x columns x K per step, and the workgroup's invocations (which one of the device's
  // workgroup-scope shapes must name).
  struct Coopmat2Tile {
    int m = 128, n = 128, k = 32, invocations = 256;
  } linear_coopmat2_tile;
  std::string linear_coopmat2_unfit;  // why linear_coopmat2 cannot run on this device ("" where it can or is off)
  // Where the linear family is coopmat, GEMM weights a model stores in bf16 are kept on the device in fp16, the
  // operand type the tensor cores read: converted once at load (ComponentWeights::store_as) instead of per element
  // in every GEMM's loads. Off: kept bf16 and converted in the loads (A/B runs). Same bits either way.
  bool linear_weights_fp16 = true;
  // Where the linear family is coopmat, what the transformer's GEMMs alone read is written in fp16: the block
  // LayerNorms' output, the attention output (where a flash kernel runs the call: ops::attention_takes_f16) and the
  // FFN's GELU output (by the GEMM's epilogue), rounded once there instead of in every GEMM tile's loads, at half
  // the bytes; where the attention runs on tensor cores, its K and V are cast to fp16 once a block. Off: f32 (A/B
  // runs). Same bits.
  bool linear_activations_fp16 = true;
  // Measurements only, the results are then wrong (issue 35's ablations, dvs-bench in the device script): 1 the
  // 16-byte path loads no operand (constants staged instead), 2 no MMA. 0: none.
  int linear_coopmat_ablation = 0;
  // conv_coopmat's operand tiles in two shared-memory stages where they fit (the next step's gather in flight
  // during this step's products, one barrier a step); off: one stage. Unmeasured on a GPU (the sweep compares).
  bool conv_coopmat_double_buffer = true;
  // conv_coopmat gathers 8 channels (16 bytes) per load, with each pixel's taps worked out once (no division in the
  // loop), where its input is repacked fp16, the channels are a multiple of the tile's K, the weights are 16-bit and
  // the kernel at most 16 x 16 per frame (the VAE's convolutions on GPUs); off: 4 channels per load, each step's
  // taps found by division (A/B runs). Same bits.
  bool conv_coopmat_vector_loads = true;
  // The convolution through VK_NV_cooperative_matrix2 (nn/conv_coopmat2.comp: the gather by tensor addressing, the
  // padding by its clamp, the driver's own staging) where the device has what linear_coopmat2 needs, the stride is
  // 1, the input repack and the weights are fp16 and the channels a multiple of the tile's K; the KHR kernel
  // elsewhere. Off until a device run has checked it by value and timed it (lavapipe cannot run it).
  bool conv_coopmat2 = false;
  // A stride-1, same-size convolution (upsample2x_conv3x3's too) with weights packed at load and channels a
  // multiple of the GEMM tile's K, on the tensor-core family, as the tensor-core GEMM itself (nn/conv_shifted_coopmat,
  // a variant of linear_coopmat.comp: its tile, loads and order, linear_coopmat's layout): the input repacked fp16 on
  // its zero-padded grid, each step's X rows shifted by its tap's offset on the grid, so no gather, division or bounds
  // test is left in the loop (ops_conv_shifted.hpp). Same bits as conv_coopmat. Off until a device run has timed it
  // (the sweep compares).
  bool conv_shifted_gemm = false;
  // Its tile: a patch of output rows x columns, output channels, input channels per step, invocations.
  struct ConvCoopmat2Tile {
    int rows = 4, cols = 32, n = 128, k = 32, invocations = 256;
  } conv_coopmat2_tile;
  // Where the conv family is coopmat, each call's channels-last repack of its input (what only the GEMM reads) is
  // written in fp16, the tensor cores' operand type: rounded once there instead of in every tap's loads, at half the
  // bytes written and read. Off: f32 (A/B runs). Same bits.
  bool conv_activations_fp16 = true;
  // Where the conv family is coopmat, conv weights a model stores in bf16 are kept on the device in fp16, the operand
  // type the tensor cores read, converted once at load before they are packed (ops::conv_weight_dtype, models'
  // ComponentWeights::packed_conv) instead of per element in every tile's loads. Off: kept bf16 (A/B runs). Same bits.
  bool conv_weights_fp16 = true;
  int attention_coopmat_subgroups = 0;
  // The tensor-core attention keeps scores, P and O in the matrices (nn/attention_flash_coopmat2) where the
  // device has VK_NV_cooperative_matrix2's reductions, conversions and per-element operations and the fragment's
  // N equals its K; off: the KHR kernel, whose softmax goes through shared memory (A/B runs).
  bool attention_coopmat2 = true;
  // Where a coopmat family was asked for (by the entry or an override) but runs tiled on this device: why,
  // per op ("" where it was not asked or runs). Ops note it with every call they run (kernel_census.hpp).
  std::string linear_unfit, attention_unfit, conv_unfit;
};

// The tuning for a device: its table entry, then the DVS_TUNING environment variable, then the in-process
// override (ScopedTuningOverride). Cached per device and override string; cheap to call per op.
const DeviceTuning& device_tuning(const vk::DeviceCaps& caps);

// The same as a pure function of the device's properties and an override string (unit tests on faked
// property lists). Throws dvs::Error naming the field and the accepted values on a bad override.
DeviceTuning select_tuning(const vk::DeviceCaps& caps, const std::string& overrides);

// The fields DVS_TUNING may set, with their accepted values, one per line (for errors and `dvs info`).
std::string tuning_field_names();

// Human-readable report of a tuning (dvs info, dvs-bench).
std::string describe_tuning(const DeviceTuning& t);

// While alive, device_tuning() applies `overrides` after DVS_TUNING (tests and benchmarks: A/B a field or
// force an entry in-process). Not thread-safe; one at a time.
class ScopedTuningOverride {
 public:
  explicit ScopedTuningOverride(std::string overrides);
  ~ScopedTuningOverride();
  ScopedTuningOverride(const ScopedTuningOverride&) = delete;
  ScopedTuningOverride& operator=(const ScopedTuningOverride&) = delete;

 private:
  std::string previous_;
};

// The tile for a convolution with `outputs` output pixels, `out_channels` output channels and weights
// stored as `wdt` (texel family), from the device's tuning. `device_class` (optional) receives the entry.
GemmTile conv_tile(const vk::DeviceCaps& caps, DType wdt, int64_t outputs, int64_t out_channels,
                   std::string* device_class = nullptr);

// How the lanes of a cluster talk on this device (GemmTile::lanes).
int gemm_lanes(const vk::DeviceCaps& caps);

// Output pixels of one row that one invocation of the convolution's input repack writes; 0: the whole row.
int conv_pack_columns(const vk::DeviceCaps& caps);

}  // namespace dvs::ops
