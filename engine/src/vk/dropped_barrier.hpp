// DVS_DEBUG_DROP_BARRIER, a switch for tests only: the recorder leaves out one barrier of every recording, so a
// test can prove that the synchronization-validation pass (tests/run_with_sync_validation.sh) fails a test whose
// commands race, although lavapipe computes the right values anyway (docs/testing.md).
//
//   DVS_DEBUG_DROP_BARRIER=N          the N-th barrier() of every recording (hazard barriers and explicit ones)
//   DVS_DEBUG_DROP_BARRIER=segment:N  the barrier opening the N-th segment of every recording (seen only with
//                                     the layer's QueueSubmit check: the race is between two submissions)
//
// N counts from 1. The tracker goes on as if the barrier were there, so exactly one barrier is missing; the
// recorder's barrier_count() counts only the barriers it recorded. Unset or empty: nothing is dropped.
// Anything malformed is a UsageError naming the variable and what it accepts.
#pragma once
#include <cstdint>
#include <string>

namespace dvs::vk {

struct DroppedBarrier {
  enum class Kind { none, hazard, segment };
  Kind kind = Kind::none;
  uint32_t index = 0;  // 1-based; 0 with Kind::none
  bool drops_hazard(uint32_t n) const { return kind == Kind::hazard && index == n; }
  bool drops_segment(uint32_t n) const { return kind == Kind::segment && index == n; }
};

DroppedBarrier parse_dropped_barrier(const std::string& spec, const std::string& source = "DVS_DEBUG_DROP_BARRIER");
DroppedBarrier dropped_barrier_from_env();  // DVS_DEBUG_DROP_BARRIER, read at every call

}  // namespace dvs::vk
