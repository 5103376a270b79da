// dvs-bench [--filter GROUP[,GROUP]] [--quick] [--device I|NAME]
// Runs the registered benchmark groups (limits first) and ends with one JSON line per result.
#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <sstream>

#include "dvs/error.hpp"
#include "harness.hpp"

int main(int argc, char** argv) {
  using namespace dvs::bench;
  std::vector<std::string> groups;
  bool quick = false;
  dvs::vk::ContextOptions opts;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--filter" && i + 1 < argc) {
      std::stringstream ss(argv[++i]);
      for (std::string g; std::getline(ss, g, ',');) groups.push_back(g);
    } else if (a == "--device" && i + 1 < argc) opts.device = argv[++i];
    else {
      // --help: the usage on stdout, status 0; anything else is a usage error: the usage on stderr, status 2.
      const bool help = a == "-h" || a == "--help";
      std::ostream& out = help ? std::cout : std::cerr;
      if (!help) out << "dvs-bench: unknown option or missing value: " << a << "\n";
      out << "usage: dvs-bench [--filter GROUP[,GROUP]] [--quick] [--device I|NAME]\ngroups:";
      for (auto& r : registry()) out << " " << r.group;
      out << "\n";
      return help ? 0 : 2;
    }
  }
  try {
    dvs::vk::Context ctx(opts);
    const char* lp = std::getenv("LP_NUM_THREADS");
    const char* ob = std::getenv("OPENBLAS_NUM_THREADS");
    std::cout << "device: " << ctx.caps().name << " (" << ctx.caps().driver_name << ")  LP_NUM_THREADS="
              << (lp ? lp : "unset") << "  OPENBLAS_NUM_THREADS=" << (ob ? ob : "unset") << "\n";
    Bench bench(ctx, quick);
    auto regs = registry();
    std::stable_sort(regs.begin(), regs.end(), [](auto& a, auto& b) { return a.order < b.order; });
    for (auto& r : regs) {
      bool wanted = groups.empty() || r.order == 0 ||
                    std::find(groups.begin(), groups.end(), std::string(r.group)) != groups.end();
      if (wanted) r.fn(bench);
    }
    std::cout << "\n";
    bench.print_json();
  } catch (const dvs::Error& e) {
    std::cerr << "dvs-bench: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
