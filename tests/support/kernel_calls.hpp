// How many op calls the kernel census (vk::Context::note_kernel) has seen dispatch `shader` so far: tests that force
// a kernel family check with it that the call really ran the shader they meant.
#pragma once
#include <cstdint>
#include <string>

#include "vk/context.hpp"

namespace dvs::test {

inline uint64_t kernel_calls(const vk::Context& ctx, const std::string& shader) {
  uint64_t n = 0;
  for (const auto& [note, count] : ctx.kernel_notes())
    if (note.shader == shader) n += count;
  return n;
}

}  // namespace dvs::test
