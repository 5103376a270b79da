#include "options.hpp"

#include <stdexcept>

namespace dvs::cli {

const OptionGroup kClipInputs{
    "inputs",
    {{"video", "V", "input video (any size and fps)"},
     {"trajectory", "T",
      "camera path: loop1..loop4, wave1, oscillating_wave (official), pan_left,\n"
      "pan_right, tilt_up, tilt_down, dolly_in, dolly_out, truck_left, truck_right,\n"
      "arc_left, arc_right (NAME:MAGNITUDE sets degrees or radius fractions), or a\n"
      ".txt (official three-line format), .json (4x4 poses) or .gltf/.glb camera\n"
      "animation (default loop1)"},
     {"frames", "N", "first N frames (default 49; run, invert and batch: 4k+1; render: 0 = all)"},
     {"size", "HxW",
      "working size (default 480x720; multiples of 8; a model with learned\n"
      "positional embeddings, as CogVideoX-5B-I2V, needs its own size)"},
     {"height", "H", "working height, with --width instead of --size"},
     {"width", "W", "working width, with --height instead of --size"},
     {"resize", "crop|squash", "keep the aspect ratio and crop the centre (default), or squash (official)"},
     {"intrinsics", "fx,fy,cx,cy",
      "in pixels of the working size (default: f = 500 px at 1024x576, square\n"
      "pixels under crop, scaled per axis under squash)"},
     {"points", "", "hard z-buffer point splatting instead of the soft bilinear splat"}}};

const OptionGroup kDepthSource{
    "depth (one of --depth and --depth-model)",
    {{"depth", "D",
      "per-frame depth: .npy/.npz [N,H,W] (or [N,H,W,1]; float or 16-bit;\n"
      "FILE.npz:KEY picks an array, default key 'depths'), a folder of 16-bit\n"
      "PNG/EXR frames (natural name order: d_2 before d_10) or a grayscale video"},
     {"depth-model", "FILE",
      "instead of --depth: estimate the depth with Video-Depth-Anything\n"
      "(video_depth_anything_vits.pth etc., see README); cached in the cache folder\n"
      "by the video's bytes, the model and the settings (--no-cache: estimate again)"},
     {"depth-input-size", "N", "--depth-model's network input's short side (default 518)"},
     {"metric-depth", "", "D holds metric depth (default: disparity, as Video-Depth-Anything writes)"},
     {"trim-depth", "", "allow D to have more frames than the video uses"},
     {"depth-fit", "error|stretch|crop",
      "depth of another aspect ratio (or orientation) than the video: refuse\n"
      "(error, the default), scale each axis (stretch) or cut its centre (crop)"}}};

const OptionGroup kDepthCache{
    "cache",
    {{"cache-dir", "DIR", "the cache folder, as DVS_CACHE_DIR=DIR: depth estimates, inversions and latents in\n"
                          "DIR/inversions (default $DVS_CACHE_DIR, else ~/.cache/dvs)"},
     {"no-cache", "", "neither read nor write the cache (compute everything again)"}}};

const OptionGroup kOutFolder{"output", {{"out", "DIR", "output folder (created)"}}};

const OptionGroup kModelInputs{
    "model",
    {{"model", "DIR", "model folder laid out like THUDM/CogVideoX-5b-I2V"},
     {"lora", "FILE[:SCALE]",
      "a LoRA adapter (.safetensors, diffusers/PEFT layout) on the transformer, for\n"
      "the inversion and the sampling (scale 1 when not given)"}}};

const OptionGroup kPromptInputs{
    "prompt",
    {{"prompt", "TEXT", "what the scene shows (\"\" is allowed: no text conditioning)"},
     {"negative-prompt", "T", "default \"\" (paper) / the authors' fixed text (official)"}}};

const OptionGroup kSchedule{
    "schedule",
    {{"preset", "paper|official", "paper (default) or the authors' code (see README)"},
     {"steps", "N", "sampling schedule length (paper 50, official 30)"},
     {"strength", "S", "keeps the last floor(N*S) steps (paper 0.95, official 0.98)"},
     {"inversion-steps", "N", "DDIM inversion steps (30)"}}};

const OptionGroup kSampling{
    "sampling",
    {{"k", "K", "K-RNR order (10; real values allowed)"},
     {"delta", "D", "AdaIN target order (paper 3, official 2)"},
     {"guidance", "G", "classifier-free guidance scale (6)"},
     {"dynamic-cfg", "on|off",
      "the authors' position-wise guidance: occluded latents get a per-step scale\n"
      "from G, fully visible ones --preservation-scale (official on, paper off)"},
     {"preservation-scale", "P",
      "guidance scale of the fully visible latents with --dynamic-cfg on (1 = the\n"
      "prompt-conditioned prediction, as the authors' config)"},
     {"seed", "N", "seed of every random draw (42)"}}};

const OptionGroup kMemory{
    "memory",
    {{"vae-tiling", "",
      "encode and decode in overlapping spatial tiles (diffusers' enable_tiling): far\n"
      "less device memory at 480x720; use it when a run stops out of device memory"},
     {"vae-tile", "HxW", "tile size in pixels, multiples of 8 (implies --vae-tiling; default 240x360)"},
     {"weights", "MODE",
      "the transformer's and T5's block weights: resident, stream (from host memory\n"
      "through a few device slots, uploads behind the compute) or auto (default: the\n"
      "memory plan's choice, streamed only where resident does not fit); same results"}}};

const OptionGroup kDevice{"device", {{"device", "I|NAME", "Vulkan device: index or name substring (also: DVS_DEVICE)"}}};

const OptionGroup kProgressOutput{
    "output",
    {{"progress", "bar|json|none", "progress output (default bar)"},
     {"quiet", "", "no progress output (--progress none); not with another --progress"}}};

const OptionGroup kCheckOnly{
    "check",
    {{"check", "",
      "preflight only: check the options, files (and for run the model, LoRA, tiling\n"
      "and device memory), report every problem, run nothing (exit 0 = fine)"}}};

OptionSpec option_in(const OptionGroup& group, const std::string& name) {
  for (const OptionSpec& o : group.options)
    if (o.name == name) return o;
  throw std::logic_error("no option --" + name + " in the group " + group.title);
}

std::vector<OptionGroup> run_option_groups() {
  return {kClipInputs, kDepthSource, kOutFolder, kModelInputs, kPromptInputs, kSchedule, kSampling, kDepthCache,
          kMemory,     kDevice,      kProgressOutput};
}

std::vector<OptionGroup> invert_option_groups() {
  return {kClipInputs, kDepthSource, kOutFolder, kModelInputs, kSchedule, kDepthCache, kMemory, kDevice, kProgressOutput};
}

}  // namespace dvs::cli
