// dvs-weights: look inside model weights and make new ones. `inspect` lists components, tensors, dtypes, shapes
// and sizes and checks them against the schema their config.json implies; `make-tiny` writes a random-weight
// model; `merge-lora` writes a model folder with a LoRA merged into the transformer (merge_lora.hpp).
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <vector>
#include <sstream>
#include <algorithm>

#include "dvs/error.hpp"
#include "dvs/usage_error.hpp"
#include "spec/model_folder.hpp"
#include "models/random/tiny_model.hpp"
#include "models/random/vda_random.hpp"
#include "io/safetensors_writer.hpp"
#include "spec/vda_config.hpp"
#include "spec/model_schema.hpp"
#include "io/npy.hpp"
#include "io/pth_file.hpp"
#include "io/safetensors.hpp"
#include "io/weight_file.hpp"
#include "io/third_party_logs.hpp"
#include "convert_pth.hpp"
#include "merge_lora.hpp"
#include "value_scan.hpp"

namespace fs = std::filesystem;

namespace {

constexpr const char* kUsage = R"(usage: dvs-weights <command> [options]

commands:
  inspect PATH [--summary] [--values]
      PATH is a pipeline folder (with model_index.json), a component folder (config.json + weights),
      a .safetensors file, a *.safetensors.index.json shard index, a PyTorch .pth checkpoint, or a .npy file.
      Prints every component with its library and class, every tensor with dtype, shape and bytes, totals
      per component and overall, and checks the tensors against the schema of the component's class
      (T5EncoderModel, CogVideoXTransformer3DModel, AutoencoderKLCogVideoX) built from its config.json.
      A component that model_index.json lists and whose class needs weights (a model class) but that has
      no *.safetensors is an error.
      --summary  totals and schema check only, no per-tensor lines.
      --values   also read every floating-point weight and fail (exit 1) on NaN or Inf, naming the tensor
                 and its first bad element (flat index and [i,j,...]); reads all the data, so it takes
                 about as long as reading the files once. A .pth's records are read as dvs reads them, so a
                 damaged one (CRC mismatch) fails too.
  make-tiny --out DIR [--real-size] [--seed N] [--dtype f32|bf16] [--layers N] [--heads N] [--head-dim N]
            [--time-embed-dim N] [--t5-layers N] [--t5-d-model N] [--t5-heads N] [--t5-d-kv N] [--t5-d-ff N]
            [--vocab N] [--text-len N] [--sample LHxLWxF] [--vae-channels a,b,c,d] [--vae-layers-per-block N]
            [--vae-groups N] [--latent-channels N] [--force]
                    write a random-weight CogVideoX-5B-I2V folder of tiny (or any) size that dvs loads;
                    defaults are the conformance pack's sizes; --real-size starts from the real model's
                    (THUDM/CogVideoX-5b-I2V: 42 blocks of 48x64, T5-XXL 24 layers, 480x720x49; about 20 GB
                    in bf16), the other options then change single sizes. DIR is a folder (created; not a file).
                    --sample is the transformer's sample size in LATENT units: latent height x latent width
                    (pixels / 8, the VAE's scale, each even) x video frames (4k+1); e.g. 8x8x9 suits
                    --size 64x64 --frames 9. An existing DIR that is not empty is refused unless --force
                    (then files of the same names are replaced).
  make-vda --size vits|vitb|vitl --out FILE.safetensors [--seed N]
                    write a random-weight Video-Depth-Anything checkpoint of a released size (every tensor
                    of the released .pth, same names and shapes; metric mode when FILE's name starts with
                    "metric_", as the released metric files) for measurements without downloads; dvs reads
                    it wherever it reads a .pth (--depth-model)
  convert IN.pth OUT.safetensors
                    write the checkpoint's tensors (names, dtypes, shapes, bytes) as safetensors
  merge-lora --model DIR --lora FILE[:SCALE] --out DIR2 [--prefix P]
                    write DIR2, a copy of DIR whose transformer has the LoRA merged into its weights
                    (W + SCALE·(alpha/rank)·B·A, in the stored dtype, sharded like DIR); see merge-lora --help

options:
  -h, --help        this text
  --verbose         let the libraries' own log lines through (SentencePiece's trainer in make-tiny)

exit status: 0 all good; 1 a file is unreadable or corrupt, or weights do not match their schema;
             2 usage error.
)";

