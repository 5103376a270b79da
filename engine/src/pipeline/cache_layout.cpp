#include "pipeline/cache_layout.hpp"

#include <map>
#include <regex>

#include "dvs/error.hpp"
#include "io/cache_root.hpp"

namespace dvs {

std::optional<EntryName> entry_name(const std::string& file_name) {
  // An entry's files: its .npy, the .npy's commit marker (.npy.sum, pipeline/cache_entry.hpp), a latent's .json.
  static const std::regex name("(eps_inv|latent|depth)-([0-9a-f]{16})\\.(npy|npy\\.sum|json)");
  std::smatch m;
  if (!std::regex_match(file_name, m, name)) return std::nullopt;
  return EntryName{m[1].str(), m[2].str(), m[3].str()};
}

std::optional<std::string> old_cache_layout(const std::filesystem::path& cache_dir) {
  const std::filesystem::path root = cache_root(cache_dir);
  std::map<std::string, int> files_by_prefix;
  int files = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(root, ec)) {
    const auto n = entry_name(e.path().filename().string());
    if (n && e.is_regular_file(ec)) files_by_prefix[n->prefix]++, files++;
  }
  if (files == 0) return std::nullopt;
  const std::filesystem::path entries = cache_entries_folder(root);
  std::string globs;
  for (const auto& [prefix, count] : files_by_prefix) globs += " '" + root.string() + "'/" + prefix + "-*";
  std::string what = root.string() + ": the cache folder holds " + std::to_string(files) +
                     " entry files directly in it, where an earlier dvs put them when --cache-dir named the entries' "
                     "own folder; --cache-dir, DVS_CACHE_DIR and the library's cache_dir now all name the cache "
                     "folder, whose entries are in " + entries.string() + ". ";
  if (root.filename() == "inversions")  // the old default's entries folder, given as the cache folder
    return what + "This is the entries folder of the cache folder " + root.parent_path().string() +
           ": give that folder instead (--cache-dir " + root.parent_path().string() + ", or DVS_CACHE_DIR).";
  return what + "Move them there to keep them: mkdir -p '" + entries.string() + "' && mv" + globs + " '" +
         entries.string() + "'/";
}

void refuse_old_cache_layout(const std::filesystem::path& cache_dir) {
  if (auto p = old_cache_layout(cache_dir)) throw Error(*p);
}

}  // namespace dvs
