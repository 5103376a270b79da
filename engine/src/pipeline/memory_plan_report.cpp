// The memory plan as a user reads it: the table `dvs plan` prints and its --json form.
#include <cstdio>
#include <sstream>

#include "pipeline/memory_plan.hpp"

namespace dvs::pipeline {

using nlohmann::json;

namespace {

json stage_json(const StageMemory& s) {
  return {{"name", s.name}, {"what", s.what}, {"working_bytes", s.working}, {"io_bytes", s.io}, {"total_bytes", s.total()}};
}

int64_t pieces(uint64_t amount, uint64_t limit) { return limit == 0 ? 1 : int64_t((amount + limit - 1) / limit); }

// One stage's largest tensor against the limits: how many bindings / texel views ops split it into, and
// whether it fits one allocation (it must: the stage cannot run otherwise).
std::string limits_verdict(const StageMemory& s, const PlanLimits& l) {
  std::string v = "largest tensor " + format_plan_bytes(s.largest_bytes) + " (" + s.largest_what + "): ";
  const int64_t b = pieces(s.largest_bytes, l.binding), t = pieces(uint64_t(s.largest_elements), l.texels);
  v += b > 1 ? "split into " + std::to_string(b) + " bindings" : std::string("one binding");
  v += ", " + std::to_string(s.largest_elements) + " texels: " +
       (t > 1 ? "split into " + std::to_string(t) + " texel views" : std::string("one texel view"));
  v += s.largest_bytes > l.alloc ? ", allocation OVER maxMemoryAllocationSize: cannot run" : ", allocation fits";
  return v;
}

// The render's own verdict: it splits a clip over frames (never a tensor over bindings or texel views).
std::string render_verdict(const geometry::SplatFootprint& r) {
  if (!r.problem.empty()) return "CANNOT RUN: " + r.problem;
  return "chunks of " + std::to_string(r.chunk_frames) + " frames, largest buffer " + format_plan_bytes(r.largest.bytes) +
         " (" + r.largest.what + "): one binding, allocation fits";
}

json limits_json(const StageMemory& s, const PlanLimits& l) {
  return {{"largest_tensor_bytes", s.largest_bytes}, {"largest_tensor", s.largest_what},
          {"largest_texel_view", s.largest_elements}, {"bindings", pieces(s.largest_bytes, l.binding)},
          {"texel_views", pieces(uint64_t(s.largest_elements), l.texels)}, {"allocation_fits", s.largest_bytes <= l.alloc}};
}

// One component's block weights: where they live in this plan, and what streaming them costs.
std::string stream_lines(const WeightStreamPlan& s, WeightsChoice choice) {
  std::ostringstream o;
  char line[320];
  const char* how = s.streamed ? (choice == WeightsChoice::stream ? "streamed (--weights stream)" : "streamed (auto: resident does not fit)")
                               : (choice == WeightsChoice::resident ? "resident (--weights resident)" : "resident");
  std::snprintf(line, sizeof line, "  %-14s %d blocks, %s\n", s.component.c_str(), int(s.blocks), how);
  o << line;
  std::snprintf(line, sizeof line,
                "    streamed: %d slots x %s + %s resident = %s on the device; host copy %s (pinned); uploads %s %s",
                s.slots, format_plan_bytes(s.slot_bytes).c_str(), format_plan_bytes(s.resident_bytes).c_str(),
                format_plan_bytes(s.device_bytes()).c_str(), format_plan_bytes(s.host_bytes).c_str(),
                format_plan_bytes(s.host_bytes).c_str(), s.calls.c_str());
  o << line;
  if (s.call_upload_seconds) {
    std::snprintf(line, sizeof line, " (%.3g s)", *s.call_upload_seconds);
    o << line;
  }
  o << "\n    " << s.verdict << "\n";
  return o.str();
}

json stream_json(const WeightStreamPlan& s) {
  auto opt = [](const std::optional<double>& v) { return v ? json(*v) : json(nullptr); };
  return {{"component", s.component},
          {"streamed", s.streamed},
          {"blocks", s.blocks},
          {"slots", s.slots},
          {"slot_bytes", s.slot_bytes},
          {"resident_bytes", s.resident_bytes},
          {"device_bytes", s.device_bytes()},
          {"host_bytes", s.host_bytes},
          {"uploaded_bytes_per_call", s.host_bytes},
          {"calls", s.calls},
          {"block_flops", s.block_flops},
          {"call_upload_seconds", opt(s.call_upload_seconds)},
          {"block_upload_seconds", opt(s.block_upload_seconds)},
          {"break_even_flops", opt(s.break_even_flops)},
          {"compute_longer_than_upload", s.compute_longer ? json(*s.compute_longer) : json(nullptr)},
          {"hides", s.hides ? json(*s.hides) : json(nullptr)},
          {"verdict", s.verdict}};
}

}  // namespace

std::string format_plan_bytes(uint64_t bytes) {
  char buf[64];
  if (bytes >= (uint64_t(1) << 30)) std::snprintf(buf, sizeof buf, "%.2f GiB", double(bytes) / double(1ull << 30));
  else if (bytes >= (uint64_t(1) << 20)) std::snprintf(buf, sizeof buf, "%.2f MiB", double(bytes) / double(1ull << 20));
  else if (bytes >= 1024) std::snprintf(buf, sizeof buf, "%.2f KiB", double(bytes) / 1024.0);
  else std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(bytes));
  return buf;
}

