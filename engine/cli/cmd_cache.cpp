// `dvs cache list` and `dvs cache clean`: what the cache folder holds (depth estimates, inversions, sampled
// latents), and removing entries by age or to fit a size, never a file another dvs process is writing.
#include <cstdio>
#include <iostream>

#include "args.hpp"
#include "commands.hpp"
#include "dvs/cache.hpp"
#include "options.hpp"

namespace dvs::cli {
namespace {

std::string bytes_text(uint64_t b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(b);
  int u = 0;
  while (v >= 1024 && u < 4) v /= 1024, ++u;
  char buf[32];
  std::snprintf(buf, sizeof buf, u ? "%.1f %s" : "%.0f %s", v, units[u]);
  return buf;
}

std::string days_text(double d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, d < 10 ? "%.1f d" : "%.0f d", d);
  return buf;
}

const CommandHelp kCacheHelp{
    "dvs cache list [--cache-dir DIR]\n"
    "       dvs cache clean (--older-than DAYS | --max-size SIZE | --all) [--dry-run] [--cache-dir DIR]",
    "The cache keeps depth estimates, inversions and sampled latents that later runs reuse, in DIR/inversions of\n"
    "the cache folder DIR (--cache-dir DIR as every command takes it, else $DVS_CACHE_DIR, else ~/.cache/dvs).\n"
    "`list` shows its entries, most recently used first; `clean` removes those unused for more than DAYS days,\n"
    "then the least recently used until the rest fits in SIZE (e.g. 500M, 20G), or all of them. A file another\n"
    "dvs process is still writing is never removed.\n",
    ""};

}  // namespace

int run_cache(const std::vector<std::string>& argv) {
  Args a("cache", kCacheHelp,
         {{"cache", {option_in(kDepthCache, "cache-dir")}},
          {"clean",
           {{"older-than", "DAYS", "remove entries unused for more than DAYS days (e.g. 30, 0.5)"},
            {"max-size", "SIZE", "then remove the least recently used until the rest fits in SIZE (500M, 20G, bytes)"},
            {"all", "", "remove every entry"},
            {"dry-run", "", "say what would be removed, remove nothing"}}}});
  a.positional("action", "list or clean");
  a.parse(argv);
  if (a.help()) return 0;
  const std::string action = a.str("action");
  const std::filesystem::path dir = a.str("cache-dir");
  if (action == "list") {
    for (const char* o : {"older-than", "max-size", "all", "dry-run"})
      if (a.has(o)) a.fail(std::string("--") + o + " belongs to dvs cache clean");
    const auto entries = list_cache(dir);
    uint64_t total = 0;
    for (const auto& e : entries) {
      total += e.bytes;
      std::printf("%-9s %s  %10s  %8s  %s\n", e.kind.c_str(), e.key.c_str(), bytes_text(e.bytes).c_str(),
                  days_text(e.age_days).c_str(), (e.data_file.empty() ? e.files.front() : e.data_file).string().c_str());
    }
    std::printf("%zu entries, %s in %s\n", entries.size(), bytes_text(total).c_str(), cache_folder(dir).string().c_str());
    if (auto old = old_cache_layout(dir)) std::printf("note: %s\n", old->c_str());
    return 0;
  }
  if (action != "clean") a.fail(action.empty() ? "say list or clean" : "unknown action '" + action + "': say list or clean");
  CacheCleaning what;
  if (a.has("older-than")) {
    const double days = a.number("older-than", 0);
    if (!(days >= 0)) a.fail("--older-than must be a number of days ≥ 0, got " + a.str("older-than"));
    what.older_than_days = days;
  }
  if (a.has("max-size")) {
    what.max_bytes = parse_byte_size(a.str("max-size"));
    if (!what.max_bytes) a.fail("--max-size must be a size such as 500M, 20G or a number of bytes, got '" + a.str("max-size") + "'");
  }
  what.all = a.has("all");
  what.dry_run = a.has("dry-run");
  if (!what.all && !what.older_than_days && !what.max_bytes)
    a.fail("say what to remove: --older-than DAYS, --max-size SIZE or --all");
  const CacheCleaned r = clean_cache(dir, what);
  const char* verb = what.dry_run ? "would remove" : "removed";
  for (const auto& e : r.removed)
    std::printf("%s %s %s (%s, %s)\n", verb, e.kind.c_str(), e.key.c_str(), bytes_text(e.bytes).c_str(), days_text(e.age_days).c_str());
  std::printf("%s %zu entries (%s); kept %d (%s) in %s\n", verb, r.removed.size(), bytes_text(r.removed_bytes).c_str(), r.kept,
              bytes_text(r.kept_bytes).c_str(), cache_folder(dir).string().c_str());
  if (r.stale_temporaries)
    std::printf("%s %d half-written files of dvs processes that no longer run\n", verb, r.stale_temporaries);
  if (auto old = old_cache_layout(dir)) std::printf("note: %s\n", old->c_str());
  return 0;
}

}  // namespace dvs::cli
