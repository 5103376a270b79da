// JSON files read with the errors a user can act on (which file, what is wrong) and a nesting guard, so a
// hostile file never reaches the parser's recursion.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string_view>

namespace dvs {

// Reads and parses a JSON file; dvs::Error names the file (and `what_to_do` when it is missing).
nlohmann::json read_json_file(const std::filesystem::path& path, std::string_view what_to_do = {});

}  // namespace dvs