// ---- output ---------------------------------------------------------------------------------------------------

std::string format_plan_table(const MemoryPlan& p) {
  std::ostringstream o;
  char line[256];
  o << "memory plan for " << p.source << "\n";
  o << "  clip " << p.request.frames << " frames x " << p.request.height << "x" << p.request.width << " -> latent "
    << p.latent_frames << "x" << p.latent_height << "x" << p.latent_width << ", " << p.text_len
    << " text tokens; allocations aligned to " << p.request.alignment << " bytes\n\n";
  o << "weights (stored dtype)\n";
  for (const auto& w : p.weights) {
    std::snprintf(line, sizeof line, "  %-14s %14llu params  %12s  (%s)\n", w.name.c_str(),
                  static_cast<unsigned long long>(w.params), format_plan_bytes(w.bytes).c_str(),
                  w.from_headers ? "safetensors headers" : "config x assumed dtype");
    o << line;
  }
  std::snprintf(line, sizeof line, "  %-14s %14s          %12s\n\n", "total", "", format_plan_bytes(p.weights_total).c_str());
  o << line;
  o << "stage peaks above the weights (activations + the call's inputs, outputs and tables)\n";
  for (const auto& s : p.stages) {
    std::snprintf(line, sizeof line, "  %-22s %12s  (activations %s)  %s\n", s.name.c_str(), format_plan_bytes(s.total()).c_str(),
                  format_plan_bytes(s.working).c_str(), s.what.c_str());
    o << line;
  }
  o << "  kept across stages: " << format_plan_bytes(p.carried) << " (prompt embeddings, latents)\n\n";
  o << "block weights (--weights " << weights_choice_name(p.request.weights) << ")\n";
  for (const auto& st : p.streams) o << stream_lines(st, p.request.weights);
  o << "\n";
  if (p.request.limits) {
    const PlanLimits& l = *p.request.limits;
    o << "limits of " << l.source << ": binding (maxStorageBufferRange) " << format_plan_bytes(l.binding)
      << ", texel view (maxTexelBufferElements) " << l.texels << " texels, allocation (maxMemoryAllocationSize) "
      << format_plan_bytes(l.alloc) << ", groups " << l.groups << "\n";
    for (const auto& s : p.stages)
      if (s.name == "render") o << "  render: " << render_verdict(p.render) << "\n";
      else if (s.name != "vae_encode" && s.name != "vae_decode") o << "  " << s.name << ": " << limits_verdict(s, l) << "\n";
    for (const auto& t : p.tilings) {
      const std::string tag = t.tiled ? " (tiles " + std::to_string(t.tiling.tile_sample_min_height) + "x" +
                                            std::to_string(t.tiling.tile_sample_min_width) + ")"
                                      : std::string(" (untiled)");
      o << "  vae_encode" << tag << ": " << limits_verdict(t.vae_encode, l) << "\n";
      o << "  vae_decode" << tag << ": " << limits_verdict(t.vae_decode, l) << "\n";
    }
    o << "\n";
  }
  o << "whole run (the largest phase: VAE weights + T5 or transformer weights when loaded, resident or their stream\n"
       "slots, + kept tensors + that call)\n";
  for (size_t i = 0; i < p.tilings.size(); ++i) {
    const auto& t = p.tilings[i];
    std::string name = t.tiled ? "VAE tiles " + std::to_string(t.tiling.tile_sample_min_height) + "x" +
                                     std::to_string(t.tiling.tile_sample_min_width) + " (" + std::to_string(t.tiles) +
                                     " per frame)"
                               : std::string("VAE untiled");
    std::snprintf(line, sizeof line, "  %-34s peak %12s  (encode %s, decode %s)%s\n", name.c_str(), format_plan_bytes(t.run_peak).c_str(),
                  format_plan_bytes(t.vae_encode.total()).c_str(), format_plan_bytes(t.vae_decode.total()).c_str(),
                  p.checked() && int(i) == p.chosen ? "  <- chosen" : "");
    o << line;
  }
  if (p.checked()) {
    o << "\n";
    if (p.request.budget) o << "budget " << format_plan_bytes(*p.request.budget);
    if (p.request.limits) o << (p.request.budget ? ", " : "") << "limits of " << p.request.limits->source;
    o << ": ";
    if (p.chosen < 0) o << "NOTHING FITS\n";
    else if (p.chosen == 0) o << "runs untiled (peak " << format_plan_bytes(p.tilings[0].run_peak) << "): dvs run without --vae-tiling\n";
    else {
      const auto& t = p.tilings[size_t(p.chosen)];
      o << "needs VAE tiling: dvs run --vae-tile " << t.tiling.tile_sample_min_height << "x" << t.tiling.tile_sample_min_width
        << " (overlap 1/6 x 1/5), peak " << format_plan_bytes(t.run_peak) << "\n";
    }
  }
  for (const auto& n : p.notes) o << "note: " << n << "\n";
  return o.str();
}

