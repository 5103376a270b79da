#version 450
// Does nothing: measures the fixed cost of one dispatch.
layout(local_size_x = 64) in;
void main() {}
