// Seconds as a person reads them, for stage times and forecasts: three significant digits below a minute ("0.41 s",
// "12.3 s"), whole seconds below an hour ("4 min 05 s"), whole minutes above ("1 h 12 min"); never the 6-9
// digits of a default stream.
#pragma once
#include <string>

#include "dvs/api.hpp"

namespace dvs {

DVS_API std::string duration_text(double seconds);

// "1 window", "3 windows": a count with its noun, singular when it is one.
DVS_API std::string count_text(long long n, const std::string& singular, const std::string& plural);

}  // namespace dvs