std::string human_bytes(uint64_t n) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(n);
  int u = 0;
  while (v >= 1024.0 && u < 4) {
    v /= 1024.0;
    ++u;
  }
  char buf[64];
  if (u == 0) std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(n));
  else std::snprintf(buf, sizeof buf, "%llu bytes, %.1f %s", static_cast<unsigned long long>(n), v, units[u]);
  return buf;
}

std::string shape_list(const dvs::Shape& s) {
  std::string out = "[";
  for (size_t i = 0; i < s.size(); ++i) {
    if (i) out += ",";
    out += std::to_string(s[i]);
  }
  return out + "]";
}

struct Totals {
  uint64_t tensors = 0, bytes = 0;
  std::map<std::string, uint64_t> per_dtype;  // dtype name -> tensor count
};

class Inspector {
 public:
  Inspector(bool summary, bool values) : summary_(summary), values_(values) {}

  int failures() const { return failures_; }

  void error(const std::string& msg) {
    std::cout.flush();  // keep the listing and the error in order when both go to one terminal
    std::cerr << "dvs-weights: error: " << msg << "\n";
    ++failures_;
  }

  // Lists the tensors of one weight set and checks them against `cls`'s schema when one is known.
  Totals weights(const dvs::WeightSet& w, const std::string& cls, const nlohmann::json* config,
                 const std::string& config_origin) {
    Totals t;
    std::cout << "  weights: " << w.source().string();
    if (w.sharded()) std::cout << " (" << w.files().size() << " shard" << (w.files().size() == 1 ? "" : "s") << ")";
    std::cout << "\n";
    size_t width = 0, shape_width = 0;
    for (const auto& [name, r] : w.entries()) {
      width = std::max(width, name.size());
      shape_width = std::max(shape_width, shape_list(r.info->shape).size());
    }
    width = std::min<size_t>(width, 72);
    for (const auto& [name, r] : w.entries()) {
      t.tensors++;
      t.bytes += r.info->nbytes();
      t.per_dtype[r.info->dtype_name]++;
      if (!summary_) {
        std::string pad(name.size() < width ? width - name.size() : 0, ' ');
        std::cout << "    " << name << pad << "  " << r.info->dtype_name
                  << std::string(r.info->dtype_name.size() < 8 ? 8 - r.info->dtype_name.size() : 1, ' ')
                  << shape_list(r.info->shape) << std::string(shape_width + 2 - shape_list(r.info->shape).size(), ' ')
                  << r.info->nbytes() << "\n";
      }
    }
    for (const auto& warn : w.warnings()) std::cout << "  warning: " << warn << "\n";
    std::cout << "  total: " << t.tensors << " tensors, " << human_bytes(t.bytes) << ";";
    for (const auto& [dt, n] : t.per_dtype) std::cout << " " << dt << " " << n;
    std::cout << "\n";

    if (cls.empty() || !config) {
      std::cout << "  schema: not checked (no model class known for these weights)\n";
    } else if (!dvs::has_schema(cls)) {
      std::cout << "  schema: not checked (no schema for " << cls << ")\n";
    } else {
      try {
        const dvs::Schema s = dvs::schema_for(cls, *config, config_origin);
        const auto issues = dvs::check_schema(s, w);
        if (issues.empty()) {
          size_t optional_absent = 0;
          for (const auto& spec : s.tensors)
            if (spec.optional && !w.find(spec.name)) ++optional_absent;
          std::cout << "  schema: OK, matches " << cls << " from " << config_origin;
          if (optional_absent) std::cout << " (" << optional_absent << " optional tensor(s) absent, e.g. tied weights)";
          std::cout << "\n";
        } else {
          std::cout << "  schema: " << issues.size() << " mismatch(es) against " << cls << " from " << config_origin << "\n";
          for (const auto& i : issues) std::cout << "    " << i.message() << "\n";
          error(w.source().string() + ": " + std::to_string(issues.size()) + " tensor(s) do not match the " + cls +
                " schema (see above)");
        }
      } catch (const dvs::Error& e) {
        error(e.what());
      }
    }
    if (values_) check_values(w);
    return t;
  }

