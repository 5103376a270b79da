#include "io/json_file.hpp"

#include <fstream>
#include <sstream>

#include "dvs/error.hpp"

namespace dvs {
namespace fs = std::filesystem;
using nlohmann::json;

bool json_nests_deeper_than(std::string_view s, int limit) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (char ch : s) {
    if (in_string) {
      if (escaped) escaped = false;
      else if (ch == '\\') escaped = true;
      else if (ch == '"') in_string = false;
    } else if (ch == '"') {
      in_string = true;
    } else if ((ch == '[' || ch == '{') && ++depth > limit) {
      return true;
    } else if (ch == ']' || ch == '}') {
      --depth;
    }
  }
  return false;
}

json read_json_file(const fs::path& path, std::string_view what_to_do) {
  const std::string name = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw Error(name + ": file not found" + (what_to_do.empty() ? std::string() : "; " + std::string(what_to_do)));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(name + ": cannot open for reading");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  if (json_nests_deeper_than(text, 64)) throw Error(name + ": JSON nests deeper than 64 levels; refusing to parse it");
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    throw Error(name + ": not valid JSON: " + e.what() + "; fix or re-download the file");
  }
}

}  // namespace dvs
