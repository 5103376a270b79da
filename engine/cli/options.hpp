// Every option of the dvs sub-commands that more than one of them takes, declared once, in the groups the
// commands take whole: render, run, invert and batch share the clip's inputs; run, invert and batch the model,
// schedule, memory and cache options; batch reads its jobs' JSON keys against the same declarations.
#pragma once
#include <string>
#include <vector>

#include "args.hpp"

namespace dvs::cli {

extern const OptionGroup kClipInputs;     // --video --trajectory --frames --size/--height/--width --resize ...
extern const OptionGroup kDepthSource;    // --depth | --depth-model, and how the depth is read
extern const OptionGroup kDepthCache;     // --cache-dir --no-cache
extern const OptionGroup kOutFolder;      // --out DIR
extern const OptionGroup kModelInputs;    // --model --lora
extern const OptionGroup kPromptInputs;   // --prompt --negative-prompt
extern const OptionGroup kSchedule;       // --preset --steps --strength --inversion-steps
extern const OptionGroup kSampling;       // --k --delta --guidance --dynamic-cfg --preservation-scale --seed
extern const OptionGroup kMemory;         // --vae-tiling --vae-tile
extern const OptionGroup kDevice;         // --device
extern const OptionGroup kProgressOutput; // --progress --quiet
extern const OptionGroup kCheckOnly;      // --check

// The declaration of --name in `group` (for a command that takes one option of a group, as encode-prompt --model).
OptionSpec option_in(const OptionGroup& group, const std::string& name);

// What `dvs run` takes (and `dvs batch` as defaults and job keys); `dvs invert` takes it without the prompt
// and sampling groups (they do not change ε_inv).
std::vector<OptionGroup> run_option_groups();
std::vector<OptionGroup> invert_option_groups();

}  // namespace dvs::cli
