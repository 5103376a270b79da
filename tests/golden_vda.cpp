// Video-Depth-Anything against the vda conformance pack (DVS_VDA_GOLDEN_DIR, default tests/golden/vda-A): the
// input size rule, the preprocessing, position-embedding resampling per grid, one window forward compared stage by
// stage (every intermediate the model exposes under the pack's file name) and the whole clip (windows, alignment,
// blending; relative and metric), with each case's tolerance from cases.json. Sizes, file names and
// layouts come from the pack, so another pack of the same format runs unchanged.
#include <gtest/gtest.h>

#ifndef DVS_VIDEO_IO
#define DVS_VIDEO_IO 1  // tests/CMakeLists.txt defines it as 0 for this file in a DVS_VIDEO_IO=OFF build
#endif
// The preprocessing is OpenCV's cubic resize, absent without video I/O.
#define DVS_SKIP_WITHOUT_VIDEO_IO() \
  if (!DVS_VIDEO_IO) GTEST_SKIP() << "built without video I/O (DVS_VIDEO_IO=OFF): no OpenCV resize"

#include <map>
#include <optional>
#include <set>
#include <string>

#include "io/npy.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_pos_embed.hpp"
#include "models/vda/vda_preprocess.hpp"
#include "models/vda/vda_video.hpp"
#include "support/golden_compare.hpp"
#include "support/gpu.hpp"
#include "support/precision_rule.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

using test::vda_golden_path;

struct PackFile {
  std::string file, layout, role;
  double atol = 0, rtol = 0;
};

// Every file of the named cases, with its case's tolerance; keyed by the file's stem ("encoder/block0").
std::map<std::string, PackFile> pack_files(std::initializer_list<const char*> cases) {
  std::map<std::string, PackFile> out;
  for (const char* name : cases) {
    const auto& c = test::vda_case(name);
    for (const auto& f : c.at("files")) {
      PackFile p{f.at("file"), f.value("layout", ""), f.value("role", ""), c.at("tolerance").at("atol"),
                 c.at("tolerance").at("rtol")};
      std::string stem = p.file.substr(0, p.file.size() - 4);  // drop ".npy"
      if (!out.count(stem)) out[stem] = p;
    }
  }
  return out;
}

// A pack tensor laid out B,C,T,H,W (float32, or float16 as the bf16 runs are stored) as the engine's
// frames-in-the-batch [B*T, C, H, W], float32.
HostTensor frames_in_batch(const HostTensor& g) {
  const int64_t b = g.shape[0], c = g.shape[1], t = g.shape[2], hw = g.shape[3] * g.shape[4];
  HostTensor out({b * t, c, g.shape[3], g.shape[4]}, DType::f32);
  const std::vector<float> values = g.to_f32();
  const float* s = values.data();
  float* d = out.as<float>();
  for (int64_t bi = 0; bi < b; ++bi)
    for (int64_t ci = 0; ci < c; ++ci)
      for (int64_t ti = 0; ti < t; ++ti)
        std::copy(s + ((bi * c + ci) * t + ti) * hw, s + ((bi * c + ci) * t + ti + 1) * hw, d + ((bi * t + ti) * c + ci) * hw);
  return out;
}

TEST(VdaGolden, PositionEmbeddingResampledPerGrid) {
  const HostTensor table = read_npy(vda_golden_path() / "pos_embed" / "param.npy");
  const auto& c = test::vda_case("pos_embed");
  int compared = 0;
  for (const auto& f : c.at("files")) {
    if (f.value("role", "") != "output") continue;
    const HostTensor golden = read_npy(vda_golden_path() / f.at("file").get<std::string>());
    // "pos_embed/grid_HxW.npy": the patch grid from the name, checked against the row count.
    const std::string file = f.at("file");
    const auto at = file.find("grid_") + 5, x = file.find('x', at);
    const int64_t h = std::stoll(file.substr(at, x - at)), w = std::stoll(file.substr(x + 1));
    ASSERT_EQ(golden.shape[1], 1 + h * w) << file;
    const HostTensor ours = vda_resample_pos_embed(table, h, w);
    test::expect_close_values(file, ours.shape, ours.to_f32(), golden.shape, golden.to_f32(), c.at("tolerance").at("atol"),
                              c.at("tolerance").at("rtol"));
    ++compared;
  }
  EXPECT_GT(compared, 0) << "the pack's pos_embed case lists no output grid";
}

class VdaWindow : public test::GpuTest {};

