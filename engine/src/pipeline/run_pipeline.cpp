// `dvs run` on files: the run's ends (pipeline/run_stages.hpp) that decode a video and read a depth file, key the
// caches by the files' fingerprints, and write the videos and run.json into the output folder, staged so that a
// failed run leaves the folder's earlier results as they were.
#include <optional>

#include "io/public_call.hpp"
#include "dvs/pipeline.hpp"
#include "io/video.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/memory_advice.hpp"
#include "pipeline/output_lock.hpp"
#include "pipeline/preflight.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/run_outputs.hpp"
#include "pipeline/run_record.hpp"
#include "pipeline/run_stages.hpp"

namespace dvs {
namespace {

class FileEnds : public RunEnds {
 public:
  void check(const RunOptions& o) override {
    require_preflight(o, JobKind::run);
    out_dir_ = o.render.out_dir;
    out_lock_.emplace(out_dir_);  // held to the end: one process writes into a folder at a time
  }
  std::vector<std::string> input_key(const RunOptions& o) const override { return file_input_key(o); }
  RenderedInput input(vk::Context& ctx, const RunOptions& o, StageTracker& stages) override {
    return render_for_model(ctx, o, stages);
  }
  void write(vk::Context&, const RunResults& r, RunReport& report, StageTracker& stages) override {
    const RenderedInput& in = r.in;
    stages.begin("write", "writing the videos");
    files_.emplace(out_dir_);
    RunOutputs& files = *files_;  // staged: earlier results in the folder stay until this run is complete
    const auto render_mp4 = files.add("render.mp4"), mask_mp4 = files.add("mask.mp4"),
               comparison_mp4 = files.add("comparison.mp4"), output_mp4 = files.add("output.mp4");
    run_json_ = files.add("run.json");  // last: moved into place last, it marks the folder finished
    files.write([&] {
      write_video(render_mp4, in.render, in.fps);
      write_video(mask_mp4, mask_as_video(in.mask), in.fps);
      write_video(comparison_mp4, hstack_videos({&in.rgb, &in.render, &r.output}), in.fps);
      write_video(output_mp4, r.output, in.fps);
    });
    report.render_mp4 = files.final_path("render.mp4");
    report.mask_mp4 = files.final_path("mask.mp4");
    report.comparison_mp4 = files.final_path("comparison.mp4");
    report.output_mp4 = files.final_path("output.mp4");
    report.run_json = files.final_path("run.json");
    stages.end();
  }
  void finish(const RunOptions& o, const RunReport& report, const RunRecordExtras& extras,
              StageTracker& stages) override {
    files_->write([&] { write_run_record(run_json_, o, report, extras); });
    stages.check_cancelled();  // the last chance before the job's files replace anything
    files_->commit();
  }

 private:
  std::filesystem::path out_dir_;
  std::optional<OutputLock> out_lock_;
  std::optional<RunOutputs> files_;
  std::filesystem::path run_json_;
};

}  // namespace

RunReport run_pipeline(const RunOptions& o, const ProgressFn& progress, const CancelFn& cancelled) {
  return public_call("dvs::run_pipeline", [&]() -> RunReport {
    StageTracker stages(progress, cancelled);
    stages.set_memory_advice([&o](const std::string& stage) { return out_of_memory_advice(o, stage); });
    CreatedFolders out_folder(o.render.out_dir);  // removed again if the run fails before filling it
    FileEnds ends;
    RunReport report = stages.run([&] { return run_stages(o, ends, nullptr, stages); });
    out_folder.keep();
    return report;
  });
}

}  // namespace dvs