  int pipeline(const fs::path& root) {
    const dvs::ModelFolder m = dvs::ModelFolder::open(root);
    std::cout << "pipeline " << (m.pipeline_class().empty() ? "(no _class_name)" : m.pipeline_class()) << " at "
              << root.string() << "\n";
    Totals all;
    size_t with_weights = 0;
    for (const auto& c : m.components()) {
      std::cout << "\ncomponent " << c.name << ": " << c.library << " " << c.class_name << "\n";
      try {
        const dvs::Component comp = m.load(c.name);
        std::cout << "  config: " << comp.config_path.string() << "\n";
        if (!comp.weights) {
          if (expects_weights(c.class_name)) {
            std::cout << "  no weights\n";
            error(c.name + ": model_index.json lists it as " + c.class_name + ", a model with weights, but " +
                  comp.dir.string() + " holds no *.safetensors (an incomplete download or copy?)");
          } else {
            std::cout << "  no weights (none expected for " << c.class_name << ")\n";
          }
          // dvs's tokenizer reads the SentencePiece vocabulary from this one file (models/cogvideox/tokenizer.cpp).
          if (c.class_name.find("T5Tokenizer") != std::string::npos && !fs::is_regular_file(comp.dir / "spiece.model"))
            error(c.name + ": " + (comp.dir / "spiece.model").string() + " is missing: dvs run reads the " + c.class_name +
                  " vocabulary from it (copy the model's tokenizer/ folder again)");
          continue;
        }
        ++with_weights;
        const Totals t = weights(*comp.weights, c.class_name, &comp.config, comp.config_path.string());
        all.tensors += t.tensors;
        all.bytes += t.bytes;
        for (const auto& [dt, n] : t.per_dtype) all.per_dtype[dt] += n;
      } catch (const dvs::Error& e) {
        error(e.what());
      }
    }
    std::cout << "\noverall: " << with_weights << " component(s) with weights, " << all.tensors << " tensors, "
              << human_bytes(all.bytes) << ";";
    for (const auto& [dt, n] : all.per_dtype) std::cout << " " << dt << " " << n;
    std::cout << "\n";
    return finish();
  }

  // A component folder, a .safetensors file or a shard index: the class comes from a config.json beside it.
  int weight_source(const fs::path& p, bool is_dir) {
    const fs::path dir = is_dir ? p : p.parent_path();
    const dvs::WeightSet w = is_dir ? dvs::WeightSet::open_dir(p) : dvs::WeightSet::open_file(p);
    nlohmann::json config;
    std::string cls, origin;
    std::error_code ec;
    if (fs::is_regular_file(dir / "config.json", ec)) {
      origin = (dir / "config.json").string();
      config = dvs::read_json_file(dir / "config.json");
      cls = dvs::config_class_name(config);
    }
    std::cout << (is_dir ? "component " : "file ") << p.string();
    if (!cls.empty()) std::cout << ": " << cls;
    std::cout << "\n";
    weights(w, cls, cls.empty() ? nullptr : &config, origin);
    return finish();
  }

  int npy(const fs::path& p) {
    const dvs::HostTensor t = dvs::read_npy(p);
    std::cout << "npy " << p.string() << ": " << dvs::dtype_name(t.dtype) << " " << shape_list(t.shape) << ", "
              << human_bytes(t.bytes()) << "\n";
    if (values_ && (t.dtype == dvs::DType::f32 || t.dtype == dvs::DType::f16)) {
      const auto hit = dvs::weights_tools::first_non_finite(t.data, t.dtype == dvs::DType::f32 ? "F32" : "F16");
      if (hit)
        error(p.string() + ": holds " + std::string(hit->nan ? "NaN" : "an infinite value") + ", first at element " +
              std::to_string(hit->index) + " " + index_list(t.shape, hit->index));
      else
        std::cout << "  values: OK, all finite\n";
    }
    return finish();
  }

