// JSON files read with the errors a user can act on (which file, what is wrong) and a nesting guard, so a
// hostile file never reaches the parser's recursion.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string_view>

namespace dvs {

// Reads and parses a JSON file; dvs::Error names the file (and `what_to_do` when it is missing).
nlohmann::json read_json_file(const std::filesystem::path& path, std::string_view what_to_do = {});

// Whether `text` nests brackets deeper than `limit` outside strings: checked before parsing, so hostile input
// ("[[[[...") never reaches a parser's recursion or a recursive destructor. Stops at the first level past it.
bool json_nests_deeper_than(std::string_view text, int limit);

}  // namespace dvs
