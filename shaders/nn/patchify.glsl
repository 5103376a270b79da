// Body of the patchify shaders. One invocation moves one p×p patch of one channel between
//   image [BF, C, H, W]                 (H = Hp·p, W = Wp·p)
//   tokens [BF, Hp, Wp, C, p, p]        (= [B, F·Hp·Wp, C·p·p], features in (c, i, j) order)
// pixel (hp·p + i, wp·p + j) of channel c <-> feature (c, i, j) of token (hp, wp).
// INVERSE: tokens -> image (CogVideoX unpatchify); otherwise image -> tokens (input of the patch conv).
// P2: p = 2 with vec2 rows on the image side and one vec4 per patch on the token side; otherwise p from push
// constants and single floats. Invocations run in token order, so token-side accesses are contiguous.
layout(local_size_x = 64) in;
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
  uint n;  // BF · Hp · Wp · C patches
  uint C, Hp, Wp, p;
} u;

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint t = gl_GlobalInvocationID.x; t < u.n; t += stride) {
    uint c = t % u.C, q = t / u.C;
    uint wp = q % u.Wp;
    q /= u.Wp;
    uint hp = q % u.Hp, bf = q / u.Hp;
#ifdef P2
    // Image rows of 2 floats at (bf, c, 2hp + i, 2wp): vec2 index = ((bf·C + c)·H + 2hp + i)·Wp + wp.
    uint row0 = ((bf * u.C + c) * u.Hp * 2u + hp * 2u) * u.Wp + wp;
#ifdef INVERSE
    vec4 v = tok[t];
    img[row0] = v.xy;
    img[row0 + u.Wp] = v.zw;
#else
    tok[t] = vec4(img[row0], img[row0 + u.Wp]);
#endif
#else
    uint W = u.Wp * u.p;
    uint base = ((bf * u.C + c) * u.Hp * u.p + hp * u.p) * W + wp * u.p;
    for (uint i = 0u; i < u.p; ++i)
      for (uint j = 0u; j < u.p; ++j) {
#ifdef INVERSE
        img[base + i * W + j] = tok[(t * u.p + i) * u.p + j];
#else
        tok[(t * u.p + i) * u.p + j] = img[base + i * W + j];
#endif
      }
#endif
  }
}
