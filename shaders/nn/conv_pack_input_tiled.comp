#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_samplerless_texture_functions : require
#extension GL_EXT_control_flow_attributes : require
// The input repack of conv_pack_input.comp (same bindings, push constants, layout and values; its header describes
// them) as a transpose through shared memory, for GPUs (DeviceTuning::conv_pack_tiled): x is channel-planar, the
// packed chunk channels-last, so an invocation per vec4 of channels either reads each plane with a stride or writes
// with one. Here a workgroup takes CT = 32 channels x PT = 64 packed columns of one packed row: it reads them
// channel by channel, neighbouring invocations on neighbouring columns (whole runs of a plane's row), into shared
// memory, then writes them pixel by pixel, neighbouring invocations on neighbouring vec4s of channels (one pixel's
// 32 channels a contiguous 64 bytes in fp16, 128 in f32). Not for `partial` dispatches (a channel range that does
// not own whole vec4s): the host runs conv_pack_input.comp for those.
// Workgroups: nq x rows_p x ceil(cols_p / PT) x ceil(nc4 / 8) tiles (the channel tile slowest), then one more for
// the zero pixel where `zero`, over the x and y of a grid that ops::grid_1d split.
layout(local_size_x = 256) in;
#include "conv_pack_io.glsl"

const uint CT = 32u, PT = 64u, WG = 256u;
shared float tile[CT * (PT + 1u)];  // [channel][column], rows padded by one: both phases without bank conflicts

void main() {
  const uint wg = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x, t = gl_LocalInvocationIndex;
  const uint col_tiles = (p.cols_p + PT - 1u) / PT, rows_all = p.nq * p.rows_p;
  const uint tiles = rows_all * col_tiles * ((p.nc4 + CT / 4u - 1u) / (CT / 4u));
  if (wg >= tiles) {  // the zero pixel, after frames * rows_p * cols_p pixels
    if (wg == tiles && p.zero != 0u)
      for (uint i = t; i < p.cp4; i += WG) store_out(p.frames * p.rows_p * p.cols_p * p.cp4 + i, vec4(0.0));
    return;
  }
  const uint ct = wg / (rows_all * col_tiles), rest = wg % (rows_all * col_tiles);
  const uint prow_all = rest / col_tiles, pc0 = (rest % col_tiles) * PT;
  const uint q = p.q0 + prow_all / p.rows_p, prow = prow_all % p.rows_p;
  const uint c4_0 = p.c4a + ct * (CT / 4u), c4_end = min(c4_0 + CT / 4u, p.c4a + p.nc4);
  const PackRow r = pack_row(q, prow);

  // Read: invocation t takes column pc0 + t % PT of channels t / PT, + 4, + 8, ...: a subgroup reads a run of one
  // plane's row. Channels at or past cc (up to CP) and the halo are zeros.
  const uint lc = t % PT, pc = pc0 + lc;
  const bool inside = pc < p.cols_p && pack_inside(r, pc);
  [[unroll]] for (uint n = 0; n < CT * PT / WG; ++n) {
    const uint k = t / PT + n * (WG / PT), ch = c4_0 * 4u + k;
    tile[k * (PT + 1u) + lc] = inside && ch < p.cc ? pack_value(r, ch, pc) : 0.0;
  }
  barrier();

  // Write: invocation t takes vec4 t % (CT / 4) of column t / (CT / 4), + 32, ...: a subgroup writes whole runs of
  // pixels' channels.
  [[unroll]] for (uint n = 0; n < CT / 4u * PT / WG; ++n) {
    const uint i = t + n * WG, v4 = i % (CT / 4u), col = i / (CT / 4u), c4 = c4_0 + v4;
    if (pc0 + col >= p.cols_p || c4 >= c4_end) continue;
    const uint k = v4 * 4u;
    const vec4 v = vec4(tile[k * (PT + 1u) + col], tile[(k + 1u) * (PT + 1u) + col], tile[(k + 2u) * (PT + 1u) + col],
                        tile[(k + 3u) * (PT + 1u) + col]);
    store_out(((q * p.rows_p + prow) * p.cols_p + pc0 + col) * p.cp4 + c4, v);
  }
}
