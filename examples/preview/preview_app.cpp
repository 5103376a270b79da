#include "preview_app.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <numeric>
#include <stdexcept>

#include "digit_font.hpp"
#include "dvs/context.hpp"
#include "dvs/scene.hpp"
#include "dvs/trajectory.hpp"
#include "fly_camera.hpp"
#include "frame_pacing.hpp"
#include "input_script.hpp"
#include "model_depth.hpp"
#include "npy_arrays.hpp"
#include "preview_inputs.hpp"
#include "png_file.hpp"
#include "present_window.hpp"

namespace preview {

namespace {

constexpr double kLookRadiansPerPixel = 0.003;
// Per second of wall time (frame_pacing.hpp), whatever the frame rate: W held for a second moves 0.6 orbit radii
// (× the scroll speed); P plays the path at CogVideoX's 8 frames a second.
constexpr double kRadiiPerSecond = 0.6;
constexpr double kPlayFramesPerSecond = 8;

std::string pose_text(const dvs::Pose& p) {
  std::string out;
  char buf[32];
  for (double v : p.m) {
    std::snprintf(buf, sizeof buf, "%s%.17g", out.empty() ? "" : " ", v);
    out += buf;
  }
  return out;
}

std::string with_extension(const std::string& path, const std::string& ext) {
  const size_t dot = path.find_last_of('.'), slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return path + ext;
  return path.substr(0, dot) + ext;
}

// Scroll steps from GLFW's callback, read once a frame.
double g_scroll = 0;
// Keys pressed (not held) since the last frame.
std::vector<int> g_pressed;

void on_scroll(GLFWwindow*, double, double dy) { g_scroll += dy; }
void on_key(GLFWwindow*, int key, int, int action, int) {
  if (action == GLFW_PRESS) g_pressed.push_back(key);
}

struct FrameTimes {
  std::vector<double> ms;
  double mean() const { return ms.empty() ? 0 : std::accumulate(ms.begin(), ms.end(), 0.0) / double(ms.size()); }
  double median() const {
    if (ms.empty()) return 0;
    std::vector<double> s = ms;
    std::sort(s.begin(), s.end());
    return s.size() % 2 ? s[s.size() / 2] : 0.5 * (s[s.size() / 2 - 1] + s[s.size() / 2]);
  }
};

}  // namespace

void run_preview(const PreviewOptions& o) {
  Inputs in = read_inputs(o);
  const std::vector<ScriptEvent> script = o.script.empty() ? std::vector<ScriptEvent>{} : read_script(o.script);
  const int H = o.height, W = o.width;

  WindowOptions wo;
  wo.panel_width = W;
  wo.panel_height = H;
  wo.device = o.gpu;
  wo.validation = o.validation;
  wo.vsync = o.vsync;  // FIFO unless --no-vsync
  PresentWindow window(wo);
  glfwSetScrollCallback(window.window(), on_scroll);
  glfwSetKeyCallback(window.window(), on_key);

  // dvs on the window's device (the embedding), or on a device of its own for comparison.
  std::unique_ptr<dvs::Context> ctx =
      o.own_device ? std::make_unique<dvs::Context>() : std::make_unique<dvs::Context>(window.host_device());
  std::cout << "dvs-preview: window on " << window.device_name() << "; dvs on " << ctx->device_name()
            << (ctx->owns_device() ? " (its own device)" : " (the window's device)") << std::endl;
  if (!o.depth_model.empty()) estimate_model_depth(o, *ctx, in);

  dvs::CameraIntrinsics K = dvs::CameraIntrinsics::dvs_default(W, H, o.squash);
  if (o.intrinsics) K = {(*o.intrinsics)[0], (*o.intrinsics)[1], (*o.intrinsics)[2], (*o.intrinsics)[3], W, H};
  dvs::SceneOptions so;
  so.depth_is_disparity = in.depth_is_disparity;
  so.hard_points = o.hard_points;
  dvs::PointCloudScene scene(*ctx, in.frame_view, in.depth_view, K, so);
  const double radius = scene.orbit_radius();
  std::cout << "dvs-preview: scene " << H << "x" << W << ", centre depth " << scene.centre_depth() << ", orbit radius "
            << radius << std::endl;

  FlyCamera camera;
  double speed = 1;
  std::vector<dvs::Pose> keys{dvs::Pose{}};  // the path starts at the input view (frame 0 of every dvs path)
  std::vector<dvs::Pose> path = dvs::interpolate_path({{0, keys[0]}}, o.frames);
  int path_frame = -1;  // the path frame shown while scrubbing or playing; −1 = flying freely
  bool playing = false;
  double played_s = 0;  // seconds since P
  std::vector<float> mask(size_t(H) * size_t(W));
  // The render and mask panels as device images dvs renders into (not with --host-round-trip or a device of dvs's
  // own, whose images the window could not draw); the mask as dvs's RGBA8 display form (white where visible).
  const bool on_device = !o.host_round_trip && !o.own_device;
  VkImage render_panel = on_device ? window.device_panel(1, VK_FORMAT_R8G8B8A8_UNORM) : VK_NULL_HANDLE;
  VkImage mask_panel_image = on_device ? window.device_panel(2, VK_FORMAT_R8G8B8A8_UNORM) : VK_NULL_HANDLE;
  auto panel_image = [&](VkImage image, VkFormat format) {
    return dvs::DeviceImageView{image, format, uint32_t(W), uint32_t(H), VK_IMAGE_LAYOUT_UNDEFINED,
                                VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL};
  };
  FrameTimes times, recent, render_times;
  auto last_report = std::chrono::steady_clock::now();
  FramePacer pacer(o.max_fps);

  auto rebuild_path = [&] {
    const std::vector<int> at = dvs::evenly_spaced_key_frames(int(keys.size()), o.frames);
    std::vector<dvs::KeyPose> kp;
    for (size_t k = 0; k < keys.size(); ++k) kp.push_back({at[k], keys[k]});
    path = dvs::interpolate_path(kp, o.frames);
  };
  auto add_key = [&] {
    if (int(keys.size()) >= o.frames) throw std::runtime_error("more key poses than --frames " + std::to_string(o.frames));
    keys.push_back(camera.pose());
    rebuild_path();
    std::cout << "dvs-preview: key pose " << keys.size() - 1 << ": " << pose_text(keys.back()) << std::endl;
  };
  auto export_path = [&](const std::string& json) {
    const std::string glb = with_extension(json, ".glb");
    dvs::write_trajectory_json(json, path, "dvs-preview: " + std::to_string(keys.size()) + " key poses");
    dvs::write_trajectory_glb(glb, path);
    std::cout << "dvs-preview: exported " << path.size() << " poses to " << json << " and " << glb << std::endl;
    const std::vector<int> at = dvs::evenly_spaced_key_frames(int(keys.size()), o.frames);
    for (size_t k = 0; k < keys.size(); ++k)
      std::cout << "dvs-preview: path frame " << at[k] << " = key pose " << k << ": " << pose_text(path[size_t(at[k])])
                << std::endl;
  };
  auto scrub_to = [&](int f) {
    path_frame = std::clamp(f, 0, o.frames - 1);
    camera.set_pose(path[size_t(path_frame)]);
  };
  std::string pending_screenshot;
  auto screenshot = [&](const std::string& file, const dvs::Pose& pose) {
    const uint8_t* render = window.panel(1);
    if (file.size() > 4 && file.substr(file.size() - 4) == ".npy") {
      write_npy(file, "u1", {H, W, 4}, render, size_t(H) * size_t(W) * 4);
    } else if (o.screenshot_panel) {
      write_png(file, render, W, H);
    } else {
      const std::vector<uint8_t> all = window.window_pixels();
      write_png(file, all.data(), 3 * W, H);
    }
    std::cout << "dvs-preview: screenshot " << file << " at pose: " << pose_text(pose) << std::endl;
  };

  size_t next_event = 0;
  int event_frames_left = 0;
  const ScriptEvent* holding = nullptr;
  bool quit = false;
  int frame = 0;
  double last_x = 0, last_y = 0;
  glfwGetCursorPos(window.window(), &last_x, &last_y);
  const auto first_frame = std::chrono::steady_clock::now();
  while (!quit && !glfwWindowShouldClose(window.window())) {
    const double dt = pacer.begin_frame();  // waits for --max-fps; the seconds this frame's motion covers
    const auto t0 = std::chrono::steady_clock::now();
    glfwPollEvents();
    double forward = 0, right = 0, down = 0, look_x = 0, look_y = 0;
    std::vector<int> pressed;
    pressed.swap(g_pressed);
    if (!script.empty()) {  // scripted: keyboard and mouse are ignored, one event (or one held frame) a frame
      pressed.clear();
      if (event_frames_left == 0) {
        holding = nullptr;
        if (next_event >= script.size()) {
          quit = true;
        } else {
          const ScriptEvent& e = script[next_event++];
          event_frames_left = e.frames;
          if (e.verb == "key") holding = &e;
          else if (e.verb == "mouse") look_x = e.a, look_y = e.b;
          else if (e.verb == "scroll") g_scroll += e.a;
          else if (e.verb == "keypose") pressed.push_back(GLFW_KEY_K);
          else if (e.verb == "scrub") scrub_to(int(e.a));
          else if (e.verb == "play") pressed.push_back(GLFW_KEY_P);
          else if (e.verb == "screenshot") pending_screenshot = e.text;
          else if (e.verb == "export") export_path(e.text);
          else if (e.verb == "quit") quit = true;
        }
      }
      if (holding) {
        const char k = holding->text[0];
        forward = k == 'W' ? 1 : k == 'S' ? -1 : 0;
        right = k == 'D' ? 1 : k == 'A' ? -1 : 0;
        down = k == 'E' ? 1 : k == 'Q' ? -1 : 0;
      }
      if (event_frames_left > 0) --event_frames_left;
    } else {
      GLFWwindow* w = window.window();
      auto held = [&](int key) { return glfwGetKey(w, key) == GLFW_PRESS ? 1.0 : 0.0; };
      forward = held(GLFW_KEY_W) - held(GLFW_KEY_S);
      right = held(GLFW_KEY_D) - held(GLFW_KEY_A);
      down = held(GLFW_KEY_E) - held(GLFW_KEY_Q);
      double x = 0, y = 0;
      glfwGetCursorPos(w, &x, &y);
      if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) look_x = x - last_x, look_y = y - last_y;
      last_x = x, last_y = y;
    }
    speed *= std::pow(1.25, g_scroll);
    g_scroll = 0;
    for (int key : pressed) {
      if (key == GLFW_KEY_K) add_key();
      else if (key == GLFW_KEY_LEFT_BRACKET) scrub_to(path_frame < 0 ? 0 : path_frame - 1);
      else if (key == GLFW_KEY_RIGHT_BRACKET) scrub_to(path_frame + 1);
      else if (key == GLFW_KEY_P) playing = true, played_s = 0, scrub_to(0);
      else if (key == GLFW_KEY_X) export_path(o.export_name);
      else if (key == GLFW_KEY_R) camera.reset(), path_frame = -1;
      else if (key == GLFW_KEY_F12) pending_screenshot = "preview_" + std::to_string(frame) + ".png";
      else if (key == GLFW_KEY_ESCAPE) quit = true;
    }
    if (forward || right || down || look_x || look_y) {  // flying leaves the path
      playing = false;
      path_frame = -1;
      camera.move(forward, right, down, kRadiiPerSecond * radius * speed * dt);
      camera.look(look_x, look_y, kLookRadiansPerPixel);
    } else if (playing) {
      played_s += dt;
      const int due = int(played_s * kPlayFramesPerSecond);
      if (due >= o.frames) playing = false;
      else if (due != path_frame) scrub_to(due);
    }

    const dvs::Pose pose = camera.pose();
    const auto render_start = std::chrono::steady_clock::now();
    if (on_device) {
      // Into the window's images, drawn by present() once dvs's ticket is reached: nothing waits on the host.
      const uint64_t ticket = scene.render(pose, panel_image(render_panel, VK_FORMAT_R8G8B8A8_UNORM),
                                           panel_image(mask_panel_image, VK_FORMAT_R8G8B8A8_UNORM));
      window.wait_before_present(ctx->timeline(), ticket);
    } else {
      scene.render(pose, {window.panel(1), dvs::ElementType::u8, {H, W, 4}}, {mask.data(), dvs::ElementType::f32, {H, W}});
    }
    render_times.ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - render_start).count());
    auto fill_mask_panel = [&] {
      uint8_t* mask_panel = window.panel(2);
      for (size_t i = 0; i < mask.size(); ++i) {
        const uint8_t v = mask[i] > 0.5f ? 255 : 0;
        mask_panel[i * 4] = mask_panel[i * 4 + 1] = mask_panel[i * 4 + 2] = v;
        mask_panel[i * 4 + 3] = 255;
      }
    };
    if (!on_device) fill_mask_panel();
    if (!pending_screenshot.empty()) {  // the render panel exactly as rendered (before any overlay)
      // On the device path the same pose again into host memory for the file (the splat is not redone: the scene
      // keeps it); it equals the device image byte for byte (tests/test_scene_device_memory.cpp).
      if (on_device) {
        scene.render(pose, {window.panel(1), dvs::ElementType::u8, {H, W, 4}}, {mask.data(), dvs::ElementType::f32, {H, W}});
        fill_mask_panel();
      }
      screenshot(pending_screenshot, pose);
      pending_screenshot.clear();
    }
    std::memcpy(window.panel(0), in.frame_rgba.data(), in.frame_rgba.size());
    char status[96];
    std::snprintf(status, sizeof status, "%.1f ms  key %zu  f %s/%d", recent.mean(), keys.size() - 1,
                  path_frame < 0 ? "-" : std::to_string(path_frame).c_str(), o.frames);
    draw_text(window.panel(0), W, H, 6, 6, status, std::max(2, H / 160));
    window.present();

    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    times.ms.push_back(ms);
    recent.ms.push_back(ms);
    if (recent.ms.size() > 30) recent.ms.erase(recent.ms.begin());
    if (std::chrono::steady_clock::now() - last_report > std::chrono::seconds(1)) {
      last_report = std::chrono::steady_clock::now();
      char title[128];
      std::snprintf(title, sizeof title, "dvs preview  %.1f ms/frame", recent.mean());
      glfwSetWindowTitle(window.window(), title);
      std::cout << "dvs-preview: frame " << frame << ": " << title + 13 << std::endl;
    }
    ++frame;
    if (o.frames_to_run && frame >= o.frames_to_run) quit = true;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - first_frame).count();
  char summary[320];
  std::snprintf(summary, sizeof summary,
                "dvs-preview: frame times over %zu frames at %dx%d: mean %.2f ms, median %.2f ms (of which "
                "PointCloudScene::render: mean %.2f ms, median %.2f ms); %.1f frames/s shown (--max-fps %d)",
                times.ms.size(), H, W, times.mean(), times.median(), render_times.mean(), render_times.median(),
                double(times.ms.size()) / std::max(seconds, 1e-9), o.max_fps);
  std::cout << summary << std::endl;
}

}  // namespace preview
