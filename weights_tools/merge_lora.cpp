#include "merge_lora.hpp"

#include <unistd.h>

#include <algorithm>
#include <iostream>
#include <map>

#include "dvs/error.hpp"
#include "io/lora_file.hpp"
#include "spec/model_folder.hpp"
#include "io/safetensors_writer.hpp"

namespace fs = std::filesystem;

namespace dvs::weights_tools {
namespace {

constexpr const char* kHelp = R"(usage: dvs-weights merge-lora --model DIR --lora FILE[:SCALE] --out DIR2 [--prefix P]

Writes DIR2, a complete copy of the model folder DIR whose transformer has the LoRA merged into its weights:
for every adapted module M (M.lora_A.weight [rank, in], M.lora_B.weight [out, rank], optional M.alpha),
  M.weight <- M.weight + SCALE * (alpha / rank) * B * A     (SCALE alone when the file has no M.alpha)
computed in double precision and stored in the weight's own dtype (bf16 stays bf16), sharded like DIR's
transformer. The other components are copied as they are. dvs loads DIR2 like any model folder; the result
equals applying the LoRA unmerged, up to the rounding of the stored dtype.

  --model DIR        a model folder laid out like THUDM/CogVideoX-5b-I2V
  --lora FILE[:S]    a diffusers / PEFT LoRA .safetensors; S is the user scale (default 1)
  --out DIR2         the folder to create (must not exist, or be empty); written under a temporary name first
  --prefix P         module-name prefix in the LoRA file (default "transformer.")
)";

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// W + scale·B·A in W's dtype (f32 / f16 / bf16; narrowing rounds to nearest even).
HostTensor merged(const HostTensor& w, const LoraFileAdapter& ad, const std::string& name) {
  const int64_t out = ad.b.shape[0], rank = ad.a.shape[0], in = ad.a.shape[1];
  if (w.shape != Shape{out, in})
    throw Error("LoRA for '" + name + "' is [" + std::to_string(out) + ", " + std::to_string(in) +
                "] but the transformer's weight is [" + shape_str(w.shape) + "]");
  if (w.dtype != DType::f32 && w.dtype != DType::f16 && w.dtype != DType::bf16)
    throw Error("'" + name + "' is stored as " + std::string(dtype_name(w.dtype)) + "; only f32, f16 and bf16 weights can be merged");
  const std::vector<float> wf = w.to_f32(), af = ad.a.to_f32(), bf = ad.b.to_f32();
  HostTensor r(w.shape, w.dtype);
  std::vector<double> row(static_cast<size_t>(in));
  for (int64_t o = 0; o < out; ++o) {
    std::fill(row.begin(), row.end(), 0.0);
    for (int64_t k = 0; k < rank; ++k) {
      const double bk = double(bf[size_t(o * rank + k)]);
      const float* ak = af.data() + k * in;
      for (int64_t i = 0; i < in; ++i) row[size_t(i)] += bk * double(ak[i]);
    }
    for (int64_t i = 0; i < in; ++i) {
      const size_t e = size_t(o * in + i);
      const float v = float(double(wf[e]) + ad.scale * row[size_t(i)]);
      switch (w.dtype) {
        case DType::f32: r.as<float>()[e] = v; break;
        case DType::bf16: r.as<uint16_t>()[e] = f32_to_bf16(v); break;
        default: r.as<uint16_t>()[e] = f32_to_f16(v); break;
      }
    }
  }
  return r;
}

// Copies every file of `from` into `to`, skipping the transformer's safetensors files (written merged).
void copy_tree(const fs::path& from, const fs::path& to, const fs::path& transformer_dir) {
  for (auto it = fs::recursive_directory_iterator(from); it != fs::recursive_directory_iterator(); ++it) {
    const fs::path rel = fs::relative(it->path(), from);
    const fs::path dst = to / rel;
    if (it->is_directory()) {
      fs::create_directories(dst);
      continue;
    }
    if (it->path().parent_path() == transformer_dir && ends_with(it->path().filename().string(), ".safetensors")) continue;
    fs::create_directories(dst.parent_path());
    fs::copy_file(it->path(), dst, fs::copy_options::overwrite_existing);
  }
}

}  // namespace

