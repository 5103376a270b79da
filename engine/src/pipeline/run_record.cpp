#include "pipeline/run_record.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <nlohmann/json.hpp>

#include "io/public_call.hpp"
#include "dvs/error.hpp"
#include "io/json_file.hpp"
#include "dvs/info.hpp"
#include "io/disk_space.hpp"
#include "io/injected_faults.hpp"

namespace dvs {

void write_run_record(const std::filesystem::path& path, const RunOptions& o, const RunReport& r, const RunRecordExtras& x) {
  nlohmann::ordered_json j;
  j["dvs_version"] = version();
  j["device"] = x.device;
  j["driver"] = x.driver;
  j["versions"] = {{"dvs", version()}, {"vulkan_api", x.vulkan_api}, {"driver", x.driver}, {"opencv", x.opencv}};
  const auto abs = [](const std::filesystem::path& p) { return p.empty() ? std::string() : std::filesystem::absolute(p).lexically_normal().string(); };
  // A trajectory is a preset name or a file: a file is recorded by its absolute path.
  const std::string& traj = o.render.trajectory;
  const bool traj_file = std::filesystem::exists(traj.substr(0, traj.find(':')));
  j["inputs"] = {{"video", abs(o.render.video)}, {"depth", abs(o.render.depth)},
                 {"depth_values", o.render.metric_depth ? "depth" : "disparity"},
                 {"trajectory", traj_file ? abs(traj) : traj}, {"trajectory_poses_hash", x.poses_hash},
                 {"model", abs(o.model)}, {"model_hash", x.model_hash}, {"out", abs(o.render.out_dir)}};
  if (!o.render.depth_model.empty()) {
    j["inputs"]["depth_model"] = abs(o.render.depth_model);
    j["inputs"]["depth_input_size"] = o.render.depth_input_size;
    j["depth_estimate"] = nlohmann::ordered_json::parse(x.depth_estimate.dump());
  }
  j["settings"] = {{"preset", o.preset},
                   {"prompt", o.prompt},
                   {"negative_prompt", x.negative_prompt},
                   {"frames", o.render.frames},
                   {"height", o.render.height},
                   {"width", o.render.width},
                   {"resize", o.render.squash ? "squash" : "crop"},
                   {"intrinsics", x.intrinsics},
                   {"points", o.render.hard_points},
                   {"trim_depth", o.render.trim_depth},
                   {"depth_fit", o.render.depth_fit},
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
                   {"cache_dir", x.cache_dir.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(abs(x.cache_dir))},
                   {"vae_tiling", o.vae_tiling}};
  if (!x.cache_problem.empty()) j["cache_problem"] = x.cache_problem;
  if (o.vae_tiling) j["settings"]["vae_tile"] = {x.vae_tile_height, x.vae_tile_width};
  j["weights"] = x.weights.is_null() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json::parse(x.weights.dump());
  j["lora"] = o.lora.empty() ? nlohmann::ordered_json(nullptr)
                             : nlohmann::ordered_json{{"file", abs(o.lora)}, {"scale", o.lora_scale}};
  j["trajectory_poses"] = x.poses;
  j["slm_source_fell_back_to_visible"] = x.slm_source_fell_back;
  j["inversion_from_cache"] = r.inversion_from_cache;
  j["latent"] = x.latent.is_null() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json::parse(x.latent.dump());
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
    int err = out ? 0 : errno;  // the failed write(2)'s, which the stream leaves in errno
    if (const int injected = faults::write_error(path); injected && out) out.setstate(std::ios::badbit), err = injected;
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw Error(path.string() + ": cannot write run.json: " +
                  (err ? write_error_note(err, path.parent_path()) : std::string("an I/O error")));
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

std::vector<std::string> run_record_arguments(const std::filesystem::path& run_json) {
  return public_call("dvs::run_record_arguments", [&]() -> std::vector<std::string> {
    nlohmann::json j;
    try {
      std::ifstream in(run_json);
      if (!in) throw Error(run_json.string() + ": cannot read it (give --from RUN.json, a run.json dvs run wrote)");
      const std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      // dump() below recurses: a hostile file must not nest deep enough to exhaust the stack (run.json needs 3 levels)
      if (json_nests_deeper_than(content, 64))
        throw Error(run_json.string() + ": not a run.json (JSON nests deeper than 64 levels)");
      j = nlohmann::json::parse(content);
    } catch (const nlohmann::json::exception& e) {
      throw Error(run_json.string() + ": not a run.json (" + e.what() + ")");
    }
    const auto section = [&](const char* name) -> const nlohmann::json& {
      if (!j.contains(name) || !j[name].is_object())
        throw Error(run_json.string() + ": no \"" + std::string(name) + "\" object: not a run.json dvs run wrote");
      return j[name];
    };
    const nlohmann::json &in = section("inputs"), &st = section("settings");
    std::vector<std::string> args;
    const auto text = [&](const nlohmann::json& obj, const char* key, const char* option) {
      if (!obj.contains(key) || obj[key].is_null()) throw Error(run_json.string() + ": \"" + key + "\" is missing");
      const auto& v = obj[key];
      args.push_back(std::string("--") + option);
      args.push_back(v.is_string() ? v.get<std::string>() : v.dump());
    };
    const auto flag = [&](const nlohmann::json& obj, const char* key, const char* option) {
      if (obj.contains(key) && obj[key].is_boolean() && obj[key].get<bool>()) args.push_back(std::string("--") + option);
    };
    text(in, "video", "video");
    if (in.contains("depth_model")) {  // the depth was estimated: estimate it again (or find it in the cache)
      text(in, "depth_model", "depth-model");
      if (in.contains("depth_input_size")) text(in, "depth_input_size", "depth-input-size");
    } else {
      text(in, "depth", "depth");
    }
    // With --depth-model the checkpoint decides depth or disparity (--metric-depth is refused there).
    if (in.contains("depth_values") && in["depth_values"] == "depth" && !in.contains("depth_model")) args.push_back("--metric-depth");
    text(in, "trajectory", "trajectory");
    text(in, "model", "model");
    text(in, "out", "out");
    text(st, "preset", "preset");
    text(st, "prompt", "prompt");
    if (st.contains("negative_prompt") && st["negative_prompt"].is_string() && !st["negative_prompt"].get<std::string>().empty())
      text(st, "negative_prompt", "negative-prompt");
    text(st, "frames", "frames");
    for (const char* key : {"height", "width"})
      if (!st.contains(key) || !st[key].is_number_integer())
        throw Error(run_json.string() + ": \"" + key + "\" is missing or not a whole number");
    args.push_back("--size");
    args.push_back(st["height"].dump() + "x" + st["width"].dump());
    text(st, "resize", "resize");
    if (st.contains("intrinsics") && st["intrinsics"].is_array() && st["intrinsics"].size() == 4) {
      std::string k;
      for (const auto& v : st["intrinsics"]) k += (k.empty() ? "" : ",") + v.dump();
      args.insert(args.end(), {"--intrinsics", k});
    }
    flag(st, "points", "points");
    flag(st, "trim_depth", "trim-depth");
    text(st, "depth_fit", "depth-fit");
    for (const auto& [key, option] : std::vector<std::pair<const char*, const char*>>{
             {"steps", "steps"}, {"strength", "strength"}, {"inversion_steps", "inversion-steps"}, {"k", "k"},
             {"delta", "delta"}, {"guidance", "guidance"}, {"preservation_scale", "preservation-scale"}, {"seed", "seed"}})
      text(st, key, option);
    if (st.contains("dynamic_cfg") && st["dynamic_cfg"].is_boolean())
      args.insert(args.end(), {"--dynamic-cfg", st["dynamic_cfg"].get<bool>() ? "on" : "off"});
    if (st.contains("cache") && st["cache"].is_boolean() && !st["cache"].get<bool>()) args.push_back("--no-cache");
    if (st.contains("cache_dir") && st["cache_dir"].is_string()) text(st, "cache_dir", "cache-dir");
    if (st.contains("vae_tile") && st["vae_tile"].is_array() && st["vae_tile"].size() == 2)
      args.insert(args.end(), {"--vae-tile", st["vae_tile"][0].dump() + "x" + st["vae_tile"][1].dump()});
    // The weights' residency only where the run asked for one (auto decides again on the device of the re-run).
    if (j.contains("weights") && j["weights"].is_object() && j["weights"].contains("requested") &&
        j["weights"]["requested"].is_string() && j["weights"]["requested"] != "auto")
      args.insert(args.end(), {"--weights", j["weights"]["requested"].get<std::string>()});
    if (j.contains("lora") && j["lora"].is_object()) {
      const nlohmann::json& lora = j["lora"];
      if (!lora.contains("file") || !lora["file"].is_string() || !lora.contains("scale") || !lora["scale"].is_number())
        throw Error(run_json.string() + ": \"lora\" must hold \"file\" (a path) and \"scale\" (a number)");
      args.insert(args.end(), {"--lora", lora["file"].get<std::string>() + ":" + lora["scale"].dump()});
    }
    return args;
  });
}

}  // namespace dvs
