#include "geometry/synthetic_scene.hpp"

#include <cmath>
#include <limits>

#include "dvs/error.hpp"

namespace dvs::geometry {

namespace {

constexpr double kGroundY = 2.0, kWallZ = 6.0, kBoxZ = 3.0, kBoxHalf = 0.5, kBoxY = 0.5;

double box_centre_x(int frame, int frames) { return frames == 1 ? 0.0 : -0.8 + 1.6 * double(frame) / double(frames - 1); }

glm::dvec3 texture(int surface, const glm::dvec3& p) {
  switch (surface) {
    case 0:  // ground: warm stripes across x and z
      return {0.4 * std::sin(3.0 * p.x) + 0.2, 0.3 * std::sin(2.0 * p.z) - 0.1, -0.3 + 0.2 * std::cos(1.5 * (p.x + p.z))};
    case 1:  // wall: cool pattern in x and y
      return {-0.2 + 0.3 * std::sin(2.5 * p.y), 0.2 + 0.3 * std::cos(2.0 * p.x), 0.5 + 0.3 * std::sin(1.7 * (p.x - p.y))};
    default:  // box: bright, varies over every face
      return {0.7 + 0.2 * std::sin(6.0 * p.y), -0.6 + 0.3 * std::sin(5.0 * (p.x + p.z)), 0.1 + 0.4 * std::cos(4.0 * p.y)};
  }
}

// Nearest hit of the ray o + t·d (t > 0): surface id and t, or id −1.
int cast(const glm::dvec3& o, const glm::dvec3& d, double box_x, double& t_hit) {
  int id = -1;
  t_hit = std::numeric_limits<double>::infinity();
  auto take = [&](double t, int s) {
    if (t > 1e-9 && t < t_hit) {
      t_hit = t;
      id = s;
    }
  };
  if (d.y > 0) {  // ground plane y = 2, seen from above, in front of the wall
    double t = (kGroundY - o.y) / d.y;
    if ((o + t * d).z <= kWallZ) take(t, 0);
  }
  if (d.z != 0) {  // wall z = 6, above the ground
    double t = (kWallZ - o.z) / d.z;
    if ((o + t * d).y <= kGroundY) take(t, 1);
  }
  // Box: slabs.
  glm::dvec3 lo(box_x - kBoxHalf, kBoxY - kBoxHalf, kBoxZ - kBoxHalf), hi(box_x + kBoxHalf, kBoxY + kBoxHalf, kBoxZ + kBoxHalf);
  double t0 = -std::numeric_limits<double>::infinity(), t1 = std::numeric_limits<double>::infinity();
  bool miss = false;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (o[a] < lo[a] || o[a] > hi[a]) miss = true;
      continue;
    }
    double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  }
  if (!miss && t0 <= t1) take(t0 > 1e-9 ? t0 : t1, 2);
  return id;
}

}  // namespace

RgbdClip render_synthetic(const SyntheticSceneSpec& spec) {
  Trajectory id;
  id.transforms.assign(size_t(std::max(spec.frames, 0)), glm::dmat4(1.0));
  return render_synthetic(spec, id);
}

RgbdClip render_synthetic(const SyntheticSceneSpec& s, const Trajectory& trajectory) {
  if (s.frames < 1 || s.height < 1 || s.width < 1) throw Error("synthetic scene: frames and size must be positive");
  if (trajectory.frames() != s.frames)
    throw Error("synthetic scene: the trajectory has " + std::to_string(trajectory.frames()) + " poses for " +
                std::to_string(s.frames) + " frames");
  if (s.K.width != s.width || s.K.height != s.height) throw Error("synthetic scene: intrinsics are for another size");
  const int F = s.frames, H = s.height, W = s.width;
  RgbdClip c{HostTensor({F, 3, H, W}, DType::f32), HostTensor({F, H, W}, DType::f32), HostTensor({F, H, W}, DType::f32)};
  const size_t plane = size_t(H) * size_t(W);
  for (int f = 0; f < F; ++f) {
    glm::dmat4 C = glm::inverse(trajectory.transforms[size_t(f)]);  // target camera → source-camera coordinates
    glm::dmat3 R(C);
    glm::dvec3 o(C[3]);
    double bx = box_centre_x(f, F);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        glm::dvec3 dc = s.K.unproject(x, y, 1.0);  // camera ray with z = 1: t is the camera depth
        glm::dvec3 d = R * dc;
        double t;
        int id = cast(o, d, bx, t);
        size_t p = size_t(f) * plane + size_t(y) * W + size_t(x);
        glm::dvec3 col(-1.0);
        if (id >= 0) {
          glm::dvec3 hit = o + t * d;
          if (id == 2) hit.x -= bx;  // the box's texture moves with it
          col = glm::clamp(texture(id, hit), -1.0, 1.0);
        }
        for (int k = 0; k < 3; ++k) c.rgb.as<float>()[(size_t(f) * 3 + size_t(k)) * plane + size_t(y) * W + size_t(x)] = float(col[k]);
        c.depth.as<float>()[p] = id >= 0 ? float(t) : 0.f;
        c.valid.as<float>()[p] = id >= 0 ? 1.f : 0.f;
      }
  }
  return c;
}

}  // namespace dvs::geometry
