#include "geometry/trajectory.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "dvs/error.hpp"
#include "geometry/trajectory_gltf.hpp"
#include "geometry/trajectory_json.hpp"
#include "geometry/trajectory_official_tables.hpp"
#include "geometry/trajectory_text.hpp"

namespace dvs::geometry {

namespace {

constexpr double kPi = 3.14159265358979323846;
double deg2rad(double d) { return d * kPi / 180.0; }

// Values at linspace(0,1,frames) of the piecewise-linear function through knots at linspace(0,1,n).
std::vector<double> resample_linear(const std::vector<double>& y, int frames) {
  std::vector<double> out(static_cast<size_t>(frames));
  const size_t n = y.size();
  for (int i = 0; i < frames; ++i) {
    if (n == 1) {
      out[size_t(i)] = y[0];
      continue;
    }
    double t = frames == 1 ? 0.0 : double(i) / (frames - 1) * double(n - 1);
    size_t k = std::min(size_t(t), n - 2);
    double f = t - double(k);
    out[size_t(i)] = y[k] + (y[k + 1] - y[k]) * f;
  }
  return out;
}

// Natural cubic spline through (x_k = k/(n-1), y_k), evaluated at linspace(0,1,frames).
std::vector<double> resample_natural_spline(const std::vector<double>& y, int frames) {
  const size_t n = y.size();
  const double h = 1.0 / double(n - 1);
  // Second derivatives m_k with m_0 = m_{n-1} = 0: tridiagonal system (Thomas algorithm).
  std::vector<double> m(n, 0.0), c(n, 0.0), d(n, 0.0);
  for (size_t k = 1; k + 1 < n; ++k) {
    double rhs = 6.0 * (y[k + 1] - 2.0 * y[k] + y[k - 1]) / (h * h);
    double diag = 4.0, lower = 1.0;
    double denom = diag - lower * c[k - 1];
    c[k] = 1.0 / denom;
    d[k] = (rhs - lower * d[k - 1]) / denom;
  }
  for (size_t k = n - 2; k >= 1; --k) {
    m[k] = d[k] - c[k] * m[k + 1];
    if (k == 1) break;
  }
  std::vector<double> out(static_cast<size_t>(frames));
  for (int i = 0; i < frames; ++i) {
    double x = frames == 1 ? 0.0 : double(i) / (frames - 1);
    size_t k = std::min(size_t(x / h), n - 2);
    double a = (double(k + 1) * h - x) / h, b = 1.0 - a;
    out[size_t(i)] = a * y[k] + b * y[k + 1] + ((a * a * a - a) * m[k] + (b * b * b - b) * m[k + 1]) * h * h / 6.0;
  }
  return out;
}

std::vector<double> interpolate_list(const std::vector<double>& y, int frames) {
  std::vector<double> out = y.size() <= 3 ? resample_linear(y, frames) : resample_natural_spline(y, frames);
  out.front() = y.front();
  if (frames > 1) out.back() = y.back();
  return out;
}

glm::dmat4 rigid_inverse(const glm::dmat4& m) {
  glm::dmat3 r(m);
  glm::dmat3 rt = glm::transpose(r);
  glm::dvec3 t(m[3]);
  glm::dmat4 out(rt);
  out[3] = glm::dvec4(-(rt * t), 1.0);
  return out;
}

}  // namespace

glm::dmat4 rotation_x(double a) {
  glm::dmat4 m(1.0);
  double c = std::cos(a), s = std::sin(a);
  m[1][1] = c;   // column 1, row 1
  m[1][2] = s;   // row 2
  m[2][1] = -s;  // column 2, row 1
  m[2][2] = c;
  return m;
}

glm::dmat4 rotation_y(double a) {
  glm::dmat4 m(1.0);
  double c = std::cos(a), s = std::sin(a);
  m[0][0] = c;
  m[0][2] = -s;  // column 0, row 2
  m[2][0] = s;   // column 2, row 0
  m[2][2] = c;
  return m;
}

glm::dmat4 translation(const glm::dvec3& t) {
  glm::dmat4 m(1.0);
  m[3] = glm::dvec4(t, 1.0);
  return m;
}

// ---- (a) official ----------------------------------------------------------------------------------------

OrbitAngles parse_official_trajectory(const std::string& text, const std::string& name) {
  std::vector<std::vector<double>> lists;
  std::vector<int> line_of;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line_no == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // a UTF-8 byte-order mark
    std::istringstream words(line);
    std::string w;
    std::vector<double> values;
    while (words >> w) {
      errno = 0;
      char* end = nullptr;
      double v = std::strtod(w.c_str(), &end);
      if (end == w.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v))
        throw Error(name + ":" + std::to_string(line_no) + ": '" + printable_excerpt(w) + "' is not a finite number");
      values.push_back(v);
    }
    if (values.empty()) continue;  // blank lines are ignored
    if (lists.size() == 3)
      throw Error(name + ":" + std::to_string(line_no) +
                  ": a trajectory file has exactly three lines (theta degrees, phi degrees, r); found more");
    lists.push_back(std::move(values));
    line_of.push_back(line_no);
  }
  if (lists.size() != 3)
    throw Error(name + ": a trajectory file has three lines (theta degrees about x, phi degrees about y, r as a "
                "multiple of the radius); found " + std::to_string(lists.size()) + " non-empty line(s)");
  return {lists[0], lists[1], lists[2], {line_of[0], line_of[1], line_of[2]}};
}