json plan_to_json(const MemoryPlan& p) {
  json j;
  j["source"] = p.source;
  j["request"] = {{"frames", p.request.frames}, {"height", p.request.height}, {"width", p.request.width},
                  {"prompts", p.request.prompts}, {"alignment", p.request.alignment}};
  j["request"]["budget_bytes"] = p.request.budget ? json(*p.request.budget) : json(nullptr);
  j["request"]["weights"] = weights_choice_name(p.request.weights);
  j["weights_residency"] = json::object();
  j["streams"] = json::array();
  for (const auto& st : p.streams) {
    j["weights_residency"][st.component] = st.streamed ? "stream" : "resident";
    j["streams"].push_back(stream_json(st));
  }
  j["latent"] = {p.latent_frames, p.latent_height, p.latent_width};
  j["text_len"] = p.text_len;
  j["weights"] = json::array();
  for (const auto& w : p.weights)
    j["weights"].push_back({{"name", w.name}, {"params", w.params}, {"bytes", w.bytes},
                            {"basis", w.from_headers ? "safetensors_headers" : "config"}});
  j["weights_total_bytes"] = p.weights_total;
  j["stages"] = json::array();
  for (const auto& s : p.stages) {
    j["stages"].push_back(stage_json(s));
    if (p.request.limits) j["stages"].back()["limits"] = limits_json(s, *p.request.limits);
  }
  j["render"] = {{"chunk_frames", p.render.chunk_frames}, {"total_bytes", p.render.total},
                 {"largest_buffer_bytes", p.render.largest.bytes}, {"largest_buffer", p.render.largest.what},
                 {"runs", p.render.problem.empty()}};
  if (!p.render.problem.empty()) j["render"]["problem"] = p.render.problem;
  j["carried_bytes"] = p.carried;
  j["run_peak_bytes"] = p.run_peak;
  j["tilings"] = json::array();
  for (const auto& t : p.tilings) {
    json e = {{"tiled", t.tiled}, {"run_peak_bytes", t.run_peak}, {"vae_encode", stage_json(t.vae_encode)},
              {"vae_decode", stage_json(t.vae_decode)}};
    if (p.request.limits) {
      e["vae_encode"]["limits"] = limits_json(t.vae_encode, *p.request.limits);
      e["vae_decode"]["limits"] = limits_json(t.vae_decode, *p.request.limits);
    }
    e["runs"] = t.blocker.empty();
    if (!t.blocker.empty()) e["blocker"] = t.blocker;
    if (t.tiled) {
      e["tile_sample_min_height"] = t.tiling.tile_sample_min_height;
      e["tile_sample_min_width"] = t.tiling.tile_sample_min_width;
      e["tiles_per_frame"] = t.tiles;
    }
    j["tilings"].push_back(e);
  }
  if (p.request.limits) {
    const PlanLimits& l = *p.request.limits;
    j["limits"] = {{"source", l.source}, {"binding_bytes", l.binding}, {"texels", l.texels}, {"alloc_bytes", l.alloc},
                   {"groups", l.groups}};
  }
  if (p.checked()) {
    json c = {{"fits", p.chosen >= 0}};
    if (p.chosen >= 0) {
      const auto& t = p.tilings[size_t(p.chosen)];
      c["tiled"] = t.tiled;
      c["run_peak_bytes"] = t.run_peak;
      if (t.tiled) {
        c["tile_sample_min_height"] = t.tiling.tile_sample_min_height;
        c["tile_sample_min_width"] = t.tiling.tile_sample_min_width;
      }
    }
    j["choice"] = c;
  } else {
    j["choice"] = nullptr;
  }
  j["notes"] = p.notes;
  return j;
}

}  // namespace dvs::pipeline
