// Where run, invert, render and batch take the clip's depth from: --depth FILE, or --depth-model FILE.pth (with
// --depth-input-size N) to estimate it with Video-Depth-Anything. Exactly one of them.
#pragma once
#include "args.hpp"
#include "dvs/render.hpp"

namespace dvs::cli {

void parse_depth_source(const Args& a, RenderJob& job);

}  // namespace dvs::cli
