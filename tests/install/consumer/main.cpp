// An application that uses the installed dvs: creates a context on dvs's own device, prints it, and checks that
// an error thrown inside libdvs is caught here by its type, dvs::UsageError (the typeinfo is exported). Exit status 0 = all good.
#include <dvs/context.hpp>
#include <dvs/error.hpp>
#include <dvs/info.hpp>
#include <dvs/lora.hpp>
#include <dvs/usage_error.hpp>

#include <cstdio>
#include <string>

int main() {
  try {
    dvs::Context ctx;
    std::printf("dvs %s on %s\n", dvs::version(), ctx.device_name().c_str());
    if (ctx.device_name().empty()) {
      std::fprintf(stderr, "consumer: the context names no device\n");
      return 1;
    }
  } catch (const dvs::Error& e) {
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }

  try {
    dvs::parse_lora_argument("adapter.safetensors:not-a-number");
    std::fprintf(stderr, "consumer: a malformed --lora argument was accepted\n");
    return 1;
  } catch (const dvs::UsageError& e) {
    std::printf("caught dvs::UsageError from the library: %s\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "consumer: expected a dvs::UsageError, caught another exception: %s\n", e.what());
    return 1;
  }
  return 0;
}
