#include "input_script.hpp"

#include <fstream>
#include <sstream>
#include <stdexcept>

namespace preview {

std::vector<ScriptEvent> read_script(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the script file");
  std::vector<ScriptEvent> events;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    std::istringstream words(line);
    ScriptEvent e;
    e.line = number;
    if (!(words >> e.verb) || e.verb[0] == '#') continue;
    auto fail = [&](const std::string& what) {
      throw std::runtime_error(path + ":" + std::to_string(number) + ": " + what + " (line: '" + line + "')");
    };
    if (e.verb == "key") {
      if (!(words >> e.text) || e.text.size() != 1 || std::string("WASDQEwasdqe").find(e.text) == std::string::npos)
        fail("'key' takes one of W A S D Q E and an optional frame count");
      e.text[0] = char(std::toupper(static_cast<unsigned char>(e.text[0])));
      if (!(words >> e.frames)) e.frames = 1;
      if (e.frames < 1) fail("the frame count must be at least 1");
    } else if (e.verb == "mouse") {
      if (!(words >> e.a >> e.b)) fail("'mouse' takes two numbers: DX DY in pixels");
    } else if (e.verb == "scroll") {
      if (!(words >> e.a)) fail("'scroll' takes a number of steps");
    } else if (e.verb == "scrub") {
      if (!(words >> e.a) || e.a < 0) fail("'scrub' takes a path frame index (0 or more)");
    } else if (e.verb == "wait") {
      if (!(words >> e.frames) || e.frames < 1) fail("'wait' takes a frame count (1 or more)");
    } else if (e.verb == "screenshot" || e.verb == "export") {
      if (!(words >> e.text)) fail("'" + e.verb + "' takes a file name");
    } else if (e.verb != "keypose" && e.verb != "play" && e.verb != "quit") {
      fail("unknown event '" + e.verb + "' (key mouse scroll keypose scrub play wait screenshot export quit)");
    }
    std::string extra;
    if (words >> extra) fail("unexpected '" + extra + "' at the end");
    events.push_back(e);
  }
  return events;
}

}  // namespace preview
