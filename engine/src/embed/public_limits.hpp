// A device's limits as the public API reports them (dvs/devices.hpp), from what dvs queried (vk/device_info).
#pragma once
#include "dvs/devices.hpp"
#include "vk/device_info.hpp"

namespace dvs {

DeviceLimits limits_of(const vk::DeviceCaps& device);

}  // namespace dvs