TEST_F(VdaWindow, ForwardMatchesThePackStageByStage) {
  VdaModel model = VdaModel::load(ctx(), test::vda_checkpoint_path());
  const auto files = pack_files({"encoder", "temporal_modules", "dpt_head", "window_forward"});
  std::map<std::string, HostTensor> got;
  model.set_probe([&](const std::string& name, const Tensor& t) { got[name] = t.download(ctx()); });
  HostTensor input = read_npy(vda_golden_path() / files.at("window/input").file);  // [B, T, 3, H, W]
  input.shape = test::without_batch(input.shape);
  Tensor depth = model.forward(Tensor::upload(ctx(), input));
  got["window/depth"] = depth.download(ctx());

  std::set<std::string> compared;
  for (const auto& [stem, f] : files) {
    if (f.role == "input") continue;
    const auto it = got.find(stem);
    if (it == got.end()) continue;
    // The golden and PyTorch's bf16 run of it (when the pack has one), in the engine's layout.
    test::PackGolden g = test::read_pack_golden(vda_golden_path(), f.file);
    if (f.layout == "B,C,T,H,W") {
      g.golden = frames_in_batch(g.golden);
      if (g.bf16) g.bf16 = frames_in_batch(*g.bf16);
    }
    std::optional<std::vector<float>> bf16;
    if (g.bf16) {
      bf16 = g.bf16->to_f32();
      // The bf16 run as compared still has the error the pack records for it: the layout change moved both
      // tensors alike and read the bf16 file in its own storage (float16 or float32).
      const auto& rec = test::vda_cases().at("torch_bf16").at("files").at(f.file);
      const test::ErrorMeasure m = test::error_measure(*bf16, g.golden.to_f32());
      const double max_abs = rec.at("max_abs"), rel_l2 = rec.at("rel_l2");
      EXPECT_NEAR(m.max_abs, max_abs, 1e-6 * max_abs) << stem;
      EXPECT_NEAR(m.rel_l2, rel_l2, 1e-6 * rel_l2) << stem;
    }
    test::expect_golden_values(stem, it->second.shape, it->second.to_f32(), g.golden.shape, g.golden.to_f32(), bf16,
                               g.bf16_path.string(), f.atol, f.rtol, test::kAllKernelOps);
    compared.insert(stem);
  }
  // The stages that must have been checked whatever else the model exposes: every tap, every temporal module's
  // output, the head's output and the window's disparity.
  std::vector<std::string> required = {"window/depth", "head/output"};
  for (int i = 0; i < 4; ++i) required.push_back("encoder/tap" + std::to_string(i));
  for (int j = 0; j < 4; ++j) required.push_back("temporal/m" + std::to_string(j) + "_out");
  for (const auto& r : required) EXPECT_TRUE(compared.count(r)) << r << " was not compared";
  std::printf("  compared %zu of the pack's %zu tensors for these cases\n", compared.size(), files.size());
}

// The clip of the preprocess / e2e cases as the u8 RGB frames the driver takes.
HostTensor pack_clip() {
  const HostTensor f = read_npy(vda_golden_path() / "preprocess" / "frames_uint8.npy");
  HostTensor u8(f.shape, DType::u8);
  const std::vector<float> v = f.to_f32();
  for (size_t i = 0; i < v.size(); ++i) u8.as<uint8_t>()[i] = uint8_t(v[i]);
  return u8;
}

TEST(VdaGolden, InputSizeRuleForEveryRecordedFrameSize) {
  const auto table = test::vda_read_json(vda_golden_path() / "preprocess" / "size_rule.json");
  ASSERT_FALSE(table.empty());
  const int patch = test::vda_model_config().at("encoder").at("patch_size");
  for (const auto& e : table) {
    const VdaInputSize s = vda_input_size(e.at("frame_height"), e.at("frame_width"), e.at("input_size"), patch);
    EXPECT_EQ(s.height, e.at("model_height").get<int64_t>()) << e.dump();
    EXPECT_EQ(s.width, e.at("model_width").get<int64_t>()) << e.dump();
  }
}

TEST(VdaGolden, PreprocessingOfEveryFrame) {
  DVS_SKIP_WITHOUT_VIDEO_IO();
  const auto& c = test::vda_case("preprocess");
  const HostTensor clip = pack_clip();
  const HostTensor golden = read_npy(vda_golden_path() / "preprocess" / "normalised.npy");  // [L, 3, h, w]
  const int64_t L = clip.shape[0], H = clip.shape[1], W = clip.shape[2];
  const VdaConfig cfg = vda_config_from_json(test::vda_model_config(), "pack config");
  const VdaInputSize size = vda_input_size(H, W, c.at("input_size_argument"), cfg.patch_size);
  ASSERT_EQ(size.height, golden.shape[2]);
  ASSERT_EQ(size.width, golden.shape[3]);
  HostTensor ours({L, 3, size.height, size.width}, DType::f32);
  for (int64_t f = 0; f < L; ++f)
    vda_preprocess_frame(clip.as<uint8_t>() + f * H * W * 3, H, W, size, cfg, ours.as<float>() + f * 3 * size.height * size.width);
  test::expect_close("preprocess/normalised", ours, golden, c.at("tolerance").at("atol"), c.at("tolerance").at("rtol"));
}

