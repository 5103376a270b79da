// The random-weight Video-Depth-Anything checkpoints dvs-weights make-vda writes: the schema names and shapes
// every tensor the conformance pack's checkpoint holds (for its config), and each released size's schema is
// recognised as that size, so measurements at the real size run the real architecture.
#include <gtest/gtest.h>

#include <map>

#include "io/safetensors.hpp"
#include "spec/vda_config.hpp"
#include "models/random/vda_random.hpp"
#include "support/files.hpp"
#include "support/process.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

TEST(VdaRandomCheckpoint, SchemaIsThePackCheckpointsTensorList) {
  const VdaConfig cfg = vda_config_from_json(test::vda_model_config(), "pack config");
  std::map<std::string, Shape> ours;
  for (const auto& [name, shape] : vda_checkpoint_schema(cfg)) EXPECT_TRUE(ours.emplace(name, shape).second) << name;
  std::map<std::string, Shape> pack;
  for (const auto& k : test::vda_cases().at("checkpoint").at("keys")) pack[k.at(0)] = k.at(1).get<Shape>();
  EXPECT_EQ(ours, pack);
}

TEST(VdaRandomCheckpoint, ReleasedSizesAreRecognisedAsThemselves) {
  for (const char* size : {"vits", "vitb", "vitl"}) {
    std::map<std::string, Shape> shapes;
    for (const auto& [name, shape] : vda_checkpoint_schema(released_vda_config(size))) shapes[name] = shape;
    const VdaConfig c = recognise_vda_size(shapes, "video_depth_anything_x.pth");
    EXPECT_EQ(c.name, size);
    EXPECT_FALSE(c.metric);
    EXPECT_TRUE(recognise_vda_size(shapes, "metric_video_depth_anything_x.pth").metric);
  }
}

TEST(VdaRandomCheckpoint, MakeVdaWritesTheSchemaWithValues) {
  test::TempDir dir;
  const auto file = dir / "vits.safetensors";
  auto r = test::run_command(test::program("dvs-weights") + " make-vda --size vits --seed 3 --out " + file.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const SafetensorsFile f = SafetensorsFile::open(file);
  const auto schema = vda_checkpoint_schema(released_vda_config("vits"));
  ASSERT_EQ(f.tensors().size(), schema.size());
  const auto ls = f.load(f.tensors().front());
  EXPECT_GT(ls.numel(), 0);
  auto bad = test::run_command(test::program("dvs-weights") + " make-vda --size vitx --out " + file.string());
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
}

}  // namespace
}  // namespace dvs
