// --depth-model: the clip's depth estimated in the preview itself (dvs::DepthEstimator on dvs's context), then
// frame --frame-index converted and mapped exactly as `dvs render --depth-model` does for the same frames.
#pragma once
#include "dvs/context.hpp"
#include "preview_inputs.hpp"
#include "preview_options.hpp"

namespace preview {

// Fills in.depth / in.depth_view (metric depth at --size). Throws dvs::Error / std::runtime_error naming the file.
void estimate_model_depth(const PreviewOptions& o, dvs::Context& ctx, Inputs& in);

}  // namespace preview
