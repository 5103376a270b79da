// Must NOT compile (tests/public_api/check_views_constness.cmake): outputs stay writable memory, so const memory given
// as a render's output is refused by the compiler (issue 34 §2.11).
#include <dvs/scene.hpp>

#include <vector>

void output(dvs::PointCloudScene& scene, const std::vector<uint8_t>& rgba) {
  scene.render(dvs::Pose{}, dvs::HostView{rgba.data(), dvs::ElementType::u8, {4, 4, 4}});
}
