// The names of the cache's entry files, and the layout before the cache folder had one meaning: a dvs whose
// --cache-dir named the entries' own folder left them directly in that folder, where the entries now live in its
// inversions/ folder (io/cache_root.hpp). Such entries are named with what to do, never silently computed again.
#pragma once
#include <filesystem>
#include <optional>
#include <string>

#include "dvs/cache.hpp"  // old_cache_layout

namespace dvs {

// An entry file's name split: prefix (eps_inv, latent, depth), key (16 hex digits), ending (npy, npy.sum, json).
struct EntryName {
  std::string prefix, key, ending;
};
std::optional<EntryName> entry_name(const std::string& file_name);

// Throws dvs::Error with old_cache_layout's message: called before a job reads or writes the cache.
void refuse_old_cache_layout(const std::filesystem::path& cache_dir);

}  // namespace dvs
