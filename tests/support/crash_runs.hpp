// Kill-and-rerun helpers for the robustness tests (tests/test_crash_*.cpp, tests/test_concurrent_*.cpp): a
// command run with the crash-point switches (engine/src/io/crash_points.hpp), its trace read back, kill points
// picked from it (seeded), and the checks every rerun must pass (folders' files, leftovers, cache entries).
#pragma once
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "pipeline/cache_entry.hpp"
#include "support/files.hpp"

namespace dvs::test {

struct TracePoint {
  long n = 0;        // 1-based, in the order the process reached them
  std::string name;  // "stage-begin:render", "step:sample:2", "publish-before:output.mp4", ...
  std::string stage; // the stage it lies in: the last "stage-begin" before it ("start" before the first), or
                     // "cache" (a cache entry's write) or "publish" (the job's files moved into place)
};

inline std::vector<TracePoint> read_trace(const std::filesystem::path& file) {
  std::vector<TracePoint> points;
  std::ifstream in(file);
  std::string stage = "start";
  for (TracePoint p; in >> p.n >> p.name;) {
    if (p.name.rfind("stage-begin:", 0) == 0) stage = p.name.substr(12);
    if (p.name == "depth-estimate-begin") stage = "estimate";  // dvs depth has no stages of its own
    p.stage = p.name.rfind("publish", 0) == 0 ? "publish" : p.name.rfind("cache-", 0) == 0 ? "cache" : stage;
    points.push_back(p);
  }
  return points;
}

// A `dvs run` command line of PipelineInputs without progress lines (warnings still go to stderr).
inline std::string without_progress(std::string cmd) {
  const size_t at = cmd.find("--progress json");
  if (at != std::string::npos) cmd.replace(at, 15, "--progress none");
  return cmd;
}

// `cmd` with the trace switch (and, with at > 0, the kill switch) set; through env, so it also works after exec.
inline std::string with_crash(const std::string& cmd, const std::filesystem::path& trace, long at = 0) {
  return "env DVS_CRASH_TRACE=" + trace.string() + (at > 0 ? " DVS_CRASH_AT=" + std::to_string(at) : "") + " " + cmd;
}

// The seed of the kill-point choice: DVS_CRASH_SEED when set (to replay another choice), else 23.
inline unsigned crash_seed() {
  const char* s = std::getenv("DVS_CRASH_SEED");
  return s && *s ? unsigned(std::strtoul(s, nullptr, 10)) : 23u;
}

// One point chosen at random in each stage of the trace, and every point named in `always` (the ones whose
// timing is the point: half-published cache entries, a commit half done); sorted, no repeats.
inline std::vector<long> pick_kill_points(const std::vector<TracePoint>& trace, unsigned seed,
                                          const std::vector<std::string>& always) {
  std::map<std::string, std::vector<long>> by_stage;
  std::vector<long> picked;
  for (const auto& p : trace) {
    by_stage[p.stage].push_back(p.n);
    if (std::find(always.begin(), always.end(), p.name) != always.end()) picked.push_back(p.n);
  }
  std::mt19937 rng(seed);
  for (const auto& [stage, ns] : by_stage) picked.push_back(ns[std::uniform_int_distribution<size_t>(0, ns.size() - 1)(rng)]);
  std::sort(picked.begin(), picked.end());
  picked.erase(std::unique(picked.begin(), picked.end()), picked.end());
  return picked;
}

// The files of `dir` a user sees (not hidden ones, not temporaries), by name, with their bytes.
inline std::map<std::string, std::string> visible_files(const std::filesystem::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& name : files_in(dir))
    if (name[0] != '.' && name.find(".tmp-") == std::string::npos && name.find(".partial-") == std::string::npos &&
        std::filesystem::is_regular_file(dir / name))
      files[name] = read_text(dir / name);
  return files;
}

// What a finished job must not leave in a folder: staging folders, its lock, temporary files.
inline std::vector<std::string> leftovers(const std::filesystem::path& dir) {
  std::vector<std::string> found;
  for (const auto& name : files_in(dir))
    if (name.rfind(".dvs-partial-", 0) == 0 || name == ".dvs-lock" || name.find(".tmp-") != std::string::npos ||
        name.find(".partial-") != std::string::npos)
      found.push_back(name);
  return found;
}

// The committed entries (those with a commit marker) of a cache folder that do not verify.
inline std::vector<std::string> damaged_entries(const std::filesystem::path& cache_dir) {
  std::vector<std::string> damaged;
  if (!std::filesystem::is_directory(cache_dir)) return damaged;
  for (const auto& e : std::filesystem::recursive_directory_iterator(cache_dir)) {
    if (e.path().extension() != ".npy" || !cache_entry_exists(e.path())) continue;
    const CacheEntryRead r = read_cache_entry(e.path());
    if (!r.tensor) damaged.push_back(e.path().filename().string() + ": " + r.problem);
  }
  return damaged;
}

// run.json without what differs between two runs of one job by design: timings, memory peaks, whether caches
// were used (and so which weights were loaded at all), and the folders (out, cache) it was given.
inline nlohmann::json stable_record(const std::string& run_json_text) {
  nlohmann::json j = nlohmann::json::parse(run_json_text);
  for (const char* k : {"seconds", "seconds_total", "peak_device_bytes", "peak_host_bytes", "inversion_from_cache"}) j.erase(k);
  if (j.contains("inputs") && j["inputs"].is_object()) j["inputs"].erase("out");
  if (j.contains("settings") && j["settings"].is_object()) j["settings"].erase("cache_dir");
  if (j.contains("latent") && j["latent"].is_object()) j["latent"].erase("reused"), j["latent"].erase("path");
  if (j.contains("depth_estimate") && j["depth_estimate"].is_object())
    for (const char* k : {"from_cache", "seconds", "estimate"}) j["depth_estimate"].erase(k);
  // A run that takes its latent from the cache loads neither model: "not loaded" there, "resident" in a run alone.
  if (j.contains("weights") && j["weights"].is_object()) j["weights"].erase("transformer"), j["weights"].erase("text_encoder");
  return j;
}

}  // namespace dvs::test
