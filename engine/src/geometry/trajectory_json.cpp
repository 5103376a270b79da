#include "geometry/trajectory_json.hpp"

#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "dvs/error.hpp"
#include "geometry/trajectory_text.hpp"
#include "io/disk_space.hpp"
#include "io/injected_faults.hpp"

namespace dvs::geometry {

namespace {

using nlohmann::json;

double number(const json& v, const std::string& where) {
  if (!v.is_number()) throw Error(where + ": expected a number, got " + std::string(v.type_name()));
  double d = v.get<double>();
  if (!std::isfinite(d)) throw Error(where + ": value is not finite");
  return d;
}

// GLM is column-major: m[col][row].
glm::dmat4 parse_pose(const json& p, const std::string& where) {
  glm::dmat4 m(1.0);
  if (p.is_object()) {
    if (!p.contains("R") || !p.contains("t")) throw Error(where + ": a pose object needs \"R\" (3x3) and \"t\" (3)");
    const json& R = p["R"];
    const json& t = p["t"];
    if (!R.is_array() || R.size() != 3) throw Error(where + ".R: expected 3 rows");
    for (int r = 0; r < 3; ++r) {
      const json& row = R[size_t(r)];
      if (!row.is_array() || row.size() != 3) throw Error(where + ".R[" + std::to_string(r) + "]: expected 3 numbers");
      for (int c = 0; c < 3; ++c) m[c][r] = number(row[size_t(c)], where + ".R[" + std::to_string(r) + "][" + std::to_string(c) + "]");
    }
    if (!t.is_array() || t.size() != 3) throw Error(where + ".t: expected 3 numbers");
    for (int r = 0; r < 3; ++r) m[3][r] = number(t[size_t(r)], where + ".t[" + std::to_string(r) + "]");
    return m;
  }
  if (!p.is_array()) throw Error(where + ": expected a 4x4 matrix, 16 numbers or {\"R\", \"t\"}");
  if (p.size() == 16) {
    for (int i = 0; i < 16; ++i) m[i % 4][i / 4] = number(p[size_t(i)], where + "[" + std::to_string(i) + "]");
  } else if (p.size() == 4) {
    for (int r = 0; r < 4; ++r) {
      const json& row = p[size_t(r)];
      if (!row.is_array() || row.size() != 4) throw Error(where + "[" + std::to_string(r) + "]: expected 4 numbers");
      for (int c = 0; c < 4; ++c) m[c][r] = number(row[size_t(c)], where + "[" + std::to_string(r) + "][" + std::to_string(c) + "]");
    }
  } else {
    throw Error(where + ": expected a 4x4 matrix (4 rows or 16 numbers), got an array of " + std::to_string(p.size()));
  }
  if (std::abs(m[0][3]) > 1e-6 || std::abs(m[1][3]) > 1e-6 || std::abs(m[2][3]) > 1e-6 || std::abs(m[3][3] - 1) > 1e-6)
    throw Error(where + ": the last row must be 0 0 0 1");
  glm::dmat3 R(m);
  glm::dmat3 E = glm::transpose(R) * R;
  double err = 0;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) err = std::max(err, std::abs(E[c][r] - (c == r ? 1.0 : 0.0)));
  if (err > 1e-3 || glm::determinant(R) < 0)
    throw Error(where + ": not a rigid transform (the 3x3 part must be a rotation; max |RᵀR − I| = " +
                std::to_string(err) + ")");
  return m;
}

glm::dmat4 rigid_inverse(const glm::dmat4& m) {
  glm::dmat3 rt = glm::transpose(glm::dmat3(m));
  glm::dmat4 out(rt);
  out[3] = glm::dvec4(-(rt * glm::dvec3(m[3])), 1.0);
  return out;
}

}  // namespace

