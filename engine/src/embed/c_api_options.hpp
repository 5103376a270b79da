// What the C API's calls share beyond the guard (embed/c_api_guard.hpp): the option structs read through their
// struct_size (dvs/dvs.h: structs that can grow) and converted to the C++ options, the C names of options in
// messages, and the start of a job handle.
#pragma once
#include <algorithm>
#include <cstring>
#include <functional>
#include <string>

#include "dvs/dvs.h"
#include "dvs/info.hpp"
#include "dvs/usage_error.hpp"
#include "dvs/job.hpp"
#include "dvs/pipeline.hpp"
#include "dvs/render.hpp"

namespace dvs::capi {

constexpr size_t kLargestPlausibleStruct = 1 << 16;  // an uninitialised struct_size is refused, not read through

// The caller's struct `given` of C type T (named `type`) read through its struct_size (dvs/dvs.h: structs that can
// grow): a shorter one (an older dvs.h, at least `first_size` bytes) keeps `defaults` for the fields it lacks; a
// longer one (a newer dvs.h) must hold zeros beyond this library's sizeof(T). UsageError naming `call` otherwise.
template <class T>
T read_sized(const T& given, const T& defaults, size_t first_size, const char* type, const char* call) {
  const size_t n = given.struct_size;
  const std::string where = std::string(call) + ": " + type + ".struct_size is " + std::to_string(n);
  if (n < first_size || n > kLargestPlausibleStruct)
    throw UsageError(where + ", not sizeof(" + type + ") = " + std::to_string(sizeof(T)) + ": fill the struct with " +
                     type + "_default() first, then set its fields");
  T out = defaults;
  std::memcpy(static_cast<void*>(&out), &given, std::min(n, sizeof(T)));
  const auto* bytes = reinterpret_cast<const unsigned char*>(&given);
  for (size_t i = sizeof(T); i < n; ++i)
    if (bytes[i] != 0)
      throw UsageError(where + ": the program's dvs.h is newer than this library (dvs " + version() + ", " +
                       std::to_string(sizeof(T)) + " bytes) and sets a field it does not know (byte " +
                       std::to_string(i) + "); leave that field 0, or run with the dvs the program was built for");
  out.struct_size = sizeof(T);
  return out;
}

// Makes the default log line (no callback set) name the C structs' fields, unless the application installed a
// handler of its own (embed/c_api_log.cpp). Every call that takes options or loads a trajectory calls it.
void use_c_names_in_default_log();

// read_sized with the defaults its _default call fills (dvs_render_options_default, ...), by a call that takes
// options.
template <class T>
T read_filled(const T& given, dvs_status (*fill_defaults)(T*), size_t first_size, const char* type, const char* call) {
  use_c_names_in_default_log();
  T defaults;
  fill_defaults(&defaults);
  return read_sized(given, defaults, first_size, type, call);
}

// The caller's dvs_render_options / dvs_pipeline_options as the C++ options (NULL strings = unset), after their
// struct_size is checked (UsageError naming `call`, the struct and struct_size). A NULL render = the defaults.
RenderJob render_job(const dvs_render_options& options, const char* call);
RunOptions run_options(const dvs_pipeline_options& options, const char* call);

// A message of the C++ library with its option names as the C structs' ("RunOptions::strength" ->
// "dvs_pipeline_options.strength", "RenderJob::trajectory" -> "dvs_render_options.trajectory") and the C call for
// the C++ one it names (dvs::enable_video_files()).
std::string c_option_names(std::string message);

// *out = a job handle of `kind` ("render", "pipeline", "depth") around what `begin` starts; errors as guarded().
dvs_status start_job(dvs_job** out, const char* call, const char* kind, const std::function<Job()>& begin);

}  // namespace dvs::capi
