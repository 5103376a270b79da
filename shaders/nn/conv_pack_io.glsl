// What the two input repacks of a convolution chunk share (conv_pack_input.comp, one invocation per vec4 of channels
// of a few pixels; conv_pack_input_tiled.comp, a tile of channels x pixels transposed through shared memory): their
// bindings, push constants (engine/src/tensor/ops_conv_pack.cpp's PackInputPush), the packed element's type and where
// a packed row's source values are. conv_pack_input.comp's header describes the layout and every field.
layout(constant_id = 0) const bool OUT_F16 = false;

layout(binding = 0) uniform textureBuffer X;      // R32F, [B, C, F, H, W]
layout(binding = 1) uniform textureBuffer Cache;  // R32F, [B, C, prefix, H, W] (time_mode 3; else any)
layout(std430, binding = 2) buffer Out { vec4 o[]; };
layout(std430, binding = 2) buffer OutH { uvec2 oh[]; };  // OUT_F16

vec4 load_out(uint i) { return OUT_F16 ? vec4(unpackHalf2x16(oh[i].x), unpackHalf2x16(oh[i].y)) : o[i]; }
void store_out(uint i, vec4 v) {
  if (OUT_F16) {
    oh[i] = uvec2(packHalf2x16(v.xy), packHalf2x16(v.zw));
  } else {
    o[i] = v;
  }
}

layout(push_constant) uniform Push {
  uint cp4;           // CP / 4
  uint c, src_frames, h, w;
  uint batch;         // batch item packed
  uint tp0, frames, r0, rows;
  uint prefix, time_mode;
  uint c0, cc;         // the chunk's first input channel, its channel count
  uint q0, nq;         // packed frames of this dispatch
  uint ca, cb;         // chunk channels of this dispatch (cb == cc: also the zero channels up to cp)
  uint c4a, nc4;       // vec4 columns of this dispatch
  uint x_base, cache_base;  // element of x / cache at the start of the bound views
  uint zero, partial;  // 1: also write the zero pixel; 1: merge into the existing vec4s
  uint col0, wc;       // source columns [col0, col0 + wc) (w: x's width)
  uint seg;           // packed pixels of a row per invocation (conv_pack_input.comp)
  uint halo_top, rows_p, halo_left, cols_p;  // the packed grid
  uint up_shift;      // 1: rows and columns of the x2 upsampling
} p;

// Where packed row `prow` of packed frame q (counted from tp0) reads: whether it is a source row (not the halo),
// whether its frame comes from the cache, and the bound view's element of chunk channel 0 at the row's column 0
// (channel ch adds ch times chan_stride; x's column col0 + col >> up_shift is added by pack_element).
struct PackRow {
  bool row_in, from_cache;
  uint base, chan_stride;
};

PackRow pack_row(uint q, uint prow) {
  PackRow r;
  r.row_in = prow >= p.halo_top && prow - p.halo_top < p.rows;
  const uint row = p.r0 + prow - p.halo_top, tp = p.tp0 + q;
  r.from_cache = p.time_mode == 3u && tp < p.prefix;
  uint frame;
  if (p.time_mode == 1u) frame = tp == 0u ? 0u : 1u + (tp - 1u) / 2u;
  else if (p.time_mode == 2u) frame = tp / 2u;
  else if (p.time_mode == 3u) frame = r.from_cache ? tp : tp - p.prefix;
  else frame = uint(max(int(tp) - int(p.prefix), 0));
  const uint frames = r.from_cache ? p.prefix : p.src_frames, hw = p.h * p.w;
  r.chan_stride = frames * hw;
  r.base = ((p.batch * p.c + p.c0) * frames + frame) * hw + (row >> p.up_shift) * p.w;
  r.base -= r.from_cache ? p.cache_base : p.x_base;
  return r;
}

// Whether packed column pc is a source column (not the halo) of a source row.
bool pack_inside(PackRow r, uint pc) { return r.row_in && pc >= p.halo_left && pc - p.halo_left < p.wc; }

// The source value of chunk channel ch (below cc) at packed column pc (pack_inside).
float pack_value(PackRow r, uint ch, uint pc) {
  const int at = int(r.base + ch * r.chan_stride + ((p.col0 + pc - p.halo_left) >> p.up_shift));
  return r.from_cache ? texelFetch(Cache, at).x : texelFetch(X, at).x;
}
