#include "dvs/info.hpp"

#include "io/public_call.hpp"
#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"

namespace dvs {

const char* version() { return DVS_VERSION; }

std::string device_report(const std::string& device_spec) {
  return public_call("dvs::device_report", [&]() -> std::string {
    std::vector<vk::DeviceCaps> devices = vk::list_devices();
    uint32_t chosen = vk::select_device(devices, device_spec);
    std::string out = "dvs " + std::string(version()) + ": " + std::to_string(devices.size()) + " Vulkan device" +
                      (devices.size() == 1 ? "" : "s") + "\n\n";
    for (const auto& d : devices) {
      out += vk::describe_device(d);
      if (d.index == chosen) {
        out += "  (selected: dvs uses this device)\n";
        out += ops::describe_tuning(ops::device_tuning(d));
      }
      out += "\n";
    }
    out += "Choose a device with --device INDEX|NAME or the DVS_DEVICE environment variable.\n";
    return out;
  });
}

}  // namespace dvs
