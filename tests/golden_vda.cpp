// Video-Depth-Anything against the vda conformance pack (DVS_VDA_GOLDEN_DIR, default tests/golden/vda-A):
// position-embedding resampling per grid, and one window forward compared stage by stage (every intermediate the
// model exposes under the pack's file name), with each case's tolerance from cases.json. Sizes, file names and
// layouts come from the pack, so another pack of the same format runs unchanged.
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>

#include "io/npy.hpp"
#include "models/vda_model.hpp"
#include "models/vda_pos_embed.hpp"
#include "support/golden_compare.hpp"
#include "support/gpu.hpp"
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

// A pack tensor laid out B,C,T,H,W as the engine's frames-in-the-batch [B*T, C, H, W].
HostTensor frames_in_batch(const HostTensor& g) {
  const int64_t b = g.shape[0], c = g.shape[1], t = g.shape[2], hw = g.shape[3] * g.shape[4];
  HostTensor out({b * t, c, g.shape[3], g.shape[4]}, DType::f32);
  const float* s = g.as<float>();
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
    HostTensor golden = read_npy(vda_golden_path() / f.file);
    if (f.layout == "B,C,T,H,W") golden = frames_in_batch(golden);
    test::expect_close(stem, it->second, golden, f.atol, f.rtol);
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

}  // namespace
}  // namespace dvs
