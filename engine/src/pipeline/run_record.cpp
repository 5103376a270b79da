#include "pipeline/run_record.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "dvs/error.hpp"
#include "dvs/info.hpp"

namespace dvs {

void write_run_record(const std::filesystem::path& path, const RunOptions& o, const RunReport& r, const RunRecordExtras& x) {
  nlohmann::ordered_json j;
  j["dvs_version"] = version();
  j["device"] = x.device;
  j["driver"] = x.driver;
  j["versions"] = {{"dvs", version()}, {"vulkan_api", x.vulkan_api}, {"driver", x.driver}, {"opencv", x.opencv}};
  j["inputs"] = {{"video", o.render.video.string()}, {"depth", o.render.depth.string()},
                 {"depth_values", o.render.metric_depth ? "depth" : "disparity"}, {"trajectory", o.render.trajectory},
                 {"model", o.model.string()}, {"model_hash", x.model_hash}};
  j["settings"] = {{"preset", o.preset},
                   {"prompt", o.prompt},
                   {"negative_prompt", x.negative_prompt},
                   {"frames", o.render.frames},
                   {"height", o.render.height},
                   {"width", o.render.width},
                   {"resize", o.render.squash ? "squash" : "crop"},
                   {"steps", x.steps},
                   {"strength", x.strength},
                   {"t0", x.t0},
                   {"sampling_steps_run", x.sampling_steps},
                   {"inversion_steps", x.inversion_steps},
                   {"k", o.k},
                   {"delta", x.delta},
                   {"guidance", o.guidance},
                   {"dynamic_cfg", x.dynamic_cfg},
                   {"preservation_scale", o.preservation_scale},
                   {"seed", o.seed},
                   {"cache", o.use_cache},
                   {"vae_tiling", o.vae_tiling}};
  if (o.vae_tiling) j["settings"]["vae_tile"] = {o.vae_tile_height, o.vae_tile_width};  // 0 = the VAE's default
  j["lora"] = o.lora.empty() ? nlohmann::ordered_json(nullptr)
                             : nlohmann::ordered_json{{"file", o.lora.string()}, {"scale", o.lora_scale}};
  j["slm_source_fell_back_to_visible"] = x.slm_source_fell_back;
  j["inversion_from_cache"] = r.inversion_from_cache;
  nlohmann::ordered_json stages = nlohmann::ordered_json::object();
  double total = 0;
  for (const auto& s : r.stages) {
    stages[s.stage] = s.seconds;
    total += s.seconds;
  }
  j["seconds"] = stages;
  j["seconds_total"] = total;
  j["peak_device_bytes"] = r.peak_device_bytes;
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  j["peak_host_bytes"] = uint64_t(usage.ru_maxrss) * 1024;  // Linux reports kilobytes
  j["outputs"] = {{"output", r.output_mp4.filename().string()}, {"render", r.render_mp4.filename().string()},
                  {"mask", r.mask_mp4.filename().string()}, {"comparison", r.comparison_mp4.filename().string()}};
  const auto tmp = path.string() + ".partial-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp);
    out << j.dump(2) << "\n";
    out.close();
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw Error(path.string() + ": cannot write run.json");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    const std::string why = ec.message();
    std::filesystem::remove(tmp, ec);
    throw Error(path.string() + ": cannot write run.json (" + why + ")");
  }
}

}  // namespace dvs
