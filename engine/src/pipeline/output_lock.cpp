#include "pipeline/output_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "dvs/error.hpp"
#include "io/option_names.hpp"
#include "io/crash_points.hpp"
#include "pipeline/run_outputs.hpp"

namespace dvs {
namespace {

// What the holder wrote into the lock file: "pid 123 on host node7".
std::string holder_of(int fd) {
  char buf[256] = {};
  const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
  std::string s = n > 0 ? std::string(buf, size_t(n)) : "";
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s.empty() ? "another dvs process" : "dvs process " + s;
}

}  // namespace

OutputLock::OutputLock(const std::filesystem::path& dir) : file_(dir / ".dvs-lock") {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir))
    throw Error(dir.string() + ": cannot create the output folder (" + (ec ? ec.message() : "not a folder") + ")");
  bool locked = true;
  for (;;) {
    fd_ = ::open(file_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0)
      throw Error(file_.string() + ": cannot create the output folder's lock file (" + std::strerror(errno) +
                  "); give " + option_name("RenderJob::out_dir") + " a folder you can write to");
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      if (errno != EWOULDBLOCK) {
        // A file system without locks (an NFSv3 mount without lockd, some FUSE ones): the job runs unlocked,
        // as dvs did before it had the lock, and leaves alone the staging folders of live processes.
        locked = false;
        break;
      }
      const std::string holder = holder_of(fd_);
      ::close(fd_);
      fd_ = -1;
      throw Error(dir.string() + ": this output folder is in use by " + holder + " (its lock is " +
                  file_.filename().string() + "); wait for it to finish, or give another " +
                  option_name("RenderJob::out_dir"));
    }
    // The previous holder removes the file when it is done: a lock taken on a file no longer at that name is no
    // lock on the folder, so take it again on the one that is.
    struct stat held {}, named {};
    if (::fstat(fd_, &held) == 0 && ::stat(file_.c_str(), &named) == 0 && held.st_ino == named.st_ino &&
        held.st_dev == named.st_dev)
      break;
    ::close(fd_);
  }
  char host[128] = {};
  ::gethostname(host, sizeof host - 1);
  const std::string me = "pid " + std::to_string(::getpid()) + " on host " + host + "\n";
  const bool noted = ::ftruncate(fd_, 0) == 0 && ::pwrite(fd_, me.data(), me.size(), 0) == ssize_t(me.size());
  (void)noted;  // the holder's name only makes a refused process's message clearer
  recover_staging(dir, locked);  // locked, no other process writes here: whatever is staged is a dead one's
  crash_point("out-locked");
}

OutputLock::~OutputLock() {
  std::error_code ec;
  std::filesystem::remove(file_, ec);  // while still held: see the inode check above
  ::close(fd_);
}

}  // namespace dvs
