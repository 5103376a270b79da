// Every `dvs <command> --flag` that README.md, docs/, the public headers and the preview (its README, help text and
// comments) name is an option of that command (its --help lists it), so documentation cannot send a user to an
// option that does not exist (issue 34: `dvs render --squash` and `--hard-points` were named where the options are
// `--resize squash` and `--points`). A mention is `dvs` (or a path ending in /dvs), a command of `dvs --help`, then
// the command line's tokens: flags, their values, brackets and alternatives, until a token that cannot be part of it.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "support/files.hpp"
#include "support/process.hpp"
#include "support/source_dir.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

struct Mention {
  std::string command, flag, where;  // flag without its dashes
};

// A flag token's name: "--size", "[--squash]", "(--older-than", "--depth-fit=crop", "`--points`," -> the name; "" when
// the token is not a flag.
std::string flag_name(std::string token) {
  while (!token.empty() && (token[0] == '[' || token[0] == '(' || token[0] == '`' || token[0] == '"')) token.erase(0, 1);
  if (token.rfind("--", 0) != 0) return "";
  std::string name;
  for (size_t i = 2; i < token.size() && (std::isalnum(static_cast<unsigned char>(token[i])) || token[i] == '-'); ++i)
    name += token[i];
  return name;
}

// The mentions in `text` (from `where`), for the commands in `commands`.
std::vector<Mention> mentions_in(const std::string& text, const std::set<std::string>& commands, const std::string& where) {
  std::vector<Mention> found;
  std::vector<std::string> tokens;
  std::istringstream in(text);
  for (std::string t; in >> t;) tokens.push_back(t);
  static const std::regex program("^[`\"(\\[]*([A-Za-z0-9_.$/{}-]*/)?dvs$");
  for (size_t i = 0; i + 1 < tokens.size(); ++i) {
    if (!std::regex_match(tokens[i], program)) continue;
    std::string command = tokens[i + 1];
    const bool ends_here = !command.empty() && std::string("`),.;:").find(command.back()) != std::string::npos;
    while (!command.empty() && std::string("`),.;:").find(command.back()) != std::string::npos) command.pop_back();
    if (!commands.count(command) || ends_here) continue;
    bool after_flag = false;
    int positionals = 0, depth = 0;
    for (size_t k = i + 2; k < tokens.size(); ++k) {
      std::string t = tokens[k];
      if (std::regex_match(t, program)) break;  // the next command line
      for (char c : t) depth += c == '(' ? 1 : c == ')' ? -1 : 0;
      const bool last = (t.back() == ')' && depth < 0) || std::string("`,;:").find(t.back()) != std::string::npos ||
                        (t.back() == '.' && t.size() > 1 && !std::isalnum(static_cast<unsigned char>(t[t.size() - 2])));
      if (const std::string f = flag_name(t); !f.empty()) {
        found.push_back({command, f, where});
        after_flag = true;
      } else if (t == "|" || t == "[" || t == "]" || t == "\\") {
        after_flag = false;  // alternatives, an optional group, a continued line
      } else if (after_flag || (positionals++ == 0 && k == i + 2)) {
        after_flag = false;  // a flag's value, or the command's first positional (a batch file, an action)
      } else {
        break;
      }
      if (last || t == "&&" || t == "||" || t == ">" || t == "2>&1") break;
    }
  }
  return found;
}

// A file's text with comment leaders removed from each line (headers: `// ...`, ` * ...`), so that a command line
// wrapped over two comment lines reads as one.
std::string without_comment_leaders(const std::string& text) {
  std::string out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    size_t at = line.find_first_not_of(" \t");
    if (at != std::string::npos && line.compare(at, 2, "//") == 0) at += 2;
    else if (at != std::string::npos && (line.compare(at, 2, "/*") == 0)) at += 2;
    else if (at != std::string::npos && line[at] == '*' && line.compare(at, 2, "*/") != 0) at += 1;
    out += (at == std::string::npos ? std::string() : line.substr(at)) + "\n";
  }
  return out;
}

// The lines of a help text that declare options ("  --name ...", "  -h,--help"): the names.
std::set<std::string> declared_options(const std::string& help) {
  std::set<std::string> names;
  static const std::regex line("^\\s+(?:-[A-Za-z], ?)?--([a-z0-9][a-z0-9-]*)");
  std::istringstream in(help);
  for (std::string l; std::getline(in, l);) {
    std::smatch m;
    if (std::regex_search(l, m, line)) names.insert(m[1].str());
  }
  return names;
}

