// A program that calls only dvs::read_video_frames (issue 34 §2.12): linked as an application without CMake links it
// (pkg-config dvs-video, an rpath to the prefix's library folder, --as-needed), it needs libdvs_video.so.0 alone, so
// libdvs.so.0 must be found through libdvs_video's own RUNPATH ($ORIGIN). Catches std::exception only (a catch of
// dvs::Error would make the program need libdvs itself). Prints "<count> frames of <H>x<W>"; exit status 0 = read.
#include <dvs/video.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s VIDEO\n", argv[0]);
    return 2;
  }
  try {
    const dvs::VideoFrames v = dvs::read_video_frames(argv[1], 0, 5, 48, 64);
    std::printf("%d frames of %dx%d\n", v.count, v.height, v.width);
    return v.count == 5 && v.rgb.size() == size_t(5) * 48 * 64 * 3 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
    return 1;
  }
}
