#include "model_depth.hpp"

#include <iostream>
#include <stdexcept>
#include <vector>

#include "dvs/depth_file.hpp"
#include "dvs/depth_frames.hpp"
#ifdef DVS_PREVIEW_VIDEO
#include "dvs/video.hpp"
#endif

namespace preview {

void estimate_model_depth(const PreviewOptions& o, dvs::Context& ctx, Inputs& in) {
#ifdef DVS_PREVIEW_VIDEO
  // The clip's first --frames frames as dvs render feeds its estimate (file size, long side ≤ 1280): the
  // disparity is normalised over all of them, so frame k's depth depends on the whole clip, as in dvs render.
  const dvs::VideoFrames v = dvs::read_video_frames_for_depth(o.video, o.frames);
  dvs::DepthModelOptions mo;
  mo.input_size = o.depth_input_size;
  dvs::DepthEstimator estimator(ctx, o.depth_model, mo);
  std::vector<float> clip(size_t(v.count) * size_t(v.height) * size_t(v.width));
  const dvs::HostView frames{const_cast<uint8_t*>(v.rgb.data()), dvs::ElementType::u8, {v.count, v.height, v.width, 3}};
  const dvs::HostView out{clip.data(), dvs::ElementType::f32, {v.count, v.height, v.width}};
  std::cout << "dvs-preview: estimating the depth of " << v.count << " frame(s) at " << v.height << "x" << v.width
            << " with " << o.depth_model << std::endl;
  estimator.estimate(frames, out, [](const std::string& stage, int step, int total, const std::string& note) {
    std::cout << "dvs-preview: " << stage;
    if (total > 0) std::cout << " " << step << "/" << total;
    if (!note.empty()) std::cout << " " << note;
    std::cout << std::endl;
  });

  dvs::DepthFileOptions d;
  d.metric_depth = estimator.metric();  // metric checkpoints give depth, the others disparity (as dvs render)
  d.source_height = v.source_height;
  d.source_width = v.source_width;
  d.squash = o.squash;
  d.depth_fit = o.depth_fit;
  in.depth = dvs::load_depth_frame(out, o.frame_index, o.height, o.width, d).depth;
  in.depth_is_disparity = false;  // converted over the whole clip to metric depth
  in.depth_view = {in.depth.data(), dvs::ElementType::f32, {o.height, o.width}};
#else
  (void)ctx, (void)in;
  throw std::runtime_error("--depth-model " + o.depth_model + ": this dvs-preview was built against a dvs without its "
                           "video component (it decodes the clip): rebuild dvs with -DDVS_VIDEO_IO=ON, or give --depth");
#endif
}

}  // namespace preview