  // --values for a .pth: every tensor's record read as the loaders read it (so libzip checks its CRC, as
  // dvs depth's load does) and every floating-point one scanned for NaN/Inf.
  int pth_values(const fs::path& p) {
    const dvs::PthFile f = dvs::PthFile::open(p);
    size_t checked = 0, bad = 0;
    for (const auto& t : f.tensors()) {
      std::vector<uint8_t> bytes;
      try {
        bytes = f.read_bytes(t);
      } catch (const dvs::Error& e) {
        ++bad;
        error(std::string(e.what()) + " (tensor '" + t.name + "'; the file is damaged: download or copy it again)");
        continue;
      }
      if (!dvs::weights_tools::is_float_dtype(t.dtype_name)) continue;
      ++checked;
      const auto hit = dvs::weights_tools::first_non_finite(bytes, t.dtype_name);
      if (!hit) continue;
      ++bad;
      error(p.string() + ": tensor '" + t.name + "' " + t.dtype_name + shape_list(t.shape) + " holds " +
            (hit->nan ? "NaN" : "an infinite value") + ", first at element " + std::to_string(hit->index) + " " +
            index_list(t.shape, hit->index));
    }
    if (bad == 0) std::cout << "  values: OK, every record reads back intact and all " << checked << " floating-point tensors are finite\n";
    else std::cout << "  values: " << bad << " tensor(s) unreadable or holding NaN/Inf\n";
    return finish();
  }

  // Model classes hold weights; tokenizers and schedulers do not.
  static bool expects_weights(const std::string& cls) {
    auto ends = [&](const std::string& suffix) {
      return cls.size() >= suffix.size() && cls.compare(cls.size() - suffix.size(), suffix.size(), suffix) == 0;
    };
    return dvs::has_schema(cls) || ends("Model") || cls.rfind("Autoencoder", 0) == 0;
  }

 private:
  int finish() const {
    if (failures_) std::cout << "\nFAILED: " << failures_ << " problem(s)\n";
    return failures_ ? 1 : 0;
  }

  // --values: every float tensor read; each one holding NaN/Inf is a failure naming its first bad element.
  void check_values(const dvs::WeightSet& w) {
    size_t checked = 0, bad = 0;
    for (const auto& [name, r] : w.entries()) {
      if (!dvs::weights_tools::is_float_dtype(r.info->dtype_name)) continue;
      ++checked;
      const auto hit = dvs::weights_tools::first_non_finite(r.file->bytes(*r.info), r.info->dtype_name);
      if (!hit) continue;
      ++bad;
      error(w.source().string() + ": tensor '" + name + "' " + r.info->dtype_name + shape_list(r.info->shape) + " holds " +
            (hit->nan ? "NaN" : "an infinite value") + ", first at element " + std::to_string(hit->index) + " " +
            index_list(r.info->shape, hit->index));
    }
    if (bad == 0) std::cout << "  values: OK, all " << checked << " floating-point tensors are finite\n";
    else std::cout << "  values: " << bad << " of " << checked << " floating-point tensors hold NaN or Inf\n";
  }

  // Flat C-order index -> "[i,j,k]".
  static std::string index_list(const dvs::Shape& shape, uint64_t flat) {
    std::vector<uint64_t> idx(shape.size());
    for (size_t d = shape.size(); d-- > 0;) {
      const uint64_t n = uint64_t(std::max<int64_t>(shape[d], 1));
      idx[d] = flat % n;
      flat /= n;
    }
    std::string out = "[";
    for (size_t d = 0; d < idx.size(); ++d) {
      if (d) out += ',';
      out += std::to_string(idx[d]);
    }
    return out + "]";
  }

  bool summary_, values_;
  int failures_ = 0;
};

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

