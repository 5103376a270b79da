#include "npy_arrays.hpp"

#include <cstring>
#include <fstream>
#include <stdexcept>

namespace preview {

int64_t NpyArray::elements() const {
  int64_t n = 1;
  for (int64_t d : shape) n *= d;
  return n;
}

namespace {

std::string field(const std::string& header, const std::string& key) {
  const size_t k = header.find("'" + key + "'");
  if (k == std::string::npos) return "";
  size_t v = header.find(':', k);
  if (v == std::string::npos) return "";
  ++v;
  while (v < header.size() && header[v] == ' ') ++v;
  if (header[v] == '\'') return header.substr(v + 1, header.find('\'', v + 1) - v - 1);
  if (header[v] == '(') return header.substr(v + 1, header.find(')', v) - v - 1);
  return header.substr(v, header.find_first_of(",}", v) - v);
}

}  // namespace

NpyArray read_npy(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open the file (does it exist?)");
  char magic[8];
  in.read(magic, 8);
  if (!in || std::memcmp(magic, "\x93NUMPY", 6) != 0)
    throw std::runtime_error(path + ": not an .npy file (numpy's np.save format); give an .npy array");
  uint32_t header_len = 0;
  if (magic[6] == 1) {
    uint8_t b[2];
    in.read(reinterpret_cast<char*>(b), 2);
    header_len = b[0] | (b[1] << 8);
  } else {
    uint8_t b[4];
    in.read(reinterpret_cast<char*>(b), 4);
    header_len = b[0] | (b[1] << 8) | (b[2] << 16) | (uint32_t(b[3]) << 24);
  }
  std::string header(header_len, '\0');
  in.read(header.data(), header_len);
  if (!in) throw std::runtime_error(path + ": the .npy header is cut short");
  NpyArray a;
  const std::string descr = field(header, "descr");
  if (descr == "|u1" || descr == "<u1") a.dtype = "u1";
  else if (descr == "<f4") a.dtype = "f4";
  else throw std::runtime_error(path + ": dtype '" + descr + "' is not supported (uint8 or little-endian float32)");
  if (field(header, "fortran_order") != "False")
    throw std::runtime_error(path + ": Fortran-ordered array; save it with np.ascontiguousarray");
  const std::string shape = field(header, "shape");
  for (size_t p = 0; p < shape.size();) {
    while (p < shape.size() && (shape[p] == ' ' || shape[p] == ',')) ++p;
    if (p >= shape.size()) break;
    size_t used = 0;
    a.shape.push_back(std::stoll(shape.substr(p), &used));
    p += used;
  }
  const size_t bytes = size_t(a.elements()) * (a.dtype == "f4" ? 4 : 1);
  a.bytes.resize(bytes);
  in.read(reinterpret_cast<char*>(a.bytes.data()), std::streamsize(bytes));
  if (!in) throw std::runtime_error(path + ": holds fewer bytes than its shape says (the file is cut short)");
  return a;
}

void write_npy(const std::string& path, const std::string& dtype, const std::vector<int64_t>& shape, const void* data,
               size_t bytes) {
  std::string dims;
  for (int64_t d : shape) dims += std::to_string(d) + ", ";
  if (shape.size() > 1) dims.resize(dims.size() - 2);
  std::string header = "{'descr': '" + std::string(dtype == "u1" ? "|u1" : "<f4") +
                       "', 'fortran_order': False, 'shape': (" + dims + "), }";
  const size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header += '\n';
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error(path + ": cannot write the file (is the folder writable?)");
  const uint16_t len = uint16_t(header.size());
  out.write("\x93NUMPY\x01\x00", 8);
  out.put(char(len & 0xff)).put(char(len >> 8));
  out << header;
  out.write(static_cast<const char*>(data), std::streamsize(bytes));
  if (!out) throw std::runtime_error(path + ": writing failed (disk full?)");
}

}  // namespace preview
