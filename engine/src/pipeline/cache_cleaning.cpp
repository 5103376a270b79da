// `dvs cache`: the cache folder's entries listed and trimmed. Every writer (write_cache_entry, LatentCache::store)
// writes under a temporary name (NAME.tmp-PID-N, NAME.partial-PID) and renames the
// complete file into place, so a file with an entry's own name is always whole, and one with a temporary name
// belongs to a writer: only its writer's death (no such process) makes it removable.
#include "dvs/cache.hpp"


#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <regex>
#include <string>

#include "io/cache_root.hpp"
#include "pipeline/cache_layout.hpp"
#include "pipeline/run_outputs.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

double days_since(fs::file_time_type t) {
  return std::chrono::duration<double>(fs::file_time_type::clock::now() - t).count() / 86400.0;
}

// The pid in a temporary name (".tmp-PID-N", ".partial-PID"), or 0 when the name is not one.
long writer_pid(const std::string& name) {
  for (const char* mark : {".tmp-", ".partial-"}) {
    const size_t at = name.rfind(mark);
    if (at != std::string::npos) return std::strtol(name.c_str() + at + std::char_traits<char>::length(mark), nullptr, 10);
  }
  return 0;
}

const char* kind_of(const std::string& prefix) {
  if (prefix == "eps_inv") return "inversion";
  return prefix == "depth" ? "depth" : "latent";
}

}  // namespace

fs::path cache_folder(const fs::path& cache_dir) { return cache_entries_folder(cache_root(cache_dir)); }

std::vector<CacheEntry> list_cache(const fs::path& cache_dir) {
  std::map<std::string, CacheEntry> entries;  // by "<prefix>-<key>"
  std::map<std::string, fs::file_time_type> newest;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(cache_folder(cache_dir), ec)) {
    const std::string name = e.path().filename().string();
    const std::optional<EntryName> n = entry_name(name);
    if (!n || !e.is_regular_file(ec)) continue;
    const std::string id = n->prefix + "-" + n->key;
    CacheEntry& c = entries[id];
    c.kind = kind_of(n->prefix);
    c.key = n->key;
    c.files.push_back(e.path());
    if (n->ending == "npy") c.data_file = e.path();
    const uintmax_t size = e.file_size(ec);
    if (!ec) c.bytes += size;
    const auto t = e.last_write_time(ec);
    if (!newest.count(id) || t > newest[id]) newest[id] = t;
  }
  std::vector<CacheEntry> list;
  for (auto& [id, c] : entries) {
    // A latent is its .npy with its .json; a .json alone is the first half of a store still under way (or of
    // one that failed): not an entry yet.
    if (c.kind == "latent" && c.data_file.empty()) continue;
    std::sort(c.files.begin(), c.files.end(), [](const fs::path& a, const fs::path& b) {
      return a.extension() == ".sum" && b.extension() != ".sum";  // the marker first: removed first, the entry is gone
    });
    c.age_days = days_since(newest[id]);
    list.push_back(std::move(c));
  }
  std::sort(list.begin(), list.end(), [](const CacheEntry& a, const CacheEntry& b) { return a.age_days < b.age_days; });
  return list;
}

CacheCleaned clean_cache(const fs::path& cache_dir, const CacheCleaning& what) {
  CacheCleaned r;
  const std::vector<CacheEntry> entries = list_cache(cache_dir);  // most recently used first
  uint64_t total = 0;
  for (const auto& c : entries) total += c.bytes;
  // Decided from the oldest: past --older-than, or while the rest is over --max-size.
  std::vector<bool> remove(entries.size(), false);
  uint64_t left = total;
  for (size_t i = entries.size(); i-- > 0;) {
    const CacheEntry& c = entries[i];
    const bool old = what.older_than_days && c.age_days > *what.older_than_days;
    const bool over = what.max_bytes && left > *what.max_bytes;
    if (what.all || old || over) {
      remove[i] = true;
      left -= c.bytes;
    }
  }
  for (size_t i = 0; i < entries.size(); ++i) {
    if (!remove[i]) {
      r.kept++, r.kept_bytes += entries[i].bytes;
      continue;
    }
    if (!what.dry_run)
      for (const auto& f : entries[i].files) {
        std::error_code ec;
        fs::remove(f, ec);
      }
    r.removed.push_back(entries[i]);
    r.removed_bytes += entries[i].bytes;
  }
  // Half-written files whose writer is gone (killed, power loss): never a live writer's.
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(cache_folder(cache_dir), ec)) {
    const long pid = writer_pid(e.path().filename().string());
    if (!process_is_gone(pid) || !e.is_regular_file(ec)) continue;
    r.stale_temporaries++;
    if (!what.dry_run) fs::remove(e.path(), ec);
  }
  return r;
}

std::optional<uint64_t> parse_byte_size(const std::string& text) {
  static const std::regex size("\\s*([0-9]+(?:\\.[0-9]+)?)\\s*([kKmMgGtT]?)(i?[bB])?\\s*");
  std::smatch m;
  if (!std::regex_match(text, m, size)) return std::nullopt;
  double v = std::strtod(m[1].str().c_str(), nullptr);
  const std::string unit = m[2].str();
  const std::string units = "kmgt";
  if (!unit.empty()) v *= std::pow(1024.0, double(units.find(char(std::tolower(unit[0]))) + 1));
  if (!(v < 1.8e19)) return std::nullopt;
  return uint64_t(std::llround(v));
}

}  // namespace dvs
