#include "vk/dropped_barrier.hpp"

#include <cstdlib>

#include "dvs/usage_error.hpp"

namespace dvs::vk {

DroppedBarrier parse_dropped_barrier(const std::string& spec, const std::string& source) {
  DroppedBarrier d;
  if (spec.empty()) return d;
  std::string number = spec;
  d.kind = DroppedBarrier::Kind::hazard;
  const std::string segment = "segment:";
  if (spec.rfind(segment, 0) == 0) {
    d.kind = DroppedBarrier::Kind::segment;
    number = spec.substr(segment.size());
  }
  const bool digits = !number.empty() && number.size() <= 9 && number.find_first_not_of("0123456789") == std::string::npos;
  if (!digits || std::stoul(number) == 0)
    throw UsageError(source + "='" + spec + "': expected N or segment:N with N a whole number from 1 (the N-th "
                     "barrier, or the barrier opening the N-th segment, of every recording is left out; a switch "
                     "for tests only)");
  d.index = uint32_t(std::stoul(number));
  return d;
}

DroppedBarrier dropped_barrier_from_env() {
  const char* e = std::getenv("DVS_DEBUG_DROP_BARRIER");
  return parse_dropped_barrier(e ? e : "");
}

}  // namespace dvs::vk
