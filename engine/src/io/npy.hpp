// NumPy .npy files (format versions 1.0, 2.0, 3.0): the golden packs' tensor format.
//
// Read: little-endian '<f4' '<f2' '<i4' '|u1' as stored; '<f8' narrowed to f32; '<i8' narrowed to i32 (an
// out-of-range value is an error); '<u2' (16-bit depth maps) widened to i32. C order only. Write: f32 f16 i32 u8 as stored; bf16 (no numpy dtype) as
// '<f4'. Writes go to a temporary file that is renamed into place, so no half-written .npy is ever left.
#pragma once
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

#include "io/host_tensor.hpp"

namespace dvs {

// Reads a whole .npy file. Throws dvs::Error naming the file and the problem.
HostTensor read_npy(const std::filesystem::path& path);

// Parses .npy bytes already in memory; `name` is used in error messages.
HostTensor parse_npy(std::span<const uint8_t> bytes, const std::string& name);

// Writes `t` atomically (temp file + rename). Throws dvs::Error on a malformed tensor or an I/O failure.
void write_npy(const std::filesystem::path& path, const HostTensor& t);

// Why a file cannot be created at `path` (errno `error_number` from the attempt), naming the user's folder, not a
// temporary name: "cannot create the file: the folder out/x does not exist".
std::string cannot_create_note(const std::filesystem::path& path, int error_number);

// The exact bytes write_npy would store (header + data).
std::vector<uint8_t> encode_npy(const HostTensor& t);

}  // namespace dvs
