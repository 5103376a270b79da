#include "pipeline/run_outputs.hpp"

namespace dvs {

std::filesystem::path RunOutputs::add(const std::string& name) {
  auto path = dir_ / name;
  std::error_code ec;
  std::filesystem::remove(path, ec);
  files_.push_back(path);
  return path;
}

RunOutputs::~RunOutputs() {
  if (committed_) return;
  std::error_code ec;
  for (const auto& f : files_) std::filesystem::remove(f, ec);
}

}  // namespace dvs
