// Shared by the splat renderer's passes: push constants, unprojection/transform/projection of one source
// pixel, and the official bilinear splat footprint (docs/design.md §6.3).
//
// The projection is computed as the source pixel plus its displacement, not as K·X2/X2.z from scratch: the float
// round trip unproject → project misses the pixel by a few ulps (u = x ± 4e-6 at 80 px wide), which the footprint
// turns into a weight of ~1e-6 on a neighbour, and the depth weighting exp(−50ρ) multiplies that by up to e^50
// where the neighbour is nearer: at the identity pose row 0 of a far sky came back as the row below it (up to 210
// levels off). The displacement of the identity (T − I = 0, equal intrinsics) is exactly zero, so every pixel lands
// on itself; for any other pose the value is the same up to rounding.
//
// The point passes run one frame per dispatch over a (W/64, H) grid, so the frame's transform lives in
// push constants (uniform, no per-lane buffer loads) and no pixel index needs a division.
// Every pass binds depth [F,H,W] f32 as binding 0.

layout(push_constant) uniform Push {
  uint H, W;      // source and target image size
  uint frame;     // the frame this dispatch renders
  uint flags;     // bit 0: keep points behind the camera (official behaviour)
  vec4 src_k;     // fx, fy, cx, cy of the source camera
  vec4 k_map;     // target vs source camera: fx_d/fx_s − 1, fy_d/fy_s − 1, cx_d − cx_s, cy_d − cy_s (0 when equal)
  vec4 t0, t1, t2;  // rows 0..2 of T − I (T: source-camera → target-camera coordinates, OpenCV axes)
} p;

const uint FLAG_KEEP_BEHIND = 1u;

// Source pixel (x, y) at depth z moved into the target camera: ray = K_src⁻¹ (x, y, 1) (integer pixel
// coordinates, no +0.5, as the official code), X1 = z · ray, its displacement D = (T − I) X1 + t, X2 = X1 + D.
struct MovedPoint {
  vec2 ray;  // X1 / z
  vec3 D;    // X2 − X1
  vec3 X2;   // the target-camera point
};
MovedPoint move_point(uint x, uint y, float z) {
  MovedPoint m;
  m.ray = vec2((float(x) - p.src_k.z) / p.src_k.x, (float(y) - p.src_k.w) / p.src_k.y);
  const vec3 X1 = vec3(z * m.ray, z);
  m.D.x = p.t0.x * X1.x + p.t0.y * X1.y + p.t0.z * X1.z + p.t0.w;
  m.D.y = p.t1.x * X1.x + p.t1.y * X1.y + p.t1.z * X1.z + p.t1.w;
  m.D.z = p.t2.x * X1.x + p.t2.y * X1.y + p.t2.z * X1.z + p.t2.w;
  m.X2 = X1 + m.D;
  return m;
}

// Whether a projected point takes part: finite, and in front of the camera unless the official behaviour
// (keep points behind it) was asked for; a point exactly on the camera plane cannot be projected.
bool point_used(vec3 X2) {
  if (isnan(X2.x) || isnan(X2.y) || isnan(X2.z) || isinf(X2.x) || isinf(X2.y) || isinf(X2.z)) return false;
  if ((p.flags & FLAG_KEEP_BEHIND) != 0u) return X2.z != 0.0;
  return X2.z > 0.0;
}

// (u, v) = K_dst X2 / X2.z of source pixel (x, y), as the pixel plus its displacement:
//   u = fx_d (ray.x + Δ.x) + cx_d = x + (fx_d/fx_s − 1)(x − cx_s) + (cx_d − cx_s) + fx_d Δ.x,
//   Δ = X2.xy / X2.z − ray = (D.xy − ray · D.z) / X2.z   (exactly 0 when D = 0).
vec2 project_point(uint x, uint y, MovedPoint m) {
  const vec2 pixel = vec2(float(x), float(y));
  const vec2 f_dst = p.src_k.xy * (1.0 + p.k_map.xy);
  const vec2 delta = (m.D.xy - m.ray * m.D.z) / m.X2.z;
  return pixel + p.k_map.xy * (pixel - p.src_k.zw) + p.k_map.zw + f_dst * delta;
}

// Normalised log depth ρ = log(1 + clamp(z, 0, 1000)) / max over the frame (max_l ≤ 0: every ρ is 0).
float log_depth(float z) { return log(1.0 + clamp(z, 0.0, 1000.0)); }

// The official footprint in the buffer padded by one pixel: o = (u+1, v+1), f = floor(o), c = ceil(o),
// o, f, c clamped independently to [0, W+1] × [0, H+1]. Corner k (nw, sw, ne, se) goes to padded pixel
// corner[k] with weight w[k]. Returns false for non-finite coordinates.
bool footprint(vec2 uv, out ivec2 corner[4], out float w[4]) {
  if (isnan(uv.x) || isnan(uv.y) || isinf(uv.x) || isinf(uv.y)) return false;
  vec2 o = uv + 1.0;
  vec2 f = floor(o), c = ceil(o);
  vec2 hi = vec2(float(p.W + 1u), float(p.H + 1u));
  o = clamp(o, vec2(0.0), hi);
  f = clamp(f, vec2(0.0), hi);
  c = clamp(c, vec2(0.0), hi);
  corner[0] = ivec2(f);                // nw: (f_y, f_x)
  corner[1] = ivec2(f.x, c.y);         // sw: (c_y, f_x)
  corner[2] = ivec2(c.x, f.y);         // ne: (f_y, c_x)
  corner[3] = ivec2(c);                // se: (c_y, c_x)
  w[0] = (1.0 - (o.y - f.y)) * (1.0 - (o.x - f.x));
  w[1] = (1.0 - (c.y - o.y)) * (1.0 - (o.x - f.x));
  w[2] = (1.0 - (o.y - f.y)) * (1.0 - (c.x - o.x));
  w[3] = (1.0 - (c.y - o.y)) * (1.0 - (c.x - o.x));
  return true;
}

// Flat index into the UNPADDED [F,H,W] accumulation buffers of a padded-buffer pixel, or -1 for the
// one-pixel border ring that the official code crops (nothing written there can reach the output).
int interior_index(ivec2 padded) {
  if (padded.x < 1 || padded.y < 1 || padded.x > int(p.W) || padded.y > int(p.H)) return -1;
  return int((p.frame * p.H + uint(padded.y - 1)) * p.W + uint(padded.x - 1));
}

// This invocation's source pixel; false past the right edge.
bool source_pixel(out uint x, out uint y, out uint i) {
  x = gl_GlobalInvocationID.x;
  y = gl_WorkGroupID.y;
  i = (p.frame * p.H + y) * p.W + x;
  return x < p.W;
}
