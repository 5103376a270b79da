// Scripted input (--script FILE) for tests and recordings: one event per line, run one display frame at a time.
//   key W 10          hold W (or A S D Q E) for 10 frames (default 1)
//   mouse DX DY       one drag of DX, DY pixels
//   scroll N          N scroll steps (speed ×1.25 each; negative slows down)
//   keypose           K: add a key pose at the current camera
//   scrub N           go to frame N of the path ([ and ] step it by one)
//   play              P: play the path from frame 0
//   wait N            N frames without input
//   screenshot FILE   F12: the render panel as .npy (u8 [H,W,4], exactly as rendered) or the window as .png
//   export FILE.json  X: the path as FILE.json and FILE.glb
//   quit
// Blank lines and lines starting with '#' are skipped. Errors name the file and line.
#pragma once
#include <string>
#include <vector>

namespace preview {

struct ScriptEvent {
  std::string verb;   // key mouse scroll keypose scrub play wait screenshot export quit
  std::string text;   // the key name or the file
  double a = 0, b = 0;
  int frames = 1;     // how many display frames it takes
  int line = 0;
};

std::vector<ScriptEvent> read_script(const std::string& path);

}  // namespace preview
