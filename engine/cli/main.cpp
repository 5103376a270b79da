// The `dvs` command line. Sub-commands are added here as the engine grows; each prints one clear
// message and exits non-zero on any user error.
//
// Exit status, the same for every command: 0 done (and --help), 1 the work failed (bad input file, device
// error, ...), 2 usage error (unknown option, malformed or missing value), 130 interrupted (Ctrl-C/SIGTERM),
// 3 internal error (a bug: please report it).
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <new>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "dvs/info.hpp"
#include "dvs/logs.hpp"
#include "dvs/option_names.hpp"
#include "dvs/usage_error.hpp"
#include "args.hpp"
#include "commands.hpp"
#include "interrupt.hpp"
#include "options.hpp"
#include "progress.hpp"

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
    "  depth           per-frame disparity of a video (Video-Depth-Anything), as .npz for --depth\n"
    "  render          geometry only: a video seen along a new camera path, plus its visibility mask\n"
    "  invert          render, encode and DDIM-invert only: writes eps_inv.npy and fills run's cache\n"
    "  encode-prompt   T5 embeddings of a prompt as .npy\n"
    "  batch           many runs from a JSON-lines file, shardable across machines (--shard i/n)\n"
    "  plan            device memory a run needs (weights, each model call, VAE tiling for a budget)\n"
    "  cache           list the cache (depth, inversions, latents) or clean it by age or size\n"
    "\n"
    "common options:\n"
    "  --device I|NAME  use device index I or the first whose name contains NAME (also: DVS_DEVICE)\n"
    "  --verbose        let the libraries' own log lines through (FFmpeg, OpenCV, SentencePiece)\n"
    "  -h, --help       this help (also: dvs <command> --help)\n"
    "  --version        print the version\n"
    "\n"
    "exit status: 0 done; 1 the work failed; 2 usage error; 130 interrupted (Ctrl-C); 3 internal error.\n"
    "With --progress json, stdout carries only JSON Lines (every other line goes to stderr), ending with one\n"
    "{\"event\":\"done\"} or {\"event\":\"error\"} object.\n";

// The final event of a --progress json run (nothing otherwise).
int finish(bool json, int code, const std::string& message = "") {
  if (json) {
    nlohmann::json e{{"event", code == 0 ? "done" : "error"}, {"exit_code", code}};
    if (code != 0) e["message"] = message;
    dvs::cli::emit_json_event(e);
  }
  return code;
}

}  // namespace

namespace dvs::cli {

int run_info(const std::vector<std::string>& argv) {
  static const OptionGroup kBench{
      "measure",
      {{"bench-upload", "",
        "measure the host -> device rate of weight streaming on the device (pinned host\n"
        "memory to device memory, 256 MiB per upload) for dvs plan --upload-rate"}}};
  Args a("info", {"dvs info [--device I|NAME] [--bench-upload]",
                  "Lists the Vulkan devices, their features, memory and limits.\n", ""},
         {kDevice, kBench});
  a.parse(argv);
  if (a.help()) return 0;
  if (a.has("bench-upload")) {
    const dvs::UploadBench b = dvs::bench_upload(a.str("device"));
    char line[256];
    std::snprintf(line, sizeof line, "%.2f GB/s (median of %d uploads of %.0f MiB; %.2f to %.2f GB/s)",
                  b.bytes_per_second / 1e9, b.uploads, double(b.bytes) / 1048576.0, b.min_bytes_per_second / 1e9,
                  b.max_bytes_per_second / 1e9);
    std::cout << "upload rate of " << b.device << " on its " << b.queue << ": " << line << "\n"
              << "use it with: dvs plan --upload-rate " << std::to_string(int64_t(b.bytes_per_second)) << "\n";
    return 0;
  }
  std::cout << dvs::device_report(a.str("device"));
  return 0;
}

}  // namespace dvs::cli

int main(int argc, char** argv) {
  std::vector<std::string> args;
  bool verbose = false;
  for (int i = 1; i < argc; ++i) {  // --verbose is common to every command
    if (std::strcmp(argv[i], "--verbose") == 0) verbose = true;
    else args.emplace_back(argv[i]);
  }
  dvs::set_third_party_logs(verbose);  // before any library starts logging
  dvs::set_option_names(dvs::OptionNames::command_line);  // messages name --strength, not RunOptions::strength
  // The library's warnings on stderr in every progress mode; on a terminal, over the progress bar's open line
  // (the bar redraws itself on the next line).
  dvs::set_log_handler([tty = isatty(fileno(stderr)) != 0](dvs::LogLevel, const std::string& message) {
    std::fprintf(stderr, "%sdvs: warning: %s\n", tty ? "\r\033[K" : "", message.c_str());
    std::fflush(stderr);
  });
  // --progress json: stdout is for JSON Lines alone, so every plain line (std::cout) goes to stderr.
  const bool json = dvs::cli::wants_json_progress(args);
  if (json) std::cout.rdbuf(std::cerr.rdbuf());
  try {
    if (args.empty()) {  // a usage error: the usage on stderr, status 2
      std::cerr << kUsage;
      return finish(json, 2, "no command given");
    }
    if (args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
      std::cout << kUsage;
      return 0;
    }
    if (args[0] == "--version") {
      std::cout << "dvs " << dvs::version() << "\n";
      return 0;
    }
    dvs::cli::install_interrupt_handler();
    std::string cmd = args[0];
    std::vector<std::string> rest(args.begin() + 1, args.end());
    int code = -1;
    if (cmd == "info") code = dvs::cli::run_info(rest);
    else if (cmd == "render") code = dvs::cli::run_render(rest);
    else if (cmd == "run") code = dvs::cli::run_run(rest);
    else if (cmd == "demo") code = dvs::cli::run_demo(rest);
    else if (cmd == "invert") code = dvs::cli::run_invert(rest);
    else if (cmd == "encode-prompt") code = dvs::cli::run_encode_prompt(rest);
    else if (cmd == "batch") code = dvs::cli::run_batch(rest);
    else if (cmd == "plan") code = dvs::cli::run_plan(rest);
    else if (cmd == "depth") code = dvs::cli::run_depth(rest);
    else if (cmd == "cache") code = dvs::cli::run_cache(rest);
    if (code < 0) {
      std::cerr << "dvs: unknown command '" << cmd << "'\n\n" << kUsage;
      return finish(json, 2, "unknown command '" + cmd + "'");
    }
    return finish(json, code, code ? "the command failed" : "");
  } catch (const dvs::Cancelled&) {
    std::cerr << "dvs: interrupted; partial outputs removed\n";
    return finish(json, dvs::cli::kInterruptedExitCode, "interrupted");
  } catch (const dvs::UsageError& e) {
    std::cerr << "dvs: error: " << e.what() << "\n";
    return finish(json, 2, e.what());
  } catch (const dvs::Error& e) {
    std::cerr << "dvs: error: " << e.what() << "\n";
    return finish(json, 1, e.what());
  } catch (const std::bad_alloc&) {
    const char* msg = "out of host memory; try --vae-tiling, a smaller --size or fewer --frames";
    std::cerr << "dvs: error: " << msg << "\n";
    return finish(json, 1, msg);
  } catch (const std::exception& e) {
    std::cerr << "dvs: internal error: " << e.what() << "\n";
    return finish(json, 3, std::string("internal error: ") + e.what());
  }
}