MergeLoraReport merge_lora_folder(const MergeLoraOptions& o) {
  std::error_code ec;
  if (!fs::is_directory(o.model, ec)) throw Error(o.model.string() + ": no such model folder (--model)");
  const fs::path tr_dir = o.model / "transformer";
  if (!fs::is_regular_file(tr_dir / "config.json", ec))
    throw Error(tr_dir.string() + "/config.json is missing: --model must be a pipeline folder with a transformer/");
  if (!fs::is_regular_file(o.lora, ec)) throw Error(o.lora.string() + ": no such LoRA file (--lora)");
  if (fs::exists(o.out, ec) && !(fs::is_directory(o.out, ec) && fs::is_empty(o.out, ec)))
    throw Error(o.out.string() + ": already exists and is not an empty folder; choose another --out");
  if (fs::weakly_canonical(o.out) == fs::weakly_canonical(o.model)) throw Error("--out must differ from --model");

  const std::map<std::string, LoraFileAdapter> adapters = read_lora_file(o.lora, o.scale, o.prefix);
  const WeightSet weights = WeightSet::open_dir(tr_dir);
  for (const auto& [module, ad] : adapters)
    if (!weights.find(module + ".weight"))
      throw Error(o.lora.string() + ": adapts '" + module + "', which the transformer in " + tr_dir.string() +
                  " does not have (is --prefix right?)");

  const fs::path tmp = o.out.parent_path() / (o.out.filename().string() + ".partial-" + std::to_string(::getpid()));
  fs::remove_all(tmp, ec);
  MergeLoraReport report;
  try {
    fs::create_directories(tmp);
    copy_tree(o.model, tmp, tr_dir);
    // Each input file becomes one output file of the same name with the same tensors (a shard index, copied
    // above, stays valid: names, files and byte totals are unchanged).
    for (const auto& file : weights.files()) {
      std::vector<std::pair<std::string, HostTensor>> tensors;
      for (const WeightEntry* t : file->entries()) {
        HostTensor h = file->load(*t);
        const std::string name = t->name;
        if (ends_with(name, ".weight")) {
          const auto it = adapters.find(name.substr(0, name.size() - 7));
          if (it != adapters.end()) {
            h = merged(h, it->second, name);
            ++report.merged_modules;
            report.rank = std::max(report.rank, it->second.a.shape[0]);
          }
        }
        tensors.emplace_back(name, std::move(h));
      }
      std::map<std::string, std::string> meta = file->metadata();
      if (meta.empty()) meta = {{"format", "pt"}};
      write_safetensors(tmp / "transformer" / file->path().filename(), tensors, meta);
    }
    if (fs::exists(o.out, ec)) fs::remove(o.out);  // the empty folder checked above
    fs::rename(tmp, o.out);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  return report;
}

int merge_lora_command(const std::vector<std::string>& args) {
  MergeLoraOptions o;
  std::string lora_spec;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "-h" || a == "--help") {
      std::cout << kHelp;
      return 0;
    }
    const bool known = a == "--model" || a == "--lora" || a == "--out" || a == "--prefix";
    if (!known) {
      std::cerr << "dvs-weights: merge-lora: unexpected argument '" << a << "'\n\n" << kHelp;
      return 2;
    }
    if (i + 1 >= args.size()) {
      std::cerr << "dvs-weights: merge-lora: " << a << " needs a value\n\n" << kHelp;
      return 2;
    }
    const std::string& v = args[++i];
    if (a == "--model") o.model = v;
    else if (a == "--out") o.out = v;
    else if (a == "--prefix") o.prefix = v;
    else lora_spec = v;
  }
  if (o.model.empty() || lora_spec.empty() || o.out.empty()) {
    std::cerr << "dvs-weights: merge-lora needs --model, --lora and --out\n\n" << kHelp;
    return 2;
  }
  try {
    const LoraSpec lora = parse_lora_spec(lora_spec);
    o.lora = lora.file;
    o.scale = lora.scale;
    const MergeLoraReport r = merge_lora_folder(o);
    std::cout << "merged " << r.merged_modules << " LoRA module(s) (rank up to " << r.rank << ", scale " << o.scale
              << ") into " << o.out.string() << "\n";
    return 0;
  } catch (const Error& e) {
    std::cerr << "dvs-weights: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "dvs-weights: error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace dvs::weights_tools
