// The name a message gives an option of RunOptions, RenderJob or MemoryPlanRequest (dvs/option_names.hpp): the field itself
// ("RunOptions::strength") or, when the dvs program asked for it, the flag that sets it ("--strength").
#pragma once
#include <string>
#include <vector>

namespace dvs {

// `field` is the C++ name: "RunOptions::steps", "RenderJob::trajectory", "RunOptions::render.trajectory" (= the
// RenderJob field), or one of the joint names "RenderJob::height/width", "RenderJob::fx/fy/cx/cy",
// "RunOptions::vae_tile_height/width". A name not in the table is an internal error (the unit test walks it).
std::string option_name(const std::string& field);

// The command-line flag of `field` whatever the process chose (for the table's test and the CLI's own messages).
std::string option_flag(const std::string& field);

// Advice that is not an option's name: `command_line` when the dvs program asked for flag names (set_option_names),
// else `library` ("Ctrl-C stops it" against "the cancel function stops it").
std::string in_words_of_caller(const std::string& command_line, const std::string& library);

// Every field the table names (for its test: each flag must be one the dvs program declares).
std::vector<std::string> option_fields();

}  // namespace dvs