OrbitAngles read_official_trajectory(const std::filesystem::path& path) {
  return parse_official_trajectory(read_trajectory_text(path), path.string());
}

std::string knot_counts(const OrbitAngles& knots) {
  const size_t t = knots.theta_deg.size(), p = knots.phi_deg.size(), r = knots.r.size();
  if (t == p && p == r) return std::to_string(t) + " knots per line";
  return "knots: theta " + std::to_string(t) + ", phi " + std::to_string(p) + ", r " + std::to_string(r) +
         "; lines of different lengths are each spread over the whole clip on their own, as the authors' loader "
         "does (their loop1.txt has 13, 9 and 8)";
}

std::string unequal_lines_warning(const OrbitAngles& k, const std::string& name) {
  const size_t t = k.theta_deg.size(), p = k.phi_deg.size(), r = k.r.size();
  if (t == p && p == r) return "";
  auto line = [&](int i, const char* what, size_t n) {
    return "line " + std::to_string(k.lines[i]) + " (" + what + ") " + std::to_string(n) + (n == 1 ? " value" : " values");
  };
  return name + ": its lines hold different numbers of values: " + line(0, "theta", t) + ", " + line(1, "phi", p) +
         ", " + line(2, "r", r) + ". dvs spreads each line over the whole clip on its own (its first value at the "
         "first frame, its last at the last frame), as the authors' loader does, so the i-th values of different "
         "lines do not fall on the same frame; give every line the same number of values to keep them together";
}

OrbitAngles interpolate_official(const OrbitAngles& knots, int frames) {
  if (frames < 1) throw Error("trajectory: the frame count must be at least 1");
  if (knots.theta_deg.empty() || knots.phi_deg.empty() || knots.r.empty())
    throw Error("trajectory: every list (theta, phi, r) needs at least one value");
  return {interpolate_list(knots.theta_deg, frames), interpolate_list(knots.phi_deg, frames),
          interpolate_list(knots.r, frames)};
}

const std::vector<std::string>& official_preset_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& t : official_tables()) n.push_back(t.name);
    return n;
  }();
  return names;
}

bool is_official_preset(const std::string& name) {
  const auto& n = official_preset_names();
  return std::find(n.begin(), n.end(), name) != n.end();
}

OrbitAngles official_preset_angles(const std::string& name, int frames) {
  if (frames < 1) throw Error("trajectory: the frame count must be at least 1");
  for (const auto& t : official_tables()) {
    if (t.name != name) continue;
    OrbitAngles table;
    for (const auto& f : t.frames) {
      table.theta_deg.push_back(f.theta_deg);
      table.phi_deg.push_back(f.phi_deg);
      table.r.push_back(f.r);
    }
    if (frames == int(t.frames.size())) return table;
    return {resample_linear(table.theta_deg, frames), resample_linear(table.phi_deg, frames),
            resample_linear(table.r, frames)};
  }
  std::string list;
  for (const auto& n : official_preset_names()) list += " " + n;
  throw Error("trajectory: no official preset named '" + name + "' (known:" + list + ")");
}

double official_radius(double centre_depth, double radius_scale) {
  if (!std::isfinite(centre_depth) || centre_depth <= 0)
    throw Error("trajectory: the centre depth of frame 0 must be finite and > 0 to place the orbit pivot (got " +
                std::to_string(centre_depth) + ")");
  return std::min(centre_depth * radius_scale, 5.0);
}

glm::dmat4 official_transform(double theta_deg, double phi_deg, double r, double radius) {
  // The code works in float32: θ, φ are np.float32 degrees. Round them the same way.
  double th = deg2rad(double(float(theta_deg))), ph = deg2rad(double(float(phi_deg)));
  glm::dmat4 M = rotation_y(ph) * rotation_x(th);
  glm::dvec3 pivot(0, 0, radius);
  glm::dvec3 back(0, 0, radius * (1.0 + double(float(r))));
  glm::dmat4 T = M;
  T[3] = glm::dvec4(pivot - glm::dmat3(M) * back, 1.0);
  return T;
}

Trajectory official_trajectory(const OrbitAngles& a, double radius, const std::string& description) {
  if (a.theta_deg.size() != a.phi_deg.size() || a.theta_deg.size() != a.r.size())
    throw Error("trajectory: theta, phi and r must have one value per frame (interpolate first)");
  Trajectory t;
  t.description = description.empty() ? "official orbit" : description;
  for (size_t i = 0; i < a.theta_deg.size(); ++i)
    t.transforms.push_back(official_transform(a.theta_deg[i], a.phi_deg[i], a.r[i], radius));
  return t;
}

