// Damaged copies of a PyTorch .pth (a stored zip, as torch.save writes it) for the tests of what readers find:
// one tensor's storage record filled with a value and the archive rewritten by libzip (a valid file: its CRC
// is recomputed), or one byte of a record flipped in place (the CRC no longer matches).
#pragma once
#include <gtest/gtest.h>
#include <zip.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "io/pth_file.hpp"
#include "support/files.hpp"

namespace dvs::test {

// The zip entry that holds `tensor`'s storage (the whole record, which may be larger than the tensor).
inline std::string pth_record_of(const std::filesystem::path& file, const std::string& tensor) {
  const PthFile f = PthFile::open(file);
  const PthTensorInfo* t = f.find(tensor);
  if (!t) throw std::runtime_error(file.string() + " has no tensor " + tensor);
  return f.record_prefix() + "data/" + t->storage_key;
}

// `to` = `from` with every f32 element of `tensor`'s storage record set to `value`, a valid archive.
inline void write_pth_filled(const std::filesystem::path& from, const std::filesystem::path& to, const std::string& tensor,
                             float value) {
  const std::string record = pth_record_of(from, tensor);
  std::filesystem::copy_file(from, to, std::filesystem::copy_options::overwrite_existing);
  int err = 0;
  zip_t* za = zip_open(to.c_str(), 0, &err);
  ASSERT_NE(za, nullptr) << to << ": libzip error " << err;
  const zip_int64_t index = zip_name_locate(za, record.c_str(), 0);
  ASSERT_GE(index, 0) << record;
  zip_stat_t st;
  ASSERT_EQ(zip_stat_index(za, zip_uint64_t(index), 0, &st), 0);
  const std::vector<float> values(size_t(st.size / 4), value);  // read by libzip at zip_close, below
  zip_source_t* src = zip_source_buffer(za, values.data(), values.size() * 4, 0);
  ASSERT_EQ(zip_file_replace(za, zip_uint64_t(index), src, 0), 0) << zip_strerror(za);
  zip_set_file_compression(za, zip_uint64_t(index), ZIP_CM_STORE, 0);
  ASSERT_EQ(zip_close(za), 0) << zip_strerror(za);
}

// `to` = `from` with one byte inside `tensor`'s stored record flipped: the archive opens, the read fails its CRC.
inline void write_pth_bad_crc(const std::filesystem::path& from, const std::filesystem::path& to, const std::string& tensor) {
  std::vector<uint8_t> bytes;
  {
    const PthFile f = PthFile::open(from);
    bytes = f.read_bytes(*f.find(tensor));
  }
  std::string all = read_text(from);
  const size_t at = all.find(std::string(bytes.begin(), bytes.end()));
  ASSERT_NE(at, std::string::npos) << "the record is not stored uncompressed";
  all[at + bytes.size() / 2] = char(all[at + bytes.size() / 2] ^ 0x10);
  write_text(to, all);
}

}  // namespace dvs::test
