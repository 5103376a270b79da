#include "args.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <regex>
#include <sstream>

#include "dvs/error.hpp"
#include "dvs/usage_error.hpp"

namespace dvs::cli {
namespace {

// CLI11's help layout with dvs's usage line first ("usage: ..." as every dvs program prints it), then the
// description, the option groups and the footer.
class HelpFormatter : public CLI::Formatter {
 public:
  explicit HelpFormatter(CommandHelp help) : help_(std::move(help)) { column_width(28); }
  std::string make_help(const CLI::App* app, std::string, CLI::AppFormatMode mode) const override {
    std::string out = "usage: " + help_.usage + "\n";
    if (!help_.about.empty()) out += "\n" + help_.about;
    out += make_positionals(app) + make_groups(app, mode);
    if (!help_.footer.empty()) out += "\n" + help_.footer;
    // One blank line between groups (CLI11 puts two).
    for (size_t at; (at = out.find("\n\n\n")) != std::string::npos;) out.erase(at, 1);
    return out;
  }

 private:
  CommandHelp help_;
};

// CLI11's words for a missing value ("--video: 1 required V missing") in dvs's.
std::string usage_message(const std::string& cli11) {
  static const std::regex missing("^(--[A-Za-z0-9-]+): [0-9]+ required .* missing$");
  std::smatch m;
  if (std::regex_match(cli11, m, missing)) return m[1].str() + " needs a value";
  return cli11;
}

}  // namespace

Args::Args(std::string command, CommandHelp help, const std::vector<OptionGroup>& groups)
    : command_(std::move(command)), app_(std::make_unique<CLI::App>("", "dvs " + command_)) {
  app_->formatter(std::make_shared<HelpFormatter>(std::move(help)));
  app_->allow_extras();  // reported by parse() in dvs's words, with the first unknown option named
  app_->set_help_flag();  // removed here, added after the groups so that it comes last in the help
  for (const OptionGroup& g : groups)
    for (const OptionSpec& o : g.options) {
      CLI::Option* opt = o.flag() ? app_->add_flag("--" + o.name, flags_[o.name], o.help)
                                  : app_->add_option("--" + o.name, values_[o.name], o.help)->type_name(o.value);
      // Later values win: `--from` puts the recorded arguments first, batch its defaults before each job's own.
      opt->group(g.title)->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
      declared_.push_back(o);
    }
  app_->set_help_flag("-h,--help", "this help")->group("help");
}

Args::~Args() = default;

void Args::positional(const std::string& name, const std::string& help) {
  app_->add_option(name, values_[name], help)->group("arguments");
}

void Args::parse(const std::vector<std::string>& argv) {
  std::vector<std::string> reversed(argv.rbegin(), argv.rend());  // CLI11 takes the arguments last first
  try {
    app_->parse(reversed);
  } catch (const CLI::CallForHelp&) {
    help_ = true;
    std::cout << help_text();
    return;
  } catch (const CLI::ParseError& e) {
    fail(usage_message(e.what()));
  }
  const std::vector<std::string> extra = app_->remaining();
  if (!extra.empty()) {
    const std::string& a = extra.front();
    if (a.rfind("--", 0) == 0) fail("unknown option " + a.substr(0, a.find('=')));
    fail("unexpected argument '" + a + "'");
  }
}

std::string Args::help_text() const { return app_->help(); }

const OptionSpec* Args::find(const std::string& name) const {
  for (const OptionSpec& o : declared_)
    if (o.name == name) return &o;
  return nullptr;
}

void Args::fail(const std::string& what) const {
  throw UsageError("dvs " + command_ + ": " + what + " (see dvs " + command_ + " --help)");
}

bool Args::has(const std::string& name) const {
  if (auto f = flags_.find(name); f != flags_.end()) return f->second;
  if (!values_.count(name)) return false;
  return app_->count(find(name) ? "--" + name : name) > 0;  // a declared option, or a positional
}

std::string Args::str(const std::string& name, const std::string& fallback) const {
  return has(name) ? values_.at(name) : fallback;
}

std::string Args::required(const std::string& name) const {
  if (!has(name) || values_.at(name).empty()) fail("--" + name + " is required");
  return values_.at(name);
}

int Args::integer(const std::string& name, int fallback, int lo, int hi) const {
  if (!has(name)) return fallback;
  const std::string& text = values_.at(name);
  try {
    size_t used = 0;
    long v = std::stol(text, &used);
    if (used != text.size()) throw std::invalid_argument("");
    if (v < lo || v > hi) fail("--" + name + " must be between " + std::to_string(lo) + " and " + std::to_string(hi));
    return int(v);
  } catch (const std::logic_error&) {
    fail("--" + name + " must be a whole number, got '" + text + "'");
  }
}

double Args::number(const std::string& name, double fallback) const {
  if (!has(name)) return fallback;
  const std::string& text = values_.at(name);
  try {
    size_t used = 0;
    double v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v)) throw std::invalid_argument("");
    return v;
  } catch (const std::logic_error&) {
    fail("--" + name + " must be a number, got '" + text + "'");
  }
}

std::pair<int, int> Args::size(const std::string& name, std::pair<int, int> fallback) const {
  if (!has(name)) return fallback;
  const std::string& text = values_.at(name);
  int h = 0, w = 0;
  char x = 0, extra = 0;
  std::istringstream in(text);
  if (!(in >> h >> x >> w) || (x != 'x' && x != 'X') || (in >> extra) || h <= 0 || w <= 0)
    fail("--" + name + " must look like HEIGHTxWIDTH, e.g. 480x720, got '" + text + "'");
  return {h, w};
}

std::pair<int, int> Args::working_size(std::pair<int, int> fallback) const {
  const bool dims = has("height") || has("width");
  if (has("size") && dims) fail("give either --size HxW or --height H --width W, not both");
  std::pair<int, int> hw;
  if (!dims) {
    hw = size("size", fallback);
  } else {
    if (!has("height") || !has("width")) fail("--height and --width go together (or use --size HxW)");
    hw = {integer("height", 0, 8, 1 << 16), integer("width", 0, 8, 1 << 16)};
  }
  if (hw.first % 8 || hw.second % 8)
    fail(std::string(dims ? "--height and --width" : "--size") + " must be multiples of 8 (the VAE works on 8x8 pixel " +
         "cells), got " + std::to_string(hw.first) + "x" + std::to_string(hw.second) + "; e.g. " +
         std::to_string(std::max(8, hw.first / 8 * 8)) + "x" + std::to_string(std::max(8, hw.second / 8 * 8)));
  return hw;
}

std::vector<double> Args::numbers(const std::string& name, size_t count) const {
  std::vector<double> out;
  const std::string s = str(name);
  const std::string expected = "--" + name + " must be " + std::to_string(count) + " comma-separated numbers, got '" + s + "'";
  std::stringstream ss(s);
  for (std::string part; std::getline(ss, part, ',');) {
    try {
      size_t used = 0;
      out.push_back(std::stod(part, &used));
      if (used != part.size()) throw std::invalid_argument("");
    } catch (const std::logic_error&) {
      fail(expected);
    }
  }
  if (out.size() != count) fail(expected);
  return out;
}

}  // namespace dvs::cli
