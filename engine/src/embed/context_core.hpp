// What a dvs::Context is inside: the device objects (vk::Context) and the gate that says who may use them now
// (embed/context_gate.hpp). Shared: the dvs::Context, each scene and depth estimator made on it and a running job
// each hold it, so destroying the dvs::Context first leaves what was made on it working (the device objects go
// with the last holder), and the context's destructor can stop its job through the gate.
#pragma once
#include <memory>

#include "embed/context_gate.hpp"
#include "vk/context.hpp"

namespace dvs::embed {

struct ContextCore {
  std::unique_ptr<vk::Context> device;  // declared first: destroyed after the gate, by the last holder
  ContextGate gate;
};

}  // namespace dvs::embed
