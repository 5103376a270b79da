// Where run, invert, render and batch take the clip's depth from: --depth FILE, or --depth-model FILE.pth (with
// --depth-input-size N) to estimate it with Video-Depth-Anything. Exactly one of them.
#pragma once
#include "args.hpp"
#include "dvs/render.hpp"

namespace dvs::cli {

void parse_depth_source(const Args& a, RenderJob& job);

// A Video-Depth-Anything network input size (--input-size, --depth-input-size): in [14, 4096] and a multiple of
// 14, the ViT's patch (the model would round any other value to one silently).
int depth_input_size(const Args& a, const std::string& option, int fallback);

}  // namespace dvs::cli
