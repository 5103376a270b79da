// A device's limits as the public API reports them (dvs/devices.hpp), from what dvs queried (vk/device_info):
// defined with the device list (pipeline/public_devices.cpp), used by it and by dvs::Context::limits (embed/).
#pragma once
#include "dvs/devices.hpp"
#include "vk/device_info.hpp"

namespace dvs {

DeviceLimits limits_of(const vk::DeviceCaps& device);

}  // namespace dvs
