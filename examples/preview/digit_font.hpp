// A tiny built-in bitmap font (3×5 cells) to draw the frame time and the path state into an RGBA8 panel:
// digits, '.', ':', '/', ' ' and the lower-case letters the status line uses (a e f k m p s y). Other characters
// draw as a blank.
#pragma once
#include <cstdint>
#include <string>

namespace preview {

// Draws `text` with its top-left corner at (x, y), each font pixel `scale`×`scale`, white on a black box, into
// an RGBA8 image of width × height (row-major, 4 bytes a pixel). Clipped at the image's edges.
void draw_text(uint8_t* rgba, int width, int height, int x, int y, const std::string& text, int scale);

}  // namespace preview
