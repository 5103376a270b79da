// Writes a NumPy .npz archive (a zip of NAME.npy members, deflated as np.savez_compressed does) through libzip,
// to a temporary name renamed when complete: an interrupted write never leaves a file that looks finished.
#pragma once
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "io/host_tensor.hpp"

namespace dvs {

void write_npz(const std::filesystem::path& path, const std::vector<std::pair<std::string, HostTensor>>& arrays);

}  // namespace dvs
