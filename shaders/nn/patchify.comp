#version 450
#extension GL_GOOGLE_include_directive : require
// nn/patchify and its variants (shaders/variants.cmake: INVERSE, P2). One invocation moves the C p×p patches of one token between
//   image [BF, C, H, W]                 (H = Hp·p, W = Wp·p)
//   tokens [BF, Hp, Wp, C, p, p]        (= [B, F·Hp·Wp, C·p·p], features in (c, i, j) order)
// pixel (hp·p + i, wp·p + j) of channel c <-> feature (c, i, j) of token (hp, wp).
// INVERSE: tokens -> image (CogVideoX unpatchify); otherwise image -> tokens (input of the patch conv).
// P2: p = 2 with vec2 rows on the image side and one vec4 per patch on the token side; otherwise p from push
// constants and single floats.
layout(local_size_x = 32) in;
#ifdef P2
#define TI vec2
#define TT vec4
#else
#define TI float
#define TT float
#endif
#ifdef INVERSE
layout(std430, binding = 0) readonly buffer Tok { TT tok[]; };
layout(std430, binding = 1) writeonly buffer Img { TI img[]; };
#else
layout(std430, binding = 0) readonly buffer Img { TI img[]; };
layout(std430, binding = 1) writeonly buffer Tok { TT tok[]; };
#endif
layout(push_constant) uniform Push {
  uint rows;  // BF · Hp: one (frame, patch row) per y step
  uint C, Hp, Wp, p;
} u;

// y steps over (bf, hp), x over wp, and each invocation walks the C channels of its token: the index
// arithmetic inside the loops is adds and multiplies only (run-time divisions are slow on CPU drivers).
void main() {
  uint stride_x = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint q = gl_WorkGroupID.y; q < u.rows; q += gl_NumWorkGroups.y) {
    uint hp = q % u.Hp, bf = q / u.Hp;
    for (uint wp = gl_GlobalInvocationID.x; wp < u.Wp; wp += stride_x) {
      uint t0 = (q * u.Wp + wp) * u.C;  // patch (token (bf, hp, wp), channel 0)
#ifdef P2
      // Image rows of 2 floats: vec2 index ((bf·C + c)·H + 2hp + i)·Wp + wp; one channel plane = 2·Hp·Wp.
      uint plane = 2u * u.Hp * u.Wp, img0 = (bf * u.C * 2u * u.Hp + hp * 2u) * u.Wp + wp;
      for (uint c = 0u; c < u.C; ++c) {
        uint r0 = img0 + c * plane;
#ifdef INVERSE
        vec4 v = tok[t0 + c];
        img[r0] = v.xy;
        img[r0 + u.Wp] = v.zw;
#else
        tok[t0 + c] = vec4(img[r0], img[r0 + u.Wp]);
#endif
      }
#else
      uint W = u.Wp * u.p, plane = u.Hp * u.p * W, img0 = bf * u.C * plane + hp * u.p * W + wp * u.p;
      for (uint c = 0u; c < u.C; ++c)
        for (uint i = 0u; i < u.p; ++i)
          for (uint j = 0u; j < u.p; ++j) {
            uint ti = ((t0 + c) * u.p + i) * u.p + j, ii = img0 + c * plane + i * W + j;
#ifdef INVERSE
            img[ii] = tok[ti];
#else
            tok[ti] = img[ii];
#endif
          }
#endif
    }
  }
}
