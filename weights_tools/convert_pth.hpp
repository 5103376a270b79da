// `dvs-weights inspect FILE.pth` and `dvs-weights convert IN.pth OUT.safetensors`: PyTorch checkpoints
// (io/pth_file.hpp) listed like safetensors files, and rewritten as safetensors with the same tensor names,
// dtypes, shapes and bytes (strided tensors made contiguous), in the checkpoint's tensor order.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

namespace dvs::weights_tools {

// Prints every tensor (name, dtype, shape, bytes), totals and the Video-Depth-Anything architecture when the
// tensors are one (config.json beside the file, or a released size). Returns the exit status.
int inspect_pth(const std::filesystem::path& file, bool summary);

// Writes `out` (via a temporary name); throws dvs::Error naming the file or tensor at fault.
void convert_pth_to_safetensors(const std::filesystem::path& in, const std::filesystem::path& out);

// The command: parses argv (after "convert"), returns the exit status (0 ok, 1 error, 2 usage).
int convert_command(const std::vector<std::string>& args);

}  // namespace dvs::weights_tools