int inspect(const std::vector<std::string>& args) {
  bool summary = false, values = false;
  std::string path;
  for (const auto& a : args) {
    if (a == "--summary") summary = true;
    else if (a == "--values") values = true;
    else if (a == "-h" || a == "--help") {
      std::cout << kUsage;
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      std::cerr << "dvs-weights: inspect: unknown option " << a << "\n" << kUsage;
      return 2;
    } else if (path.empty()) path = a;
    else {
      std::cerr << "dvs-weights: inspect takes one PATH\n" << kUsage;
      return 2;
    }
  }
  if (path.empty()) {
    std::cerr << "dvs-weights: inspect needs a PATH\n" << kUsage;
    return 2;
  }
  Inspector ins(summary, values);
  try {
    const fs::path p(path);
    std::error_code ec;
    if (fs::is_directory(p, ec)) {
      if (fs::is_regular_file(p / "model_index.json", ec)) return ins.pipeline(p);
      return ins.weight_source(p, true);
    }
    if (!fs::exists(p, ec)) throw dvs::Error(path + ": no such file or folder");
    if (ends_with(path, ".npy")) return ins.npy(p);
    if (ends_with(path, ".json")) return ins.weight_source(p, false);
    // A weight file is read as what its content shows, whatever its extension (io/weight_file.hpp); one of
    // neither format goes to the reader its name claims, which says what is wrong with it.
    const dvs::WeightFormat format = dvs::weight_file_format(p);
    const bool named_pth = ends_with(path, ".pth") || ends_with(path, ".pt");
    if (format == dvs::WeightFormat::pth || (format == dvs::WeightFormat::neither && named_pth)) {
      const int listed = dvs::weights_tools::inspect_pth(p, summary);
      return values ? std::max(listed, ins.pth_values(p)) : listed;
    }
    if (format == dvs::WeightFormat::safetensors || ends_with(path, ".safetensors")) return ins.weight_source(p, false);
    throw dvs::Error(path + ": not a pipeline folder, component folder, .safetensors, *.safetensors.index.json, .pth or .npy");
  } catch (const dvs::Error& e) {
    std::cout.flush();
    std::cerr << "dvs-weights: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cout.flush();
    std::cerr << "dvs-weights: error: " << path << ": " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

namespace {

// `--sample LHxLWxF`, refusing sizes no run can use: the transformer cuts the latent into 2x2 patches and its
// learned positional table fixes the run to exactly LH x LW, so both must be even; videos have 4k+1 frames (the VAE
// keeps the first and compresses the rest by 4), and only a clip of exactly F frames uses the stored table.
void parse_sample(const std::string& v, dvs::models::TinyModelSpec& spec) {
  int h = 0, w = 0, f = 0;
  char end = 0;
  const bool shaped = std::sscanf(v.c_str(), "%dx%dx%d%c", &h, &w, &f, &end) == 3;
  std::string why;
  if (!shaped) why = "must be LATENT_HxLATENT_WxFRAMES";
  else if (h < 2 || w < 2 || h > 1024 || w > 1024 || h % 2 || w % 2)
    why = "latent height and width must be even numbers in [2, 1024] (the transformer's 2x2 patches; its learned "
          "positional table then fixes the run's size to them)";
  else if (f < 1 || f > 1021 || (f - 1) % 4)
    why = "frames must be 4k+1 in [1, 1021] (videos have 4k+1 frames: the VAE compresses time by 4 after the first; "
          "only a clip of exactly that many frames uses the learned positional table)";
  if (!why.empty())
    throw dvs::UsageError("make-tiny: --sample " + why + ", got '" + v + "'; it is in latent units (pixels / 8), e.g. "
                          "8x8x9 for 64x64-pixel videos of 9 frames");
  spec.sample_height = h, spec.sample_width = w, spec.sample_frames = f;
}

}  // namespace

// `make-tiny`: every option has the pack's value as default.
int make_tiny(const std::vector<std::string>& args) {
  dvs::models::TinyModelSpec spec;
  std::string out;
  auto value = [&](size_t& i) -> const std::string& {
    if (i + 1 >= args.size()) throw dvs::UsageError("make-tiny: " + args[i] + " needs a value");
    return args[++i];
  };
  auto integer = [&](size_t& i, int lo, int hi) {
    const std::string name = args[i], v = value(i);
    try {
      size_t used = 0;
      int x = std::stoi(v, &used);
      if (used == v.size() && x >= lo && x <= hi) return x;
    } catch (const std::exception&) {
    }
    throw dvs::UsageError("make-tiny: " + name + " must be a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                     "], got '" + v + "'");
  };
  // --real-size first, wherever it is given, so that the other options change single sizes of it.
  if (std::find(args.begin(), args.end(), "--real-size") != args.end()) {
    spec.dtype = dvs::DType::bf16;
    spec.t5_layers = 24, spec.t5_heads = 64, spec.t5_d_kv = 64, spec.t5_d_model = 4096, spec.t5_d_ff = 10240;
    spec.vocab = 32128;
    spec.layers = 42, spec.heads = 48, spec.head_dim = 64, spec.time_embed_dim = 512, spec.text_len = 226;
    spec.sample_frames = 49, spec.sample_height = 60, spec.sample_width = 90;
    spec.vae_channels = {128, 256, 256, 512};
    spec.vae_layers_per_block = 3, spec.vae_groups = 32, spec.latent_channels = 16;
  }
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "-h" || a == "--help") {
      std::cout << kUsage;
      return 0;
    }
    if (a == "--real-size" || a == "--force") continue;
    if (a == "--out") out = value(i);
    else if (a == "--seed") spec.seed = uint64_t(integer(i, 0, 1 << 30));
    else if (a == "--dtype") {
      const std::string& d = value(i);
      if (d == "f32") spec.dtype = dvs::DType::f32;
      else if (d == "bf16") spec.dtype = dvs::DType::bf16;
      else throw dvs::UsageError("make-tiny: --dtype must be f32 or bf16");
    } else if (a == "--layers") spec.layers = integer(i, 1, 64);
    else if (a == "--heads") spec.heads = integer(i, 1, 64);
    else if (a == "--head-dim") spec.head_dim = integer(i, 16, 256);
    else if (a == "--t5-layers") spec.t5_layers = integer(i, 1, 48);
    else if (a == "--t5-d-model") spec.t5_d_model = integer(i, 8, 4096);
    else if (a == "--t5-heads") spec.t5_heads = integer(i, 1, 128);
    else if (a == "--t5-d-kv") spec.t5_d_kv = integer(i, 1, 256);
    else if (a == "--t5-d-ff") spec.t5_d_ff = integer(i, 1, 65536);
    else if (a == "--time-embed-dim") spec.time_embed_dim = integer(i, 1, 4096);
    else if (a == "--vae-layers-per-block") spec.vae_layers_per_block = integer(i, 1, 8);
    else if (a == "--vae-groups") spec.vae_groups = integer(i, 1, 512);
    else if (a == "--vocab") spec.vocab = integer(i, 16, 32128);
    else if (a == "--text-len") spec.text_len = integer(i, 2, 512);
    else if (a == "--latent-channels") spec.latent_channels = integer(i, 1, 64);
    else if (a == "--sample") parse_sample(value(i), spec);
    else if (a == "--vae-channels") {
      spec.vae_channels.clear();
      std::stringstream ss(value(i));
      for (std::string part; std::getline(ss, part, ',');) {
        try {
          spec.vae_channels.push_back(std::stoi(part));
        } catch (const std::exception&) {
          throw dvs::UsageError("make-tiny: --vae-channels must be comma-separated whole numbers, got '" + part + "'");
        }
      }
    } else throw dvs::UsageError("make-tiny: unknown option " + a + " (see dvs-weights --help)");
  }
  if (out.empty()) throw dvs::UsageError("make-tiny: --out DIR is required");
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec))
    throw dvs::Error("make-tiny: --out " + out + " is a file; it must name a folder (it is created when missing)");
  // As merge-lora: an existing folder with something in it is not written into unless asked to.
  if (fs::is_directory(out, ec) && !fs::is_empty(out, ec) && std::find(args.begin(), args.end(), "--force") == args.end())
    throw dvs::Error(out + ": already exists and is not an empty folder" +
                     std::string(fs::exists(fs::path(out) / "model_index.json", ec) ? " (it holds a model)" : "") +
                     "; choose another --out, or give --force to write into it (files of the same names are replaced)");
  spec.t5_d_kv = std::max(1, spec.t5_d_model / spec.t5_heads);
  spec.t5_d_ff = 2 * spec.t5_d_model;
  spec.time_embed_dim = spec.heads * spec.head_dim;
  dvs::models::write_tiny_model(out, spec);
  std::cout << "wrote a random-weight model to " << out << " (seed " << spec.seed << ")\n";
  return 0;
}

