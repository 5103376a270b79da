// tinygltf is header-only here: its implementation is compiled in this file only, without stb (dvs never
// reads or writes glTF images) and with the system nlohmann-json, so nothing extra has to be linked.
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

#include "geometry/trajectory_gltf.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>

#include <glm/gtc/quaternion.hpp>

#include "dvs/error.hpp"
#include "io/disk_space.hpp"
#include "io/injected_faults.hpp"

namespace dvs::geometry {

namespace {

const glm::dmat4 kFlipYZ(glm::dvec4(1, 0, 0, 0), glm::dvec4(0, -1, 0, 0), glm::dvec4(0, 0, -1, 0), glm::dvec4(0, 0, 0, 1));

bool ignore_images(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}

glm::dmat4 rigid_inverse(const glm::dmat4& m) {
  glm::dmat3 rt = glm::transpose(glm::dmat3(m));
  glm::dmat4 out(rt);
  out[3] = glm::dvec4(-(rt * glm::dvec3(m[3])), 1.0);
  return out;
}

// Floats of an accessor with `components` per element (SCALAR = 1, VEC3 = 3, VEC4 = 4).
std::vector<float> read_floats(const tinygltf::Model& m, int index, int components, const std::string& where) {
  if (index < 0 || size_t(index) >= m.accessors.size()) throw Error(where + ": accessor " + std::to_string(index) + " does not exist");
  const auto& a = m.accessors[size_t(index)];
  std::string at = where + " (accessor " + std::to_string(index) + ")";
  if (a.sparse.isSparse) throw Error(at + ": sparse accessors are not supported");
  if (a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
    throw Error(at + ": component type must be FLOAT (re-export without quantisation)");
  if (tinygltf::GetNumComponentsInType(uint32_t(a.type)) != components)
    throw Error(at + ": expected " + std::to_string(components) + " components per element");
  if (a.bufferView < 0 || size_t(a.bufferView) >= m.bufferViews.size()) throw Error(at + ": has no valid bufferView");
  const auto& bv = m.bufferViews[size_t(a.bufferView)];
  if (bv.buffer < 0 || size_t(bv.buffer) >= m.buffers.size()) throw Error(at + ": bufferView has no valid buffer");
  const auto& buf = m.buffers[size_t(bv.buffer)].data;
  size_t elem = size_t(components) * 4;
  size_t stride = bv.byteStride ? bv.byteStride : elem;
  size_t start = bv.byteOffset + a.byteOffset;
  if (a.count == 0) return {};
  size_t need = start + stride * (a.count - 1) + elem;
  if (need > buf.size() || a.byteOffset + stride * (a.count - 1) + elem > bv.byteLength)
    throw Error(at + ": data runs past the end of its buffer (truncated file?)");
  std::vector<float> out(a.count * size_t(components));
  for (size_t i = 0; i < a.count; ++i) std::memcpy(&out[i * size_t(components)], &buf[start + i * stride], elem);
  for (float v : out)
    if (!std::isfinite(v)) throw Error(at + ": contains a non-finite value");
  return out;
}

struct Channel {
  std::string path;  // translation | rotation | scale
  std::string interpolation;
  std::vector<float> times, values;
};

glm::dvec4 sample_channel(const Channel& c, double t) {
  const int n = c.path == "rotation" ? 4 : 3;
  auto value = [&](size_t k) {
    glm::dvec4 v(0.0);
    for (int i = 0; i < n; ++i) v[i] = c.values[k * size_t(n) + size_t(i)];
    return v;
  };
  const auto& T = c.times;
  if (t <= T.front()) return value(0);
  if (t >= T.back()) return value(T.size() - 1);
  size_t k = size_t(std::upper_bound(T.begin(), T.end(), float(t)) - T.begin()) - 1;
  k = std::min(k, T.size() - 2);
  if (c.interpolation == "STEP") return value(k);
  double span = double(T[k + 1]) - double(T[k]);
  double f = span > 0 ? (t - double(T[k])) / span : 0.0;
  f = std::clamp(f, 0.0, 1.0);
  glm::dvec4 a = value(k), b = value(k + 1);
  if (n == 4) {
    glm::dquat qa(a.w, a.x, a.y, a.z), qb(b.w, b.x, b.y, b.z);
    glm::dquat q = glm::slerp(qa, qb, f);
    return {q.x, q.y, q.z, q.w};
  }
  return a + (b - a) * f;
}

struct NodeAnimation {
  std::vector<Channel> channels;
};

glm::dmat4 static_local(const tinygltf::Node& n) {
  if (n.matrix.size() == 16) {
    glm::dmat4 m;
    for (int i = 0; i < 16; ++i) m[i / 4][i % 4] = n.matrix[size_t(i)];  // glTF matrices are column-major
    return m;
  }
  glm::dvec3 t(0.0), s(1.0);
  glm::dquat q(1, 0, 0, 0);
  if (n.translation.size() == 3) t = {n.translation[0], n.translation[1], n.translation[2]};
  if (n.rotation.size() == 4) q = glm::dquat(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
  if (n.scale.size() == 3) s = {n.scale[0], n.scale[1], n.scale[2]};
  glm::dmat4 m = glm::dmat4(glm::mat3_cast(glm::normalize(q)));
  m[0] *= s.x;
  m[1] *= s.y;
  m[2] *= s.z;
  m[3] = glm::dvec4(t, 1.0);
  return m;
}

glm::dmat4 animated_local(const tinygltf::Node& n, const NodeAnimation* anim, double t) {
  if (!anim || anim->channels.empty()) return static_local(n);
  glm::dvec3 tr(0.0), s(1.0);
  glm::dquat q(1, 0, 0, 0);
  if (n.translation.size() == 3) tr = {n.translation[0], n.translation[1], n.translation[2]};
  if (n.rotation.size() == 4) q = glm::dquat(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
  if (n.scale.size() == 3) s = {n.scale[0], n.scale[1], n.scale[2]};
  for (const auto& c : anim->channels) {
    glm::dvec4 v = sample_channel(c, t);
    if (c.path == "translation") tr = glm::dvec3(v);
    else if (c.path == "scale") s = glm::dvec3(v);
    else q = glm::dquat(v.w, v.x, v.y, v.z);
  }
  glm::dmat4 m = glm::dmat4(glm::mat3_cast(glm::normalize(q)));
  m[0] *= s.x;
  m[1] *= s.y;
  m[2] *= s.z;
  m[3] = glm::dvec4(tr, 1.0);
  return m;
}

void load_model(const std::filesystem::path& path, tinygltf::Model& model) {
  if (!std::filesystem::exists(path)) throw Error(path.string() + ": no such glTF file");
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(ignore_images, nullptr);
  std::string err, warn;
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  bool ok = ext == ".glb" ? loader.LoadBinaryFromFile(&model, &err, &warn, path.string())
                          : loader.LoadASCIIFromFile(&model, &err, &warn, path.string());
  if (!ok || !err.empty()) {
    while (!err.empty() && (err.back() == '\n')) err.pop_back();
    throw Error(path.string() + ": not a readable glTF 2.0 file (" + (err.empty() ? std::string("unknown error") : err) + ")");
  }
}

void append_bytes(std::vector<unsigned char>& buf, const void* data, size_t bytes) {
  while (buf.size() % 4) buf.push_back(0);
  const auto* p = static_cast<const unsigned char*>(data);
  buf.insert(buf.end(), p, p + bytes);
}

int add_accessor(tinygltf::Model& m, const void* data, size_t count, int type, int components, int target,
                 std::vector<double> min = {}, std::vector<double> max = {}) {
  auto& buf = m.buffers[0].data;
  while (buf.size() % 4) buf.push_back(0);
  tinygltf::BufferView bv;
  bv.buffer = 0;
  bv.byteOffset = buf.size();
  bv.byteLength = count * size_t(components) * 4;
  if (target) bv.target = target;
  append_bytes(buf, data, bv.byteLength);
  m.bufferViews.push_back(bv);
  tinygltf::Accessor a;
  a.bufferView = int(m.bufferViews.size() - 1);
  a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  a.count = count;
  a.type = type;
  a.minValues = std::move(min);
  a.maxValues = std::move(max);
  m.accessors.push_back(a);
  return int(m.accessors.size() - 1);
}

void bounds(const std::vector<float>& xyz, std::vector<double>& lo, std::vector<double>& hi) {
  lo.assign(3, std::numeric_limits<double>::max());
  hi.assign(3, std::numeric_limits<double>::lowest());
  for (size_t i = 0; i < xyz.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], double(xyz[i]));
    hi[i % 3] = std::max(hi[i % 3], double(xyz[i]));
  }
}

}  // namespace

Trajectory read_gltf_trajectory(const std::filesystem::path& path, const GltfCameraOptions& o) {
  const std::string name = path.string();
  if (o.frames < 1) throw Error(name + ": the number of frames to sample must be at least 1");
  tinygltf::Model model;
  load_model(path, model);

  // Animation channels per node.
  std::map<int, NodeAnimation> anims;
  for (size_t ai = 0; ai < model.animations.size(); ++ai) {
    const auto& an = model.animations[ai];
    for (size_t ci = 0; ci < an.channels.size(); ++ci) {
      const auto& ch = an.channels[ci];
      std::string where = name + ": animations[" + std::to_string(ai) + "].channels[" + std::to_string(ci) + "]";
      if (ch.target_path == "weights") continue;
      if (ch.target_path != "translation" && ch.target_path != "rotation" && ch.target_path != "scale")
        throw Error(where + ": unknown target.path '" + ch.target_path + "'");
      if (ch.target_node < 0 || size_t(ch.target_node) >= model.nodes.size())
        throw Error(where + ": target.node " + std::to_string(ch.target_node) + " does not exist");
      if (ch.sampler < 0 || size_t(ch.sampler) >= an.samplers.size())
        throw Error(where + ": sampler " + std::to_string(ch.sampler) + " does not exist");
      const auto& s = an.samplers[size_t(ch.sampler)];
      Channel c;
      c.path = ch.target_path;
      c.interpolation = s.interpolation.empty() ? "LINEAR" : s.interpolation;
      if (c.interpolation != "LINEAR" && c.interpolation != "STEP")
        throw Error(where + ": interpolation " + c.interpolation + " is not supported (use LINEAR or STEP)");
      c.times = read_floats(model, s.input, 1, where + " sampler input");
      c.values = read_floats(model, s.output, c.path == "rotation" ? 4 : 3, where + " sampler output");
      if (c.times.empty()) throw Error(where + ": the sampler has no keyframes");
      if (c.values.size() != c.times.size() * (c.path == "rotation" ? 4u : 3u))
        throw Error(where + ": sampler input and output have different keyframe counts");
      for (size_t k = 1; k < c.times.size(); ++k)
        if (c.times[k] < c.times[k - 1]) throw Error(where + ": keyframe times are not increasing");
      anims[ch.target_node].channels.push_back(std::move(c));
    }
  }

  // The camera node.
  int node = -1;
  if (!o.node.empty()) {
    for (size_t i = 0; i < model.nodes.size(); ++i)
      if (model.nodes[i].name == o.node) node = int(i);
    if (node < 0) throw Error(name + ": no node named '" + o.node + "'");
  } else {
    for (size_t i = 0; i < model.nodes.size() && node < 0; ++i)
      if (model.nodes[i].camera >= 0) node = int(i);
    if (node < 0 && !anims.empty()) node = anims.begin()->first;
    if (node < 0) throw Error(name + ": has no camera node and no animated node to follow");
  }

  std::vector<int> parent(model.nodes.size(), -1);
  for (size_t i = 0; i < model.nodes.size(); ++i)
    for (int c : model.nodes[i].children)
      if (c >= 0 && size_t(c) < model.nodes.size()) parent[size_t(c)] = int(i);
  std::vector<int> chain;  // node, its parent, ..., root
  for (int n = node; n >= 0; n = parent[size_t(n)]) {
    if (chain.size() > model.nodes.size()) throw Error(name + ": the node hierarchy has a cycle");
    chain.push_back(n);
  }

  double t0 = std::numeric_limits<double>::max(), t1 = std::numeric_limits<double>::lowest();
  for (int n : chain)
    if (auto it = anims.find(n); it != anims.end())
      for (const auto& c : it->second.channels) {
        t0 = std::min(t0, double(c.times.front()));
        t1 = std::max(t1, double(c.times.back()));
      }
  if (t0 > t1) t0 = t1 = 0;  // a static camera

  std::vector<glm::dmat4> cams;
  for (int i = 0; i < o.frames; ++i) {
    double t = o.fps > 0 ? t0 + i / o.fps : (o.frames == 1 ? t0 : t0 + (t1 - t0) * double(i) / double(o.frames - 1));
    glm::dmat4 g(1.0);
    for (int n : chain) {
      auto it = anims.find(n);
      g = animated_local(model.nodes[size_t(n)], it == anims.end() ? nullptr : &it->second, t) * g;
    }
    for (int c = 0; c < 3; ++c) {
      double len = glm::length(glm::dvec3(g[c]));
      if (!(len > 1e-12)) throw Error(name + ": camera node '" + model.nodes[size_t(node)].name + "' has a degenerate (zero) scale");
      g[c] /= len;
    }
    cams.push_back(g * kFlipYZ);  // glTF camera axes → OpenCV camera axes
  }
  Trajectory tr;
  tr.description = "glTF camera '" + model.nodes[size_t(node)].name + "' from " + name;
  for (const auto& c : cams) {
    glm::dmat4 T = rigid_inverse(c) * cams[0];
    T[3] = glm::dvec4(glm::dvec3(T[3]) * o.translation_scale, 1.0);
    tr.transforms.push_back(T);
  }
  return tr;
}

PointCloud point_cloud_from_rgbd(const float* rgb, const float* depth, int H, int W, const Intrinsics& K, int stride) {
  if (stride < 1) stride = 1;
  PointCloud pc;
  const size_t plane = size_t(H) * size_t(W);
  for (int y = 0; y < H; y += stride)
    for (int x = 0; x < W; x += stride) {
      size_t p = size_t(y) * size_t(W) + size_t(x);
      float z = depth[p];
      if (!std::isfinite(z) || z <= 0) continue;
      glm::dvec3 X = K.unproject(x, y, z);
      pc.positions.emplace_back(X);
      glm::vec3 c;
      for (int k = 0; k < 3; ++k) c[k] = std::clamp((rgb[size_t(k) * plane + p] + 1.0f) * 0.5f, 0.0f, 1.0f);
      pc.colors.push_back(c);
    }
  return pc;
}

PointCloud clip_far_points(const PointCloud& cloud, double ratio) {
  if (!(ratio > 0) || cloud.positions.empty()) return cloud;
  std::vector<float> z;
  z.reserve(cloud.positions.size());
  for (const auto& p : cloud.positions) z.push_back(p.z);
  std::nth_element(z.begin(), z.begin() + std::ptrdiff_t(z.size() / 2), z.end());
  const double limit = ratio * double(z[z.size() / 2]);
  PointCloud out;
  for (size_t i = 0; i < cloud.positions.size(); ++i)
    if (double(cloud.positions[i].z) <= limit) {
      out.positions.push_back(cloud.positions[i]);
      if (i < cloud.colors.size()) out.colors.push_back(cloud.colors[i]);
    }
  return out;
}

void write_trajectory_glb(const std::filesystem::path& path, const Trajectory& trajectory, const PointCloud* full_cloud,
                          const GlbExportOptions& options) {
  if (trajectory.transforms.empty()) throw Error(path.string() + ": cannot export an empty trajectory");
  if (!(options.fps > 0)) throw Error(path.string() + ": export fps must be > 0");
  tinygltf::Model m;
  m.asset.version = "2.0";
  m.asset.generator = "dvs";
  m.buffers.resize(1);
  tinygltf::Scene scene;
  scene.name = "dvs";

  // World for viewers: the source camera with y and z flipped (y-up, camera looking down −z).
  auto to_world = [](const glm::dvec3& p) { return glm::vec3(float(p.x), float(-p.y), float(-p.z)); };

  if (full_cloud && full_cloud->colors.size() != full_cloud->positions.size())
    throw Error(path.string() + ": point cloud has " + std::to_string(full_cloud->positions.size()) + " positions but " +
                std::to_string(full_cloud->colors.size()) + " colours");
  PointCloud clipped;
  if (full_cloud) clipped = clip_far_points(*full_cloud, options.far_clip_over_median);
  const PointCloud* cloud = full_cloud ? &clipped : nullptr;
  double extent = 1.0;  // the farthest point or camera centre from the origin: zfar goes beyond it
  if (cloud && !cloud->positions.empty()) {
    if (cloud->colors.size() != cloud->positions.size())
      throw Error(path.string() + ": point cloud has " + std::to_string(cloud->positions.size()) + " positions but " +
                  std::to_string(cloud->colors.size()) + " colours");
    std::vector<float> pos, col;
    for (size_t i = 0; i < cloud->positions.size(); ++i) {
      glm::vec3 w = to_world(glm::dvec3(cloud->positions[i]));
      pos.insert(pos.end(), {w.x, w.y, w.z});
      extent = std::max(extent, double(glm::length(w)));
      col.insert(col.end(), {cloud->colors[i].x, cloud->colors[i].y, cloud->colors[i].z});
    }
    std::vector<double> lo, hi;
    bounds(pos, lo, hi);
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_POINTS;
    prim.attributes["POSITION"] = add_accessor(m, pos.data(), pos.size() / 3, TINYGLTF_TYPE_VEC3, 3,
                                               TINYGLTF_TARGET_ARRAY_BUFFER, lo, hi);
    prim.attributes["COLOR_0"] = add_accessor(m, col.data(), col.size() / 3, TINYGLTF_TYPE_VEC3, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    tinygltf::Mesh mesh;
    mesh.name = "point_cloud";
    mesh.primitives.push_back(prim);
    m.meshes.push_back(mesh);
    tinygltf::Node n;
    n.name = "point_cloud";
    n.mesh = int(m.meshes.size() - 1);
    m.nodes.push_back(n);
    scene.nodes.push_back(int(m.nodes.size() - 1));
  }

  // Camera keyframes: C_gltf = S · C_cv · S, C_cv = T⁻¹ (S = diag(1,−1,−1) flips the world and the camera axes).
  std::vector<float> times, trans, rots, centres;
  for (size_t i = 0; i < trajectory.transforms.size(); ++i) {
    glm::dmat4 C = kFlipYZ * rigid_inverse(trajectory.transforms[i]) * kFlipYZ;
    glm::dquat q = glm::normalize(glm::quat_cast(glm::dmat3(C)));
    times.push_back(float(double(i) / options.fps));
    trans.insert(trans.end(), {float(C[3].x), float(C[3].y), float(C[3].z)});
    rots.insert(rots.end(), {float(q.x), float(q.y), float(q.z), float(q.w)});
    centres.insert(centres.end(), {float(C[3].x), float(C[3].y), float(C[3].z)});
    extent = std::max(extent, glm::length(glm::dvec3(C[3])));
  }
  tinygltf::Camera cam;
  cam.type = "perspective";
  cam.name = "target_camera";
  if (options.intrinsics) {
    cam.perspective.yfov = 2.0 * std::atan(0.5 * options.intrinsics->height / options.intrinsics->fy);
    cam.perspective.aspectRatio = double(options.intrinsics->width) / options.intrinsics->height;
  } else {
    cam.perspective.yfov = 60.0 * 3.14159265358979323846 / 180.0;
  }
  cam.perspective.znear = 0.01;
  // Any camera position sees every point within twice the extent (both lie within `extent` of the origin).
  cam.perspective.zfar = 2.0 * extent + 1.0;
  m.cameras.push_back(cam);
  tinygltf::Node cn;
  cn.name = "camera";
  cn.camera = 0;
  cn.translation = {trans[0], trans[1], trans[2]};
  cn.rotation = {rots[0], rots[1], rots[2], rots[3]};
  m.nodes.push_back(cn);
  int cam_node = int(m.nodes.size() - 1);
  scene.nodes.push_back(cam_node);

  tinygltf::Animation anim;
  anim.name = "camera_path";
  int in = add_accessor(m, times.data(), times.size(), TINYGLTF_TYPE_SCALAR, 1, 0, {double(times.front())},
                        {double(times.back())});
  int out_t = add_accessor(m, trans.data(), times.size(), TINYGLTF_TYPE_VEC3, 3, 0);
  int out_r = add_accessor(m, rots.data(), times.size(), TINYGLTF_TYPE_VEC4, 4, 0);
  for (int k = 0; k < 2; ++k) {
    tinygltf::AnimationSampler s;
    s.input = in;
    s.output = k == 0 ? out_t : out_r;
    s.interpolation = "LINEAR";
    anim.samplers.push_back(s);
    tinygltf::AnimationChannel c;
    c.sampler = k;
    c.target_node = cam_node;
    c.target_path = k == 0 ? "translation" : "rotation";
    anim.channels.push_back(c);
  }
  m.animations.push_back(anim);

  if (centres.size() >= 6) {
    std::vector<double> lo, hi;
    bounds(centres, lo, hi);
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_LINE_STRIP;
    prim.attributes["POSITION"] = add_accessor(m, centres.data(), centres.size() / 3, TINYGLTF_TYPE_VEC3, 3,
                                               TINYGLTF_TARGET_ARRAY_BUFFER, lo, hi);
    tinygltf::Mesh mesh;
    mesh.name = "camera_path";
    mesh.primitives.push_back(prim);
    m.meshes.push_back(mesh);
    tinygltf::Node n;
    n.name = "camera_path";
    n.mesh = int(m.meshes.size() - 1);
    m.nodes.push_back(n);
    scene.nodes.push_back(int(m.nodes.size() - 1));
  }
  m.scenes.push_back(scene);
  m.defaultScene = 0;

  std::filesystem::path tmp = path;
  tmp += ".tmp";
  tinygltf::TinyGLTF writer;
  const int injected = faults::write_error(path);
  if (!writer.WriteGltfSceneToFile(&m, tmp.string(), false, true, false, true) || injected) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    const std::string full =
        injected ? write_error_note(injected, path.parent_path()) : no_space_note(path.parent_path());
    throw Error(path.string() + ": could not write the .glb file" + (full.empty() ? std::string() : ": " + full));
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace dvs::geometry
