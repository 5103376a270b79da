// Walking injected faults (engine/src/io/injected_faults.hpp) over the stages of a dvs command: the trace of
// a clean run names every counted event with its stage; a fault is then injected at chosen events, one run
// each, and each outcome (exit status, message, what stayed in --out and in the cache, the clean rerun) is
// checked and kept as a row of the fault matrix that the tests print.
#pragma once
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs::test {

// One line of DVS_FAULTS_TRACE: "<kind> <N> stage=<stage> <where>".
struct FaultEvent {
  std::string kind;  // alloc, submit, write
  long n = 0;
  std::string stage, where;
};

inline std::vector<FaultEvent> read_fault_trace(const std::filesystem::path& file) {
  std::vector<FaultEvent> events;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) {
    std::istringstream s(line);
    FaultEvent e;
    std::string stage;
    s >> e.kind >> e.n >> stage;
    if (stage.rfind("stage=", 0) != 0) continue;
    e.stage = stage.substr(6);
    std::getline(s >> std::ws, e.where);
    events.push_back(e);
  }
  return events;
}

// Per stage, one event of `kind` picked with `seed` (reproducible: the same trace and seed pick the same).
inline std::vector<FaultEvent> pick_fault_events(const std::vector<FaultEvent>& events, const std::string& kind,
                                                 unsigned seed) {
  std::map<std::string, std::vector<FaultEvent>> by_stage;
  std::vector<std::string> order;
  for (const auto& e : events) {
    if (e.kind != kind) continue;
    if (!by_stage.count(e.stage)) order.push_back(e.stage);
    by_stage[e.stage].push_back(e);
  }
  std::mt19937 rng(seed);
  std::vector<FaultEvent> picks;
  for (const auto& stage : order) {
    const auto& all = by_stage[stage];
    picks.push_back(all[rng() % all.size()]);
  }
  return picks;
}

// Files in `dir` and below that a writer leaves only while it writes ("<name>.partial-<pid>", "<name>.tmp…"),
// and cache entries that do not read back whole.
inline std::vector<std::string> torn_files(const std::filesystem::path& dir) {
  std::vector<std::string> bad;
  std::error_code ec;
  if (!std::filesystem::exists(dir)) return bad;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir, ec)) {
    if (!e.is_regular_file()) continue;
    const std::string name = e.path().filename().string();
    if (name.find(".partial") != std::string::npos || name.find(".tmp") != std::string::npos) {
      bad.push_back(e.path().string() + " (a temporary file left behind)");
    } else if (e.path().extension() == ".npy") {
      try {
        (void)read_npy(e.path());
      } catch (const std::exception& x) {
        bad.push_back(e.path().string() + " (does not read: " + x.what() + ")");
      }
    } else if (e.path().extension() == ".json") {
      if (!nlohmann::json::accept(read_text(e.path()))) bad.push_back(e.path().string() + " (not whole JSON)");
    }
  }
  return bad;
}

// Whether a write goes into a cache rather than the command's output: into `cache` (except the depth cache,
// which dvs depth and --depth-model read their depth from) or the Vulkan pipeline cache folder `pipelines`.
// Losing such a write costs time on a later run, not this run: the command goes on (exit 0).
inline bool writes_a_cache(const FaultEvent& e, const std::filesystem::path& cache, const std::filesystem::path& pipelines) {
  const bool depth_entry = std::filesystem::path(e.where).filename().string().rfind("depth-", 0) == 0;
  return (e.where.rfind(cache.string(), 0) == 0 && !depth_entry) || e.where.rfind(pipelines.string(), 0) == 0;
}

// The "dvs: error: ..." line of a command's output ("" when there is none).
inline std::string error_line(const std::string& output) {
  const auto at = output.find("dvs: error: ");
  if (at == std::string::npos) return "";
  return output.substr(at, output.find('\n', at) - at);
}

// One row of the fault matrix.
struct FaultOutcome {
  std::string fault, stage, where;
  int exit_code = -1;
  std::string message;  // the error line, shortened
  std::string kept;     // what --out and the cache held afterwards, and what the clean rerun reused
};

inline std::string shorten(const std::string& s, size_t n) { return s.size() <= n ? s : s.substr(0, n) + "…"; }

inline void print_fault_matrix(const std::string& title, const std::vector<FaultOutcome>& rows) {
  std::cout << "\nFault matrix: " << title << "\n| fault | stage | exit | message | kept |\n|---|---|---|---|---|\n";
  for (const auto& r : rows)
    std::cout << "| " << r.fault << " | " << r.stage << " | " << r.exit_code << " | " << shorten(r.message, 220) << " | "
              << r.kept << " |\n";
  std::set<std::string> shown;  // a few whole messages (one per kind and stage), as the user reads them
  for (const auto& r : rows) {
    const size_t colon = r.fault.find(':');  // "write=3:EIO": the kind and the errno
    const std::string kind = r.fault.substr(0, r.fault.find('=')) + (colon == std::string::npos ? "" : r.fault.substr(colon));
    if (!r.message.empty() && shown.size() < 10 && shown.insert(kind + " " + r.stage).second)
      std::cout << "\n" << r.fault << " (" << r.stage << "):\n  " << r.message << "\n";
  }
  std::cout << std::flush;
}

// How a device fault's message names the trace's stage: "encode" -> "encode stage: ", "after-render" -> "after
// the render stage: ", "start-up" -> "start-up: ".
inline std::string stage_words(const std::string& stage) {
  if (stage == "start-up") return "start-up: ";
  if (stage.rfind("after-", 0) == 0) return "after the " + stage.substr(6) + " stage: ";
  return stage + " stage: ";
}

// What a fault's message must say: the cause in the user's words, and for a device fault the stage.
inline void expect_fault_message(const FaultEvent& e, const std::string& errno_name, const std::string& message,
                                 const std::string& stage_words) {
  EXPECT_EQ(message.find("internal error"), std::string::npos) << message;
  if (e.kind == "alloc") {
    EXPECT_NE(message.find("Out of device memory"), std::string::npos) << message;
    EXPECT_NE(message.find("Try "), std::string::npos) << "says what helps: " << message;
  } else if (e.kind == "submit") {
    EXPECT_NE(message.find("the GPU device was lost"), std::string::npos) << message;
    EXPECT_NE(message.find("What to try"), std::string::npos) << message;
  } else {
    const std::string file = std::filesystem::path(e.where).filename().string();  // its folder may be a staging one
    EXPECT_NE(message.find(file), std::string::npos) << "names the file " << file << ": " << message;
    EXPECT_NE(message.find(errno_name == "ENOSPC" ? "no space left on device" : "an I/O error (EIO)"), std::string::npos)
        << message;
    EXPECT_NE(message.find("run the same command again"), std::string::npos) << message;
  }
  if (e.kind != "write" && !stage_words.empty()) {
    EXPECT_NE(message.find(stage_words), std::string::npos) << message;
  }
}

}  // namespace dvs::test