// `make-vda`: a random-weight Video-Depth-Anything checkpoint of a released size.
int make_vda(const std::vector<std::string>& args) {
  std::string size, out;
  uint64_t seed = 0;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "-h" || a == "--help") {
      std::cout << kUsage;
      return 0;
    }
    if (a != "--size" && a != "--out" && a != "--seed") throw dvs::UsageError("make-vda: unknown option " + a + " (see dvs-weights --help)");
    if (i + 1 >= args.size()) throw dvs::UsageError("make-vda: " + a + " needs a value");
    const std::string v = args[++i];
    if (a == "--size") size = v;
    else if (a == "--out") out = v;
    else {
      try {
        size_t used = 0;
        seed = std::stoull(v, &used);
        if (used != v.size()) throw std::invalid_argument(v);
      } catch (const std::exception&) {
        throw dvs::UsageError("make-vda: --seed must be a whole number, got '" + v + "'");
      }
    }
  }
  if (size.empty() || out.empty()) throw dvs::UsageError("make-vda: --size vits|vitb|vitl and --out FILE.safetensors are required");
  if (fs::path(out).extension() != ".safetensors") throw dvs::UsageError("make-vda: --out must end in .safetensors, got " + out);
  if (size != "vits" && size != "vitb" && size != "vitl") throw dvs::UsageError("make-vda: --size must be vits, vitb or vitl, got '" + size + "'");
  const dvs::VdaConfig cfg = dvs::released_vda_config(size);
  const auto tensors = dvs::vda_random_checkpoint(cfg, seed);
  uint64_t bytes = 0;
  for (const auto& t : tensors) bytes += t.second.bytes();
  dvs::write_safetensors(out, tensors, {{"format", "pt"}, {"dvs", "random-weight Video-Depth-Anything " + size + ", seed " + std::to_string(seed)}});
  std::cout << "wrote a random-weight Video-Depth-Anything " << size << " (" << tensors.size() << " tensors, "
            << human_bytes(bytes) << ", seed " << seed << ") to " << out << "\n";
  return 0;
}

