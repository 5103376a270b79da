// `dvs batch`: many runs from a JSON-lines file, one process per shard, so a Slurm job array or a Kubernetes
// indexed job spreads a data set over machines with no coordinator: shard i of n takes the jobs whose index
// ≡ i (mod n); a job whose output.mp4 and run.json exist is skipped, so a re-run resumes.
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "args.hpp"
#include "batch_jobs.hpp"
#include "commands.hpp"
#include "dvs/error.hpp"
#include "dvs/pipeline.hpp"
#include "dvs/preflight.hpp"
#include "options.hpp"
#include "run_command.hpp"

namespace dvs::cli {
namespace {

const CommandHelp kBatchHelp{
    "dvs batch JOBS.jsonl [--shard I/N] [dvs run options as defaults]",
    "Runs every job of JOBS.jsonl: one JSON object per line whose keys are dvs run's options without the dashes,\n"
    "e.g. {\"video\": \"a.mp4\", \"depth\": \"a_depth.npz\", \"trajectory\": \"pan_left\", \"prompt\": \"...\", \"out\": \"out/a\"}.\n"
    "Values are strings or numbers; a flag is true/false (\"vae-tiling\": true); intrinsics may be an array.\n"
    "dvs run options given on this command line (e.g. --model DIR --steps 30) are defaults every job can override.\n"
    "Relative paths are relative to the current folder. Blank lines and lines starting with # are not jobs.\n",
    "The whole file is checked first: unknown keys, missing required fields (video, depth, model, prompt, out), bad\n"
    "values, two jobs with the same out folder, and each pending job's preflight (dvs run --help) are reported\n"
    "together and nothing runs. A job whose out folder holds output.mp4 and run.json is skipped (so a killed batch\n"
    "resumes at the job it was in). A job failing while it runs is reported and the batch goes on, as is a job whose\n"
    "out folder another dvs process is writing (refused at once); the exit code is 1 when any job failed. Ctrl-C\n"
    "stops the current job cleanly and exits with 130.\n"};

const OptionGroup kSharding{
    "batch", {{"shard", "I/N", "run only the jobs whose index (0-based, in file order) is I modulo N (default 0/1)"}}};

// The batch's command line: the jobs file, --shard and dvs run's options (defaults of every job). A job's keys are
// read as the same options, after those on the command line (later values win).
std::unique_ptr<Args> batch_arguments(const std::vector<std::string>& argv) {
  std::vector<OptionGroup> groups = run_option_groups();
  groups.push_back(kSharding);
  auto a = std::make_unique<Args>("batch", kBatchHelp, groups);
  a->positional("JOBS.jsonl", "the jobs, one JSON object per line");
  a->parse(argv);
  return a;
}

struct Shard {
  int index = 0, count = 1;
};

Shard parse_shard(const Args& a) {
  const std::string v = a.str("shard", "0/1");
  Shard s;
  char slash = 0, extra = 0;
  std::istringstream in(v);
  if (!(in >> s.index >> slash >> s.count) || slash != '/' || (in >> extra) || s.count < 1 || s.index < 0 ||
      s.index >= s.count)
    a.fail("--shard must be I/N with 0 ≤ I < N, e.g. 0/4, got '" + v + "'");
  return s;
}

// A job is done when its folder holds output.mp4 and run.json and no staging folder (.dvs-partial-*): a job killed
// while it moved its files into place may have left the new output.mp4 beside an earlier run.json; running it
// again completes the move (the files come from the caches) before anything is trusted.
bool finished(const std::filesystem::path& out) {
  std::error_code ec;
  if (!std::filesystem::exists(out / "output.mp4", ec) || !std::filesystem::exists(out / "run.json", ec)) return false;
  for (const auto& e : std::filesystem::directory_iterator(out, ec))
    if (e.path().filename().string().rfind(".dvs-partial-", 0) == 0) return false;
  return true;
}

}  // namespace

int run_batch(const std::vector<std::string>& argv) {
  const std::unique_ptr<Args> command_line = batch_arguments(argv);
  if (command_line->help()) return 0;
  if (!command_line->has("JOBS.jsonl")) command_line->fail("the jobs file is required: dvs batch JOBS.jsonl [options]");
  const std::filesystem::path jobs_file = command_line->str("JOBS.jsonl");
  const Shard shard = parse_shard(*command_line);
  progress_mode(*command_line);  // contradicting defaults are the command line's usage error, not every job's
  const std::vector<Job> jobs = read_jobs(jobs_file);

  // The whole file is checked before the first job runs: every job's keys, required fields and values, that no
  // two jobs share an out folder (the second would be skipped as "already done"), and each of this shard's
  // pending jobs' preflight. Any problem stops the batch with all of them listed.
  struct Planned {
    const Job* job;
    std::string where;
    RunOptions options;
    ProgressMode mode = ProgressMode::bar;
  };
  std::vector<Planned> planned;
  std::vector<std::string> problems;
  std::map<std::string, std::string> outs;  // normalised out folder -> the job that writes it
  for (const Job& job : jobs) {
    const std::string where = "job " + std::to_string(job.index) + " (" + jobs_file.filename().string() + ":" +
                              std::to_string(job.line) + ")";
    try {
      std::vector<std::string> args = argv;  // later values win: the job's own over the command line's defaults
      const auto own = job_arguments(job.spec);
      args.insert(args.end(), own.begin(), own.end());
      const std::unique_ptr<Args> job_args = batch_arguments(args);
      const Args& a = *job_args;
      std::string missing;
      const bool no_depth = a.str("depth").empty() && a.str("depth-model").empty();  // either gives the depth
      for (const char* key : {"video", "depth", "model", "prompt", "out"})
        if (key == std::string("depth") ? no_depth : a.str(key).empty())
          missing += std::string(missing.empty() ? "" : ", ") + "\"" + key + "\"";
      if (!missing.empty()) {
        problems.push_back(where + ": missing required " + missing + " (a key of the job or a --option of dvs batch" +
                           (no_depth ? "; \"depth-model\": FILE.pth estimates the depth instead of \"depth\")" : ")"));
        continue;
      }
      Planned p{&job, where, parse_run_options(a), progress_mode(a)};
      std::filesystem::path out_path = std::filesystem::absolute(p.options.render.out_dir).lexically_normal();
      if (!out_path.has_filename()) out_path = out_path.parent_path();  // "out/" is "out"
      const std::string out = std::filesystem::weakly_canonical(out_path).string();
      if (auto [it, fresh] = outs.emplace(out, where); !fresh) {
        problems.push_back(where + ": \"out\" " + p.options.render.out_dir.string() + " is also the out folder of " +
                           it->second + "; give every job its own out folder");
        continue;
      }
      if (job.index % shard.count != shard.index) continue;
      if (!finished(p.options.render.out_dir)) {
        const PreflightReport r = preflight(p.options, JobKind::run);
        for (const auto& problem : r.problems) problems.push_back(where + ": " + problem);
      }
      planned.push_back(std::move(p));
    } catch (const Error& e) {
      problems.push_back(where + ": " + e.what());
    }
  }
  if (!problems.empty()) {
    std::string m = jobs_file.string() + ": " + std::to_string(problems.size()) + " problem" + (problems.size() == 1 ? "" : "s") +
                    " found before running anything; no job was run:";
    for (const auto& p : problems) m += "\n  - " + p;
    throw Error(m);
  }

  int done = 0, skipped = 0, failed = 0, mine = 0;
  for (const Planned& p : planned) {
    ++mine;
    const RunOptions& o = p.options;
    try {
      if (finished(o.render.out_dir)) {
        std::cout << "dvs batch: " << p.where << ": skipped, " << o.render.out_dir.string() << " is already done\n";
        ++skipped;
        continue;
      }
      std::cout << "dvs batch: " << p.where << ": running -> " << o.render.out_dir.string() << "\n" << std::flush;
      execute_run(o, p.mode);
      ++done;
    } catch (const Cancelled&) {
      throw;
    } catch (const Error& e) {
      std::cerr << "dvs batch: " << p.where << " failed: " << e.what() << "\n";
      ++failed;
    }
  }
  std::cout << "dvs batch: shard " << shard.index << "/" << shard.count << ": " << mine << " of " << jobs.size()
            << " jobs: " << done << " done, " << skipped << " skipped (already done), " << failed << " failed\n";
  return failed ? 1 : 0;
}

}  // namespace dvs::cli