// ---- (b) canonical ---------------------------------------------------------------------------------------

const std::vector<std::string>& canonical_preset_names() {
  static const std::vector<std::string> names = {"pan_left",   "pan_right",  "tilt_up",    "tilt_down",
                                                 "dolly_in",   "dolly_out",  "truck_left", "truck_right",
                                                 "arc_left",   "arc_right"};
  return names;
}

bool is_canonical_preset(const std::string& name) {
  const auto& n = canonical_preset_names();
  return std::find(n.begin(), n.end(), name) != n.end();
}

double canonical_default_magnitude(const std::string& name) {
  if (name.rfind("pan", 0) == 0 || name.rfind("tilt", 0) == 0) return 15.0;
  if (name.rfind("arc", 0) == 0) return 20.0;
  return 0.25;
}

Trajectory canonical_preset(const std::string& name, int frames, double magnitude, double radius) {
  if (!is_canonical_preset(name)) {
    std::string list;
    for (const auto& n : canonical_preset_names()) list += " " + n;
    throw Error("trajectory: no preset named '" + name + "' (canonical:" + list + ")");
  }
  if (frames < 1) throw Error("trajectory: the frame count must be at least 1");
  if (!std::isfinite(magnitude)) throw Error("trajectory: the magnitude of '" + name + "' must be finite");
  if (!std::isfinite(radius) || radius <= 0) throw Error("trajectory: the radius must be finite and > 0");
  Trajectory t;
  t.description = name + ":" + std::to_string(magnitude);
  for (int i = 0; i < frames; ++i) {
    double a = frames == 1 ? 0.0 : magnitude * double(i) / double(frames - 1);
    double rad = deg2rad(a);
    glm::dmat4 C(1.0);  // target camera pose in source-camera coordinates
    if (name == "pan_left") C = rotation_y(-rad);
    else if (name == "pan_right") C = rotation_y(rad);
    else if (name == "tilt_up") C = rotation_x(rad);
    else if (name == "tilt_down") C = rotation_x(-rad);
    else if (name == "dolly_in") C = translation({0, 0, a * radius});
    else if (name == "dolly_out") C = translation({0, 0, -a * radius});
    else if (name == "truck_left") C = translation({-a * radius, 0, 0});
    else if (name == "truck_right") C = translation({a * radius, 0, 0});
    else {
      double b = name == "arc_left" ? rad : -rad;
      glm::dmat4 R = rotation_y(b);
      glm::dvec3 pivot(0, 0, radius);
      C = R;
      C[3] = glm::dvec4(pivot + glm::dmat3(R) * glm::dvec3(0, 0, -radius), 1.0);
    }
    t.transforms.push_back(rigid_inverse(C));
  }
  return t;
}

// ---- resolving a spec ---------------------------------------------------------------------------------

Trajectory load_trajectory(const std::string& spec, int frames, double radius) {
  if (frames < 1) throw Error("trajectory: the frame count must be at least 1");
  if (is_official_preset(spec))
    return official_trajectory(official_preset_angles(spec, frames), radius, "official preset " + spec);
  std::string base = spec, mag;
  if (auto colon = spec.find(':'); colon != std::string::npos) {
    base = spec.substr(0, colon);
    mag = spec.substr(colon + 1);
  }
  if (is_canonical_preset(base)) {
    double m = canonical_default_magnitude(base);
    if (!mag.empty()) {
      char* end = nullptr;
      m = std::strtod(mag.c_str(), &end);
      if (end == mag.c_str() || *end != '\0' || !std::isfinite(m))
        throw Error("trajectory '" + spec + "': the magnitude after ':' must be a number");
    }
    return canonical_preset(base, frames, m, radius);
  }
  std::filesystem::path p(spec);
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (!std::filesystem::exists(p)) {
    std::string list;
    for (const auto& n : official_preset_names()) list += " " + n;
    for (const auto& n : canonical_preset_names()) list += " " + n;
    throw Error("trajectory '" + spec + "': neither a preset nor an existing file (presets:" + list + ")");
  }
  Trajectory t;
  if (ext == ".json") {
    t = read_trajectory_json(p);
  } else if (ext == ".gltf" || ext == ".glb") {
    GltfCameraOptions o;
    o.frames = frames;
    t = read_gltf_trajectory(p, o);
  } else {
    const OrbitAngles knots = read_official_trajectory(p);
    Trajectory official = official_trajectory(interpolate_official(knots, frames), radius,
                                              "official-format file " + p.string() + " (" + knot_counts(knots) + ")");
    if (std::string w = unequal_lines_warning(knots, p.string()); !w.empty()) official.warnings.push_back(std::move(w));
    return official;
  }
  if (t.frames() != frames)
    throw Error(p.string() + ": has " + std::to_string(t.frames()) + " poses but the clip has " +
                std::to_string(frames) + " frames");
  return t;
}

}  // namespace dvs::geometry
