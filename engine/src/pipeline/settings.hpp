// The settings a run actually uses: the preset's defaults filled in and every number checked, before any
// file is read or device work starts. Shared by run_pipeline and run_inversion.
#pragma once
#include <string>

#include "dvs/pipeline.hpp"

namespace dvs {

struct Settings {
  bool official = false;
  int steps = 50, inversion_steps = 30;
  double strength = 0.95, delta = 3;
  std::string negative;
};

// Throws dvs::Error naming the option on any invalid value.
Settings resolve(const RunOptions& o);

}  // namespace dvs
