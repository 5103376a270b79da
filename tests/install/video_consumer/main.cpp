// Reads the video file argv[1] through the public API (dvs::preflight_render opens and decodes it, and notes its
// frame count and size). Built twice (CMakeLists.txt): with the video component it must report the video's
// "<frames> frames of <H>x<W>" given as argv[2]; with the core library alone it must name the missing component.
#include <dvs/preflight.hpp>
#include <dvs/render.hpp>
#if CONSUMER_LINKS_VIDEO
#include <dvs/video.hpp>
#endif

#include <cstdio>
#include <filesystem>
#include <string>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s VIDEO EXPECTED_NOTE\n", argv[0]);
    return 2;
  }
#if CONSUMER_LINKS_VIDEO
  dvs::enable_video_files();
#endif
  dvs::RenderJob job;
  job.video = argv[1];
  job.depth = argv[1];  // any existing file: only the video's checks matter here
  job.out_dir = std::filesystem::path(argv[1]).parent_path() / "render";
  job.frames = 0;
  const dvs::PreflightReport report = dvs::preflight_render(job);
  std::string all;
  for (const std::string& n : report.notes) all += "note: " + n + "\n";
  for (const std::string& p : report.problems) all += "problem: " + p + "\n";
  std::printf("%s", all.c_str());
  const std::string expected = argv[2];
  if (all.find(expected) == std::string::npos) {
    std::fprintf(stderr, "%s: expected '%s' in the report\n", argv[0], expected.c_str());
    return 1;
  }
  return 0;
}
