// The `dvs` command line. Sub-commands are added here as the engine grows; each prints one clear
// message and exits non-zero on any user error.
#include <cstring>
#include <new>
#include <iostream>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "dvs/info.hpp"
#include "args.hpp"
#include "commands.hpp"
#include "interrupt.hpp"

namespace {

const char* kUsage =
    "dvs — dynamic view synthesis on any Vulkan GPU\n"
    "\n"
    "usage: dvs <command> [options]\n"
    "\n"
    "commands:\n"
    "  demo            run the whole pipeline on a generated scene with a tiny random model\n"
    "  run             re-render a video along a new camera path (the whole pipeline)\n"
    "  info            list the Vulkan devices, their features, memory and limits\n"
    "  render          geometry only: a video seen along a new camera path, plus its visibility mask\n"
    "  invert          render, encode and DDIM-invert only: writes eps_inv.npy and fills run's cache\n"
    "  encode-prompt   T5 embeddings of a prompt as .npy\n"
    "  batch           many runs from a JSON-lines file, shardable across machines (--shard i/n)\n"
    "  plan            device memory a run needs (weights, each model call, VAE tiling for a budget)\n"
    "\n"
    "common options:\n"
    "  --device I|NAME  use device index I or the first whose name contains NAME (also: DVS_DEVICE)\n"
    "  -h, --help       this help\n"
    "  --version        print the version\n";


}  // namespace

namespace dvs::cli {

int run_info(const std::vector<std::string>& argv) {
  Args a("info", argv, {"device"}, {});
  if (a.help()) {
    std::cout << "usage: dvs info [--device I|NAME]\n";
    return 0;
  }
  std::cout << dvs::device_report(a.str("device"));
  return 0;
}

}  // namespace dvs::cli

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  try {
    if (args.empty() || args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
      std::cout << kUsage;
      return args.empty() ? 2 : 0;
    }
    if (args[0] == "--version") {
      std::cout << "dvs " << dvs::version() << "\n";
      return 0;
    }
    dvs::cli::install_interrupt_handler();
    std::string cmd = args[0];
    std::vector<std::string> rest(args.begin() + 1, args.end());
    if (cmd == "info") return dvs::cli::run_info(rest);
    if (cmd == "render") return dvs::cli::run_render(rest);
    if (cmd == "run") return dvs::cli::run_run(rest);
    if (cmd == "demo") return dvs::cli::run_demo(rest);
    if (cmd == "invert") return dvs::cli::run_invert(rest);
    if (cmd == "encode-prompt") return dvs::cli::run_encode_prompt(rest);
    if (cmd == "batch") return dvs::cli::run_batch(rest);
    if (cmd == "plan") return dvs::cli::run_plan(rest);
    std::cerr << "dvs: unknown command '" << cmd << "'\n\n" << kUsage;
    return 2;
  } catch (const dvs::Cancelled&) {
    std::cerr << "dvs: interrupted; partial outputs removed\n";
    return dvs::cli::kInterruptedExitCode;
  } catch (const dvs::Error& e) {
    std::cerr << "dvs: error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "dvs: error: out of host memory; try --vae-tiling, a smaller --size or fewer --frames\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "dvs: internal error: " << e.what() << "\n";
    return 3;
  }
}
