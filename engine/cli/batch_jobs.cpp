#include "batch_jobs.hpp"

#include <fstream>

#include "args.hpp"
#include "dvs/error.hpp"
#include "options.hpp"

namespace dvs::cli {

std::vector<Job> read_jobs(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw Error(file.string() + ": cannot read the jobs file");
  std::vector<Job> jobs;
  std::string text;
  for (int line = 1; std::getline(in, text); ++line) {
    const auto first = text.find_first_not_of(" \t\r");
    if (first == std::string::npos || text[first] == '#') continue;
    nlohmann::json spec;
    try {
      spec = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
      throw Error(file.string() + ":" + std::to_string(line) + ": not a JSON object (" + e.what() + ")");
    }
    if (!spec.is_object()) throw Error(file.string() + ":" + std::to_string(line) + ": a job must be a JSON object");
    jobs.push_back({int(jobs.size()), line, std::move(spec)});
  }
  return jobs;
}

std::vector<std::string> job_arguments(const nlohmann::json& spec) {
  const std::vector<OptionGroup> declared = run_option_groups();
  auto declaration = [&](const std::string& key) -> const OptionSpec* {
    for (const OptionGroup& g : declared)
      for (const OptionSpec& o : g.options)
        if (o.name == key) return &o;
    return nullptr;
  };
  std::vector<std::string> args;
  for (const auto& [key, value] : spec.items()) {
    const OptionSpec* option = declaration(key);
    if (!option)
      throw Error("unknown key \"" + key + "\": a job's keys are dvs run's options without the dashes (see dvs run --help)");
    const std::string opt = "--" + key;
    if (value.is_null()) continue;
    if (option->flag()) {
      if (!value.is_boolean()) throw Error("\"" + key + "\" is a flag: its value must be true or false, got " + value.dump());
      args.push_back(opt + (value.get<bool>() ? "=true" : "=false"));
    } else if (value.is_string()) {
      args.insert(args.end(), {opt, value.get<std::string>()});
    } else if (value.is_number()) {
      args.insert(args.end(), {opt, value.dump()});
    } else if (value.is_array()) {
      std::string joined;
      for (const auto& v : value) joined += (joined.empty() ? "" : ",") + (v.is_string() ? v.get<std::string>() : v.dump());
      args.insert(args.end(), {opt, joined});
    } else {
      throw Error("\"" + key + "\" must be a string, number or array (" + option->value + "), got " + value.dump());
    }
  }
  return args;
}

}  // namespace dvs::cli