// The whole clip through the production driver: window frame indices (exact), each window's forward and its
// upsampling, the scale/shift of each later window, and the stitched clip; then the metric mode's clip.
class VdaVideo : public test::GpuTest {};

TEST_F(VdaVideo, WholeClipMatchesThePackRelativeAndMetric) {
  DVS_SKIP_WITHOUT_VIDEO_IO();
  const auto& c = test::vda_case("e2e");
  const double atol = c.at("tolerance").at("atol"), rtol = c.at("tolerance").at("rtol");
  VdaModel model = VdaModel::load(ctx(), test::vda_checkpoint_path());
  model.set_micro_batch(3);                // chunks that do not divide the window: the chunking must not matter
  model.set_temporal_chunk_positions(5);   // nor the temporal modules' chunks of positions
  model.set_encoder_chunk_frames(7);       // nor the encoder's chunks of frames
  const HostTensor clip = pack_clip();
  const HostTensor indices = read_npy(vda_golden_path() / "e2e" / "window_frame_indices.npy");
  const test::PackGolden windows = test::read_pack_golden(vda_golden_path(), "e2e/window_depth.npy");
  const test::PackGolden upsampled = test::read_pack_golden(vda_golden_path(), "e2e/window_depth_upsampled.npy");
  VdaVideoOptions o;
  o.input_size = c.at("input_size");
  int probed = 0;
  o.probe = [&](int k, const std::vector<int64_t>& frames, const HostTensor& model_size, const HostTensor& frame_size) {
    ASSERT_LT(k, indices.shape[0]);
    ASSERT_EQ(int64_t(frames.size()), indices.shape[1]);
    const auto idx = indices.to_f32();
    for (size_t i = 0; i < frames.size(); ++i)
      EXPECT_EQ(frames[i], int64_t(idx[size_t(k) * frames.size() + i])) << "window " << k << " position " << i;
    const std::string w = "window " + std::to_string(k);
    // Window k of a [windows, ...] pack file and of its bf16 run (when the pack has one).
    auto expect_window = [&](const std::string& what, const HostTensor& ours, const test::PackGolden& all) {
      const int64_t per = all.golden.numel() / all.golden.shape[0];
      auto slice = [&](const HostTensor& t) {
        const auto v = t.to_f32();
        return std::vector<float>(v.begin() + k * per, v.begin() + (k + 1) * per);
      };
      std::optional<std::vector<float>> bf16;
      if (all.bf16) bf16 = slice(*all.bf16);
      test::expect_golden_values(what, ours.shape, ours.to_f32(), Shape(all.golden.shape.begin() + 1, all.golden.shape.end()),
                                 slice(all.golden), bf16, all.bf16_path.string(), atol, rtol, test::kAllKernelOps);
    };
    expect_window(w + " depth", model_size, windows);
    expect_window(w + " upsampled", frame_size, upsampled);
    ++probed;
  };
  int progress = 0;
  o.on_window = [&](int done, int total) {
    EXPECT_EQ(done, ++progress);
    EXPECT_EQ(total, indices.shape[0]);
  };
  const VdaVideoResult r = vda_video_depth(model, clip, o);
  EXPECT_EQ(probed, indices.shape[0]);
  std::vector<float> ours_st;
  for (const auto& p : r.scale_shift) ours_st.insert(ours_st.end(), p.begin(), p.end());
  test::expect_golden_file("e2e/align_scale_shift", {int64_t(r.scale_shift.size()), 2}, ours_st, vda_golden_path(),
                           "e2e/align_scale_shift.npy", atol, rtol, test::kAllKernelOps);
  test::expect_golden_file("e2e/depth", r.depth.shape, r.depth.to_f32(), vda_golden_path(), "e2e/depth.npy", atol, rtol,
                           test::kAllKernelOps);

  const auto& m = test::vda_case("e2e_metric");
  model.set_metric(true);
  o.probe = nullptr;
  progress = 0;
  const VdaVideoResult metric = vda_video_depth(model, clip, o);
  EXPECT_TRUE(metric.scale_shift.size() == r.scale_shift.size());
  for (const auto& p : metric.scale_shift) EXPECT_TRUE(p[0] == 1.0f && p[1] == 0.0f);
  test::expect_golden_file("e2e/depth_metric_mode", metric.depth.shape, metric.depth.to_f32(), vda_golden_path(),
                           "e2e/depth_metric_mode.npy", m.at("tolerance").at("atol"), m.at("tolerance").at("rtol"),
                           test::kAllKernelOps);
}

}  // namespace
}  // namespace dvs
