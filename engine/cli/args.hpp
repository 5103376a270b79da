// The dvs sub-commands' command lines, on CLI11: each option is declared once (options.hpp: its name, value
// and help, in groups that the commands sharing them take whole), CLI11 matches the arguments and prints the
// help, and the values are checked when read here. Every usage error is a dvs::UsageError (exit status 2)
// worded "dvs <command>: <what> (see dvs <command> --help)".
#pragma once
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace CLI {
class App;
}

namespace dvs::cli {

// One option: its name without the dashes, the placeholder of its value ("N", "HxW"; empty: a flag, which takes
// no value) and its help (lines after the first are indented under it).
struct OptionSpec {
  std::string name, value, help;
  bool flag() const { return value.empty(); }
};

// Options that belong together in the help and that the commands taking any of them take all of.
struct OptionGroup {
  std::string title;
  std::vector<OptionSpec> options;
};

// The help's text around the options: "usage: <usage>", then `about`, the option groups, then `footer`.
struct CommandHelp {
  std::string usage, about, footer;
};

class Args {
 public:
  Args(std::string command, CommandHelp help, const std::vector<OptionGroup>& groups);
  ~Args();
  Args(const Args&) = delete;
  Args& operator=(const Args&) = delete;

  // A positional argument (batch's JOBS.jsonl), read with str(name).
  void positional(const std::string& name, const std::string& help);
  // Matches argv against the declarations. --help prints the help on stdout and sets help(); an unknown
  // option, a missing value or a value given to a flag throws UsageError.
  void parse(const std::vector<std::string>& argv);
  bool help() const { return help_; }
  std::string help_text() const;
  // The declaration of --name, or nullptr when this command has none.
  const OptionSpec* find(const std::string& name) const;

  bool has(const std::string& name) const;  // given (a flag: given and not =false)
  std::string str(const std::string& name, const std::string& fallback = "") const;
  std::string required(const std::string& name) const;
  int integer(const std::string& name, int fallback, int lo, int hi) const;
  double number(const std::string& name, double fallback) const;
  // "480x720" -> (480, 720)
  std::pair<int, int> size(const std::string& name, std::pair<int, int> fallback) const;
  std::vector<double> numbers(const std::string& name, size_t count) const;  // "a,b,c,d"
  // The working size from --size HxW or from --height H --width W (both, and not with --size); positive
  // multiples of 8 (the VAE and the renderer work on 8x8 pixel cells).
  std::pair<int, int> working_size(std::pair<int, int> fallback) const;
  // Throws dvs::UsageError (exit status 2): "dvs <command>: <what> (see dvs <command> --help)".
  [[noreturn]] void fail(const std::string& what) const;

 private:
  std::string command_;
  std::unique_ptr<CLI::App> app_;
  std::vector<OptionSpec> declared_;
  bool help_ = false;
  std::map<std::string, std::string> values_;
  std::map<std::string, bool> flags_;
};

}  // namespace dvs::cli
