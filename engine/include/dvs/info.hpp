// Device listing for `dvs info` and for applications that let a user choose a GPU.
#pragma once
#include <string>

#include "dvs/api.hpp"
#include "dvs/version.h"  // DVS_VERSION_MAJOR/MINOR/PATCH: the headers' version

namespace dvs {

// Every Vulkan device with its type, driver, Vulkan version, subgroup size, features and limits; marks
// the one that `device_spec` (index, name substring, or "" for the default/DVS_DEVICE) selects.
DVS_API std::string device_report(const std::string& device_spec = "");

// The library's version, "MAJOR.MINOR.PATCH" (the one loaded at run time; DVS_VERSION_* are the headers').
DVS_API const char* version();

}  // namespace dvs
