// A small `--name value` / `--flag` parser for the dvs sub-commands: every value is checked when read,
// unknown options and missing values are errors that name the option and the command's --help.
#pragma once
#include <map>
#include <set>
#include <string>
#include <vector>

namespace dvs::cli {

class Args {
 public:
  // `flags` take no value; every other --option takes exactly one.
  Args(std::string command, const std::vector<std::string>& argv, const std::set<std::string>& options,
       const std::set<std::string>& flags);

  bool help() const { return help_; }
  bool has(const std::string& name) const { return values_.count(name) || flags_.count(name); }
  std::string str(const std::string& name, const std::string& fallback = "") const;
  std::string required(const std::string& name) const;
  int integer(const std::string& name, int fallback, int lo, int hi) const;
  double number(const std::string& name, double fallback) const;
  // "480x720" -> (480, 720)
  std::pair<int, int> size(const std::string& name, std::pair<int, int> fallback) const;
  std::vector<double> numbers(const std::string& name, size_t count) const;  // "a,b,c,d"
  // The working size from --size HxW or from --height H --width W (both, and not with --size).
  std::pair<int, int> working_size(std::pair<int, int> fallback) const;
  // Throws dvs::UsageError (exit status 2): "dvs <command>: <what> (see dvs <command> --help)".
  [[noreturn]] void fail(const std::string& what) const;

 private:
  std::string command_;
  bool help_ = false;
  std::map<std::string, std::string> values_;
  std::set<std::string> flags_;
};

}  // namespace dvs::cli
