#include "convert_pth.hpp"

#include <algorithm>
#include <iostream>
#include <map>

#include "dvs/error.hpp"
#include "io/pth_file.hpp"
#include "io/safetensors_writer.hpp"
#include "spec/vda_config.hpp"

namespace fs = std::filesystem;

namespace dvs::weights_tools {

namespace {

constexpr const char* kConvertUsage = R"(usage: dvs-weights convert IN.pth OUT.safetensors

Reads a PyTorch checkpoint (torch.save zip archive of a state_dict; the pickle is read by a restricted
reader that never imports or executes anything) and writes its tensors as safetensors: same names, dtypes,
shapes and bytes. OUT must not exist.
)";

}  // namespace

int inspect_pth(const fs::path& file, bool summary) {
  const PthFile f = PthFile::open(file);
  std::cout << "file " << file.string() << ": PyTorch checkpoint (record prefix '" << f.record_prefix() << "')\n";
  if (!f.unwrapped().empty()) std::cout << "  state_dict taken from the '" << f.unwrapped() << "' entry\n";
  if (f.stripped_module_prefix()) std::cout << "  'module.' prefix removed from every key\n";
  size_t width = 0, shape_width = 0;
  for (const auto& t : f.tensors()) {
    width = std::max(width, t.name.size());
    shape_width = std::max(shape_width, shape_list(t.shape).size());
  }
  width = std::min<size_t>(width, 72);
  std::map<std::string, uint64_t> per_dtype;
  std::map<std::string, Shape> shapes;
  size_t strided = 0;
  for (const auto& t : f.tensors()) {
    per_dtype[t.dtype_name]++;
    shapes[t.name] = t.shape;
    if (!t.contiguous) ++strided;
    if (summary) continue;
    std::cout << "    " << t.name << std::string(t.name.size() < width ? width - t.name.size() : 0, ' ') << "  "
              << t.dtype_name << std::string(t.dtype_name.size() < 8 ? 8 - t.dtype_name.size() : 1, ' ')
              << shape_list(t.shape) << std::string(shape_width + 2 - shape_list(t.shape).size(), ' ') << t.nbytes()
              << (t.contiguous ? "" : "  (strided)") << "\n";
  }
  std::cout << "  total: " << f.tensors().size() << " tensors, " << f.total_bytes() << " bytes;";
  for (const auto& [dt, n] : per_dtype) std::cout << " " << dt << " " << n;
  std::cout << "\n";
  if (strided) std::cout << "  " << strided << " strided tensor(s), made contiguous when read\n";
  if (shapes.count("pretrained.cls_token") || shapes.count("pretrained.patch_embed.proj.weight")) {
    try {
      const VdaConfig c = resolve_vda_config(file, shapes);
      std::cout << "  Video-Depth-Anything " << c.name << (c.metric ? " (metric)" : "") << ": embed dim " << c.embed_dim
                << ", " << c.depth << " blocks, " << c.num_heads << " heads, taps " << c.taps[0] << "," << c.taps[1]
                << "," << c.taps[2] << "," << c.taps[3] << ", DPT features " << c.features << "; " << c.origin << "\n";
    } catch (const Error& e) {
      std::cout.flush();
      std::cerr << "dvs-weights: error: " << e.what() << "\n";
      return 1;
    }
  }
  return 0;
}

void convert_pth_to_safetensors(const fs::path& in, const fs::path& out) {
  std::error_code ec;
  if (fs::exists(out, ec)) throw Error(out.string() + ": already exists; dvs-weights convert does not overwrite");
  const PthFile f = PthFile::open(in);
  std::vector<std::pair<std::string, HostTensor>> tensors;
  tensors.reserve(f.tensors().size());
  for (const auto& t : f.tensors()) {
    if (!t.dtype)
      throw Error(in.string() + ": tensor '" + t.name + "' is " + t.dtype_name +
                  "; convert writes F32, F16, BF16, I32 and U8 tensors only");
    tensors.emplace_back(t.name, f.load(t));
  }
  write_safetensors(out, tensors, {{"format", "pt"}, {"converted_from", in.filename().string()}});
}

int convert_command(const std::vector<std::string>& args) {
  std::vector<std::string> paths;
  for (const auto& a : args) {
    if (a == "-h" || a == "--help") {
      std::cout << kConvertUsage;
      return 0;
    }
    if (!a.empty() && a[0] == '-') {
      std::cerr << "dvs-weights: convert: unknown option " << a << "\n" << kConvertUsage;
      return 2;
    }
    paths.push_back(a);
  }
  if (paths.size() != 2) {
    std::cerr << "dvs-weights: convert takes IN.pth and OUT.safetensors\n" << kConvertUsage;
    return 2;
  }
  try {
    convert_pth_to_safetensors(paths[0], paths[1]);
    std::cout << "wrote " << paths[1] << "\n";
    return 0;
  } catch (const Error& e) {
    std::cerr << "dvs-weights: error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace dvs::weights_tools
