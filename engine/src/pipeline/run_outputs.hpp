// The files one job writes into its output folder, written first into a staging folder inside it
// (DIR/.dvs-partial-<pid>-<n>/, same file system) and moved into place by commit() only when the job has
// finished. A job that fails or is cancelled before commit() removes its staging folder and leaves every file
// an earlier job finished in DIR exactly as it was: results are never destroyed by a later failure.
// commit() first writes the list of its files (COMMIT, renamed into the staging folder), then moves them: a
// process killed in between leaves a staging folder that the next job in DIR completes (recover_staging), so a
// folder holds either all of the earlier job's files or, once COMMIT exists, all of the new one's.
// Jobs hold DIR's lock (output_lock.hpp) while they stage and commit.
#pragma once
#include <filesystem>
#include <typeinfo>
#include <string>
#include <vector>

#include "dvs/error.hpp"

namespace dvs {

// With DIR's lock held (`locked`), every staging folder in `dir` is a dead process's; without it (a file system
// that cannot lock) only those named by a pid that does not exist on this machine are. A dead process's staging
// folder with its COMMIT written is moved into place (rolled forward); any other is removed.
void recover_staging(const std::filesystem::path& dir, bool locked = true);

// True when no process with this pid exists on this machine: the writer a staging or temporary name names was
// killed, and what it left may be removed.
bool process_is_gone(long pid);

// Removes the temporary files a killed writer of `file` left beside it (NAME.tmp-PID-N, NAME.partial-PID, the
// names write_npy, write_npz and the cache use) when no process PID exists on this machine.
void remove_stale_temporaries(const std::filesystem::path& file);

// The output folder (and any missing folders above it) a job is about to create: a job that fails removes the
// ones it created itself once they are empty again, so a failed run does not leave an empty --out behind.
// A folder that was there before, or that holds anything (an earlier run's files), is never removed.
class CreatedFolders {
 public:
  explicit CreatedFolders(const std::filesystem::path& dir);  // notes which of dir and its parents do not exist yet
  ~CreatedFolders();                                          // removes them, deepest first, unless keep() was called
  CreatedFolders(const CreatedFolders&) = delete;
  CreatedFolders& operator=(const CreatedFolders&) = delete;
  void keep() { missing_.clear(); }

 private:
  std::vector<std::filesystem::path> missing_;  // deepest first
};

class RunOutputs {
 public:
  explicit RunOutputs(std::filesystem::path dir);  // creates the staging folder
  ~RunOutputs();                                   // removes it (with anything not committed)
  RunOutputs(const RunOutputs&) = delete;
  RunOutputs& operator=(const RunOutputs&) = delete;

  // Where to write `name` now (in the staging folder).
  std::filesystem::path add(const std::string& name);
  // Where `name` will be once committed: DIR/name.
  std::filesystem::path final_path(const std::string& name) const { return dir_ / name; }
  // Runs `writes` (the writes of the added files); a plain dvs::Error they throw (a full disk, an I/O error) is
  // rethrown naming DIR/name instead of the staging folder's path, which the user never sees (it is removed).
  template <class Writes>
  void write(Writes&& writes) const {
    try {
      writes();
    } catch (const Error& e) {
      if (typeid(e) != typeid(Error)) throw;  // device errors and cancellation keep their type
      throw Error(with_final_paths(e.what()), e.kind());
    }
  }
  std::string with_final_paths(std::string text) const;  // every staging/NAME in text as DIR/NAME
  // Renames every added file into DIR, in the order they were added (so the one added last, e.g. run.json,
  // marks the folder finished), replacing files of the same names. Throws dvs::Error naming a file that
  // could not be moved.
  void commit();

 private:
  std::filesystem::path dir_, staging_;
  std::vector<std::string> names_;
  bool journaled_ = false;  // COMMIT is written: the staging folder is left for recover_staging if commit() fails
};

}  // namespace dvs
