// Opt-in measurement (DVS_MEASURE_VDA=1): one Video-Depth-Anything window of a random-weight released size
// (DVS_MEASURE_VDA_SIZE, default vits) at a network input (DVS_MEASURE_VDA_INPUT=HxW, default 518x784) for
// DVS_MEASURE_VDA_FRAMES frames (default 4): wall and process CPU seconds of the encoder and of the head, so a
// slow stage is found without a profiler. Prints only; skipped in the default run.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdlib>

#include "io/safetensors_writer.hpp"
#include "models/vda/vda_model.hpp"
#include "models/random/vda_random.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"

namespace dvs {
namespace {

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

class VdaMeasure : public test::GpuTest {};

TEST_F(VdaMeasure, WindowStageTimes) {
  if (!std::getenv("DVS_MEASURE_VDA")) GTEST_SKIP() << "set DVS_MEASURE_VDA=1 to measure";
  const char* size_env = std::getenv("DVS_MEASURE_VDA_SIZE");
  const std::string size = size_env ? size_env : "vits";
  int64_t H = 518, W = 784, T = 4;
  if (const char* e = std::getenv("DVS_MEASURE_VDA_INPUT")) std::sscanf(e, "%ldx%ld", &H, &W);
  if (const char* e = std::getenv("DVS_MEASURE_VDA_FRAMES")) T = std::atol(e);
  test::TempDir dir;
  const auto file = dir / ("video_depth_anything_" + size + ".safetensors");
  write_safetensors(file, vda_random_checkpoint(released_vda_config(size), 0));
  VdaModel model = VdaModel::load(ctx(), file);
  HostTensor x({T, 3, H, W}, DType::f32);
  for (int64_t i = 0; i < x.numel(); ++i) x.as<float>()[i] = float((i * 7919) % 1000) / 500.0f - 1.0f;
  const Tensor input = Tensor::upload(ctx(), x);
  auto t0 = std::chrono::steady_clock::now();
  double c0 = cpu_seconds();
  auto taps = model.encode(input);
  const double enc_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double enc_cpu = cpu_seconds() - c0;
  t0 = std::chrono::steady_clock::now();
  c0 = cpu_seconds();
  const Tensor out = model.head(std::move(taps), H / 14, W / 14, T);
  out.download(ctx());
  const double head_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double head_cpu = cpu_seconds() - c0;
  std::printf("  %s, %ld frames at %ldx%ld: encoder %.1f s (%.1f CPU-s), head %.1f s (%.1f CPU-s)\n", size.c_str(),
              long(T), long(H), long(W), enc_wall, enc_cpu, head_wall, head_cpu);
}

}  // namespace
}  // namespace dvs