TEST(DocsCommandFlags, MentionsAreFoundInEveryForm) {
  const std::set<std::string> commands{"render", "run", "cache"};
  auto flags = [&](const std::string& text) {
    std::string s;
    for (const Mention& m : mentions_in(text, commands, "sample")) s += m.command + ":" + m.flag + " ";
    return s;
  };
  EXPECT_EQ(flags("as `dvs render --size HxW [--squash]` brings them"), "render:size render:squash ");
  EXPECT_EQ(flags("splat (dvs render --hard-points) instead"), "render:hard-points ");
  EXPECT_EQ(flags("build/dvs run --video v.mp4 --depth d.npz \\\n --out o --check"), "run:video run:depth run:out run:check ");
  EXPECT_EQ(flags("dvs cache clean (--older-than DAYS | --max-size SIZE | --all) [--dry-run]"),
            "cache:older-than cache:max-size cache:all cache:dry-run ");
  EXPECT_EQ(flags("`dvs run --from out/run.json --out again` repeats it; --seed is not dvs run's here"), "run:from run:out ");
  EXPECT_EQ(flags("dvs run takes --depth-fit=crop, then more --prose"), "run:depth-fit ");
  EXPECT_EQ(flags("dvs render writes a video, and --points elsewhere"), "") << "prose after the command is not a command line";
  EXPECT_EQ(flags("dvs plan --budget 8G"), "") << "a command not in the list";
  EXPECT_EQ(flags(without_comment_leaders("// brought as `dvs render --size HxW\n//   [--squash]`")),
            "render:size render:squash ");
}

TEST(DocsCommandFlags, EveryNamedFlagIsAnOptionOfItsCommand) {
  const std::string dvs = test::program("dvs");
  const auto top = test::run_command("(" + dvs + " --help 2>/dev/null)");
  ASSERT_EQ(top.exit_code, 0) << top.output;
  // The commands (the "commands:" block) and the options every command takes (the "common options:" block).
  std::set<std::string> commands, common;
  {
    std::istringstream in(top.output);
    std::string block;
    static const std::regex command_line("^  ([a-z][a-z-]*)  ");
    for (std::string l; std::getline(in, l);) {
      if (!l.empty() && l.back() == ':' && l[0] != ' ') block = l;
      std::smatch m;
      if (block == "commands:" && std::regex_search(l, m, command_line)) commands.insert(m[1].str());
    }
    common = declared_options(top.output);
  }
  ASSERT_GE(commands.size(), 8u) << top.output;
  std::map<std::string, std::set<std::string>> options;
  for (const std::string& c : commands) {
    const auto help = test::run_command("(" + dvs + " " + c + " --help 2>/dev/null)");
    ASSERT_EQ(help.exit_code, 0) << "dvs " << c << " --help\n" << help.output;
    options[c] = declared_options(help.output);
    options[c].insert(common.begin(), common.end());
    ASSERT_FALSE(options[c].empty()) << "dvs " << c << " --help declares no option\n" << help.output;
  }

  const fs::path root = test::source_dir();
  std::vector<fs::path> files{root / "README.md"};
  for (const char* dir : {"docs", "engine/include/dvs", "examples/preview"})
    for (const auto& e : fs::recursive_directory_iterator(root / dir)) {
      const std::string ext = e.path().extension().string();
      if (e.is_regular_file() && (ext == ".md" || ext == ".hpp" || ext == ".h" || ext == ".cpp")) files.push_back(e.path());
    }
  size_t checked = 0;
  for (const fs::path& f : files) {
    const std::string text = without_comment_leaders(test::read_text(f));
    for (const Mention& m : mentions_in(text, commands, fs::relative(f, root).string())) {
      ++checked;
      EXPECT_TRUE(options[m.command].count(m.flag))
          << m.where << " names `dvs " << m.command << " --" << m.flag << "`, which dvs " << m.command
          << " --help does not list: name the option it has";
    }
  }
  // The scan reads the documents it should: the README alone names dozens of options.
  EXPECT_GE(checked, 100u) << "too few mentions found: is the scan broken?";
  std::cout << "checked " << checked << " mentions of dvs options in " << files.size() << " files\n";
}

}  // namespace
}  // namespace dvs