Trajectory parse_trajectory_json(const std::string& text, const std::string& name) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number past double's range (1e999)
    throw Error(name + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  if (!j.is_object()) throw Error(name + ": expected a JSON object with \"convention\" and \"poses\"");
  if (!j.contains("convention") || !j["convention"].is_string())
    throw Error(name + ": field \"convention\" is required: \"world_to_camera\" or \"camera_to_world\"");
  std::string conv = j["convention"].get<std::string>();
  if (conv != "world_to_camera" && conv != "camera_to_world")
    throw Error(name + ": field \"convention\" must be \"world_to_camera\" or \"camera_to_world\", got \"" + conv + "\"");
  std::string axes = "opencv";
  if (j.contains("axes")) {
    if (!j["axes"].is_string()) throw Error(name + ": field \"axes\" must be \"opencv\" or \"opengl\"");
    axes = j["axes"].get<std::string>();
    if (axes != "opencv" && axes != "opengl")
      throw Error(name + ": field \"axes\" must be \"opencv\" or \"opengl\", got \"" + axes + "\"");
  }
  bool relative = false;
  if (j.contains("relative_to_first")) {
    if (!j["relative_to_first"].is_boolean()) throw Error(name + ": field \"relative_to_first\" must be true or false");
    relative = j["relative_to_first"].get<bool>();
  }
  if (!j.contains("poses") || !j["poses"].is_array())
    throw Error(name + ": field \"poses\" is required: an array with one 4x4 matrix per frame");
  const json& poses = j["poses"];
  if (poses.empty()) throw Error(name + ": field \"poses\" is empty (zero frames)");

  const glm::dmat4 D(glm::dvec4(1, 0, 0, 0), glm::dvec4(0, -1, 0, 0), glm::dvec4(0, 0, -1, 0), glm::dvec4(0, 0, 0, 1));
  Trajectory t;
  t.description = "JSON file " + name;
  std::vector<glm::dmat4> w2c;
  for (size_t i = 0; i < poses.size(); ++i) {
    glm::dmat4 m = parse_pose(poses[i], name + ": poses[" + std::to_string(i) + "]");
    glm::dmat4 w = conv == "world_to_camera" ? m : rigid_inverse(m);
    if (axes == "opengl") w = D * w * D;  // both the camera and the (source-camera) world flip y and z
    w2c.push_back(w);
  }
  glm::dmat4 first_inv = rigid_inverse(w2c[0]);
  for (auto& w : w2c) t.transforms.push_back(relative ? w * first_inv : w);
  return t;
}

Trajectory read_trajectory_json(const std::filesystem::path& path) {
  return parse_trajectory_json(read_trajectory_text(path), path.string());
}

std::string trajectory_to_json(const Trajectory& t) {
  json poses = json::array();
  for (const auto& m : t.transforms) {
    json rows = json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({m[0][r], m[1][r], m[2][r], m[3][r]});
    poses.push_back(rows);
  }
  json j = {{"convention", "world_to_camera"},
            {"axes", "opencv"},
            {"description", t.description},
            {"note", "T_i maps points in the source camera's coordinates to the target camera of frame i"},
            {"poses", poses}};
  return j.dump(1);
}

namespace {

// ": no space left on device (…)" when that is why a write into path's folder failed, else "".
std::string with_space_note(const std::filesystem::path& path) {
  const std::string note = no_space_note(path.parent_path());
  return note.empty() ? note : ": " + note;
}

}  // namespace

void write_trajectory_json(const std::filesystem::path& path, const Trajectory& t) {
  std::string text = trajectory_to_json(t);
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw Error(path.string() + ": cannot write the trajectory file" + with_space_note(path));
    f << text;
    f.close();  // the buffered bytes reach the disk here: check after it
    if (const int injected = faults::write_error(path); injected && f) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw Error(path.string() + ": write failed: " + write_error_note(injected, path.parent_path()));
    }
    if (!f) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw Error(path.string() + ": write failed" + with_space_note(path));
    }
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace dvs::geometry
