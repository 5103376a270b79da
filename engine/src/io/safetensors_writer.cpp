#include "io/safetensors_writer.hpp"

#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <nlohmann/json.hpp>

#include "dvs/error.hpp"
#include "io/disk_space.hpp"
#include "io/injected_faults.hpp"
#include "io/safetensors.hpp"

namespace dvs {

void write_safetensors(const std::filesystem::path& path, const std::vector<std::pair<std::string, HostTensor>>& tensors,
                       const std::map<std::string, std::string>& metadata) {
  nlohmann::ordered_json header;
  if (!metadata.empty()) header["__metadata__"] = metadata;
  uint64_t offset = 0;
  for (const auto& [name, t] : tensors) {
    if (name == "__metadata__" || header.contains(name)) throw Error(path.string() + ": duplicate or reserved tensor name '" + name + "'");
    header[name] = {{"dtype", safetensors_dtype_name(t.dtype)}, {"shape", t.shape}, {"data_offsets", {offset, offset + t.bytes()}}};
    offset += t.bytes();
  }
  std::string text = header.dump();
  text.append((8 - text.size() % 8) % 8, ' ');
  const uint64_t n = text.size();
  const std::filesystem::path tmp = path.string() + ".partial-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(path.string() + ": cannot write (is the folder writable?)");
    unsigned char len[8];
    for (int i = 0; i < 8; ++i) len[i] = static_cast<unsigned char>(n >> (8 * i));
    out.write(reinterpret_cast<const char*>(len), 8);
    out.write(text.data(), std::streamsize(n));
    for (const auto& [name, t] : tensors) out.write(reinterpret_cast<const char*>(t.data.data()), std::streamsize(t.bytes()));
    out.close();  // the last buffered bytes reach the disk here
    int err = out ? 0 : errno;  // the failed write(2)'s, which the stream leaves in errno
    if (const int injected = faults::write_error(path); injected && out) out.setstate(std::ios::badbit), err = injected;
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      const std::string full = no_space_note(path.parent_path());
      const std::string why = err == ENOSPC || err == EIO ? write_error_note(err, path.parent_path())
                              : full.empty()              ? std::string("an I/O error")
                                                          : full;
      throw Error(path.string() + ": write failed (" + why + ")");
    }
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace dvs
