// The files one job writes into its output folder. Until commit(), the destructor removes every one of them,
// so a failed or cancelled job leaves nothing that looks finished (each file itself is written to a temporary
// name and renamed when complete, see io/video.hpp and io/npy.hpp).
#pragma once
#include <filesystem>
#include <string>
#include <vector>

namespace dvs {

class RunOutputs {
 public:
  explicit RunOutputs(std::filesystem::path dir) : dir_(std::move(dir)) {}
  ~RunOutputs();
  RunOutputs(const RunOutputs&) = delete;
  RunOutputs& operator=(const RunOutputs&) = delete;

  // The path for `name` in the folder. A file of that name from an earlier job is removed now, so the folder
  // never mixes this job's files with an older job's.
  std::filesystem::path add(const std::string& name);
  void commit() { committed_ = true; }

 private:
  std::filesystem::path dir_;
  std::vector<std::filesystem::path> files_;
  bool committed_ = false;
};

}  // namespace dvs