// Runs a command: a usage error exits 2, any other failure (dvs::Error, filesystem errors while writing) 1.
int exit_status(int (*command)(const std::vector<std::string>&), const std::vector<std::string>& args) {
  try {
    return command(args);
  } catch (const dvs::UsageError& e) {
    std::cerr << "dvs-weights: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "dvs-weights: error: " << e.what() << "\n";
    return 1;
  }
}

int main(int argc, char** argv) {
  std::vector<std::string> args;
  bool verbose = false;
  for (int i = 1; i < argc; ++i) {  // --verbose: the libraries' own log lines (SentencePiece) too
    if (std::strcmp(argv[i], "--verbose") == 0) verbose = true;
    else args.emplace_back(argv[i]);
  }
  dvs::set_third_party_logs(verbose);
  if (args.empty()) {
    std::cerr << kUsage;
    return 2;
  }
  const std::string cmd = args[0];
  args.erase(args.begin());
  if (cmd == "-h" || cmd == "--help" || cmd == "help") {
    std::cout << kUsage;
    return 0;
  }
  if (cmd == "inspect") return inspect(args);
  if (cmd == "make-tiny") return exit_status(make_tiny, args);
  if (cmd == "make-vda") return exit_status(make_vda, args);
  if (cmd == "convert") return dvs::weights_tools::convert_command(args);
  if (cmd == "merge-lora") return dvs::weights_tools::merge_lora_command(args);
  std::cerr << "dvs-weights: unknown command '" << cmd << "'\n" << kUsage;
  return 2;
}
