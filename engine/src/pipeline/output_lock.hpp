// One dvs process at a time writes into an output folder: a job holds an exclusive flock on DIR/.dvs-lock from
// its start to its end (works across the hosts of a cluster's shared file system where flock does, e.g. NFSv4).
// A second process asking for the same folder is refused at once with the holder's pid and host (exit status 1):
// it does not wait, so a mistaken second submission is seen at once rather than after the first one's hours.
// Holding the lock, the job also finishes what a killed job left in DIR (run_outputs.hpp: recover_staging).
#pragma once
#include <filesystem>

namespace dvs {

class OutputLock {
 public:
  // Creates `dir` when missing. Throws dvs::Error naming the other process when it holds the folder.
  explicit OutputLock(const std::filesystem::path& dir);
  ~OutputLock();  // removes the lock file and releases the lock
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  std::filesystem::path file_;
  int fd_ = -1;
};

}  // namespace dvs
