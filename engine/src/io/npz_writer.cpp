#include "io/npz_writer.hpp"

#include <unistd.h>
#include <zip.h>

#include "dvs/error.hpp"
#include "io/disk_space.hpp"
#include "io/injected_faults.hpp"
#include "io/npy.hpp"

namespace dvs {

void write_npz(const std::filesystem::path& path, const std::vector<std::pair<std::string, HostTensor>>& arrays) {
  const std::filesystem::path tmp = path.parent_path() / (path.filename().string() + ".partial-" + std::to_string(::getpid()));
  std::error_code ec;
  std::filesystem::remove(tmp, ec);
  int err = 0;
  zip_t* z = zip_open(tmp.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  if (!z) throw Error(path.string() + ": cannot create the file (is the folder writable?)");
  std::vector<std::vector<uint8_t>> bytes;  // alive until zip_close writes them
  bytes.reserve(arrays.size());
  auto fail = [&](const std::string& why) {
    zip_discard(z);
    std::filesystem::remove(tmp, ec);
    throw Error(path.string() + ": " + why);
  };
  for (const auto& [name, t] : arrays) {
    bytes.push_back(encode_npy(t));
    zip_source_t* src = zip_source_buffer(z, bytes.back().data(), bytes.back().size(), 0);
    if (!src) fail("cannot add " + name);
    const zip_int64_t idx = zip_file_add(z, (name + ".npy").c_str(), src, ZIP_FL_OVERWRITE);
    if (idx < 0) {
      zip_source_free(src);
      fail("cannot add " + name + ": " + zip_strerror(z));
    }
    zip_set_file_compression(z, zip_uint64_t(idx), ZIP_CM_DEFLATE, 0);
  }
  // libzip writes everything in zip_close; its error keeps the errno of the failed write.
  const int injected = faults::write_error(path);
  if (injected || zip_close(z) != 0) {
    const int err = injected ? injected : zip_error_code_system(zip_get_error(z));
    const std::string why =
        err ? write_error_note(err, path.parent_path()) : std::string(zip_strerror(z)) + "; is the disk full?";
    zip_discard(z);
    std::filesystem::remove(tmp, ec);
    throw Error(path.string() + ": writing failed: " + why + " (nothing was written)");
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw Error(path.string() + ": cannot move the finished file into place (" + ec.message() + ")");
  }
}

}  // namespace dvs
