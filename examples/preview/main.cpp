// dvs-preview: an interactive camera-path preview embedding dvs in the application's own Vulkan device.
#include <exception>
#include <iostream>

#include "preview_app.hpp"
#include "preview_options.hpp"

int main(int argc, char** argv) {
  try {
    const preview::PreviewOptions options = preview::parse_options(argc, argv);
    if (options.help) {
      std::cout << preview::kPreviewUsage;
      return 0;
    }
    preview::run_preview(options);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "dvs-preview: error: " << e.what() << "\n";
    return 1;
  }
}
