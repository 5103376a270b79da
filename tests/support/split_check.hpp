// Checks for ops that split their work under small limits: run an op once under the limits in force and once
// under lower ones, expect the same bytes and more dispatches (proof that it split).
#pragma once
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "support/scoped_limits.hpp"
#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::test {

// Records `record` into a fresh Recorder, submits, returns its dispatch count.
inline uint32_t run_counted(vk::Context& ctx, const std::function<void(vk::Recorder&)>& record) {
  vk::Recorder rec(ctx);
  rec.begin();
  record(rec);
  rec.submit();
  return rec.dispatch_count();
}

// How many op calls have noted a split so far (every op, all kinds).
inline uint64_t split_notes(const vk::Context& ctx) {
  uint64_t n = 0;
  for (const auto& [op, count] : ctx.splits()) n += count;
  return n;
}

// How many calls of `op` have noted a split so far.
inline uint64_t split_count(const vk::Context& ctx, const std::string& op) {
  const auto it = ctx.splits().find(op);
  return it == ctx.splits().end() ? 0 : it->second;
}

// `op(rec, out)` into two outputs of `shape` (zeroed, or copies of `init` when given): first under the limits
// in force, then under `limits`. Expects identical bytes and more dispatches under `limits`.
inline void expect_split_equal(vk::Context& ctx, const std::string& limits, const Shape& shape, DType dtype,
                               const std::function<void(vk::Recorder&, const Tensor&)>& op, const std::string& what,
                               const HostTensor* init = nullptr) {
  const Tensor a = init ? Tensor::upload(ctx, *init) : Tensor::zeros(ctx, shape, dtype);
  const Tensor b = init ? Tensor::upload(ctx, *init) : Tensor::zeros(ctx, shape, dtype);
  const uint32_t whole = run_counted(ctx, [&](vk::Recorder& r) { op(r, a); });
  uint32_t split = 0;
  uint64_t noted = 0;
  {
    ScopedLimits scoped(ctx, limits);
    noted = split_notes(ctx);
    split = run_counted(ctx, [&](vk::Recorder& r) { op(r, b); });
  }
  EXPECT_GT(split, whole) << what << ": did not split";
  EXPECT_GT(split_notes(ctx), noted) << what << ": split without noting it (ctx.note_split)";
  const HostTensor ha = a.download(ctx), hb = b.download(ctx);
  size_t diff = 0;
  while (diff < ha.data.size() && ha.data[diff] == hb.data[diff]) ++diff;
  EXPECT_EQ(diff, ha.data.size()) << what << ": split result differs from byte " << diff
                                  << (dtype == DType::f32 && diff < ha.data.size()
                                          ? " (" + std::to_string(ha.to_f32()[diff / 4]) + " vs " +
                                                std::to_string(hb.to_f32()[diff / 4]) + ")"
                                          : std::string());
}

}  // namespace dvs::test
