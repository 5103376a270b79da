#include "models/random/tiny_model.hpp"

#include <sentencepiece_trainer.h>

#include "io/third_party_logs.hpp"

#include <atomic>
#include <cmath>
#include <exception>
#include <fstream>
#include <mutex>
#include <thread>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "dvs/error.hpp"
#include "spec/model_schema.hpp"
#include "io/injected_faults.hpp"
#include "io/safetensors_writer.hpp"

namespace dvs::models {
namespace {

using json = nlohmann::ordered_json;

void write_json(const std::filesystem::path& p, const json& j) {
  std::filesystem::create_directories(p.parent_path());
  std::ofstream out(p);
  out << j.dump(2) << "\n";
  if (!out || faults::write_error(p)) throw Error(p.string() + ": cannot write");
}

json t5_config(const TinyModelSpec& s) {
  return {{"architectures", {"T5EncoderModel"}}, {"d_ff", s.t5_d_ff}, {"d_kv", s.t5_d_kv}, {"d_model", s.t5_d_model},
          {"decoder_start_token_id", 0}, {"dense_act_fn", "gelu_new"}, {"dropout_rate", 0.1}, {"eos_token_id", 1},
          {"feed_forward_proj", "gated-gelu"}, {"initializer_factor", 1.0}, {"is_encoder_decoder", true},
          {"is_gated_act", true}, {"layer_norm_epsilon", 1e-6}, {"model_type", "t5"}, {"num_decoder_layers", s.t5_layers},
          {"num_heads", s.t5_heads}, {"num_layers", s.t5_layers}, {"pad_token_id", 0},
          {"relative_attention_max_distance", 128}, {"relative_attention_num_buckets", 32},
          {"tie_word_embeddings", false}, {"torch_dtype", s.dtype == DType::bf16 ? "bfloat16" : "float32"},
          {"use_cache", true}, {"vocab_size", s.vocab}};
}

json transformer_config(const TinyModelSpec& s) {
  return {{"_class_name", "CogVideoXTransformer3DModel"}, {"activation_fn", "gelu-approximate"}, {"attention_bias", true},
          {"attention_head_dim", s.head_dim}, {"dropout", 0.0}, {"flip_sin_to_cos", true}, {"freq_shift", 0},
          {"in_channels", 2 * s.latent_channels}, {"max_text_seq_length", s.text_len}, {"norm_elementwise_affine", true},
          {"norm_eps", 1e-5}, {"num_attention_heads", s.heads}, {"num_layers", s.layers}, {"ofs_embed_dim", nullptr},
          {"out_channels", s.latent_channels}, {"patch_bias", true}, {"patch_size", 2}, {"patch_size_t", nullptr},
          {"sample_frames", s.sample_frames}, {"sample_height", s.sample_height}, {"sample_width", s.sample_width},
          {"spatial_interpolation_scale", 1.875}, {"temporal_compression_ratio", 4}, {"temporal_interpolation_scale", 1.0},
          {"text_embed_dim", s.t5_d_model}, {"time_embed_dim", s.time_embed_dim}, {"timestep_activation_fn", "silu"},
          {"use_learned_positional_embeddings", true}, {"use_rotary_positional_embeddings", true}};
}

json vae_config(const TinyModelSpec& s) {
  json down = json::array(), up = json::array();
  for (size_t i = 0; i < s.vae_channels.size(); ++i) {
    down.push_back("CogVideoXDownBlock3D");
    up.push_back("CogVideoXUpBlock3D");
  }
  return {{"_class_name", "AutoencoderKLCogVideoX"}, {"act_fn", "silu"}, {"block_out_channels", s.vae_channels},
          {"down_block_types", down}, {"force_upcast", true}, {"in_channels", 3}, {"invert_scale_latents", false},
          {"latent_channels", s.latent_channels}, {"latents_mean", nullptr}, {"latents_std", nullptr},
          {"layers_per_block", s.vae_layers_per_block}, {"norm_eps", 1e-6}, {"norm_num_groups", s.vae_groups},
          {"out_channels", 3}, {"sample_height", 480}, {"sample_width", 720}, {"scaling_factor", 0.7},
          {"shift_factor", nullptr}, {"temporal_compression_ratio", 4}, {"up_block_types", up},
          {"use_post_quant_conv", false}, {"use_quant_conv", false}};
}

json scheduler_config() {
  return {{"_class_name", "CogVideoXDDIMScheduler"}, {"beta_end", 0.012}, {"beta_schedule", "scaled_linear"},
          {"beta_start", 0.00085}, {"clip_sample", false}, {"clip_sample_range", 1.0}, {"num_train_timesteps", 1000},
          {"prediction_type", "v_prediction"}, {"rescale_betas_zero_snr", true}, {"sample_max_value", 1.0},
          {"set_alpha_to_one", true}, {"snr_shift_scale", 1.0}, {"steps_offset", 0}, {"timestep_spacing", "trailing"},
          {"trained_betas", nullptr}};
}

// Seeded normals, independent of the standard library's distribution implementations.
class Normal {
 public:
  explicit Normal(uint64_t seed) : rng_(seed) {}
  float operator()() {
    if (have_) {
      have_ = false;
      return spare_;
    }
    double u1 = (double(rng_() >> 11) + 1.0) * 0x1.0p-53, u2 = double(rng_() >> 11) * 0x1.0p-53;
    double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = float(r * std::sin(2 * M_PI * u2));
    have_ = true;
    return float(r * std::cos(2 * M_PI * u2));
  }

 private:
  std::mt19937_64 rng_;
  bool have_ = false;
  float spare_ = 0;
};

bool contains(const std::string& s, const char* part) { return s.find(part) != std::string::npos; }

// The pack's initialisation, decided by the tensor's name and rank.
HostTensor random_tensor(const TensorSpec& spec, Normal& normal, DType dtype) {
  const std::string& n = spec.name;
  const int64_t count = shape_numel(spec.shape);
  double mean = 0, sigma = 0.05;
  if (spec.shape.size() >= 2) {
    int64_t fan_in = 1;
    for (size_t i = 1; i < spec.shape.size(); ++i) fan_in *= spec.shape[i];
    sigma = 1.0 / std::sqrt(double(std::max<int64_t>(fan_in, 1)));
    if (contains(n, "shared.weight") || contains(n, "embed_tokens")) sigma = 1.0;
    if (contains(n, "relative_attention_bias")) sigma = 0.5;
    if (contains(n, "pos_embedding")) sigma = 0.5;
  } else if (contains(n, "norm")) {
    bool weight = n.size() > 7 && n.compare(n.size() - 7, 7, ".weight") == 0;
    mean = weight ? 1.0 : 0.0;
    sigma = 0.1;
  }
  std::vector<float> v(static_cast<size_t>(count));
  for (float& x : v) x = float(mean + sigma * normal());
  HostTensor f32 = HostTensor::from_f32(spec.shape, v);
  if (dtype == DType::f32) return f32;
  HostTensor out(spec.shape, DType::bf16);
  for (int64_t i = 0; i < count; ++i) out.as<uint16_t>()[i] = f32_to_bf16(v[size_t(i)]);
  return out;
}

// Above this many values a component is drawn on every core, one seeded stream per tensor (the seed, the
// tensor's index), instead of one stream through all tensors: the real model's 5.6e9 transformer values take
// minutes on one core (Box-Muller). Still one model per seed; the tiny sizes keep their single stream and values.
constexpr int64_t kParallelValues = int64_t(1) << 28;

void write_weights(const std::filesystem::path& file, const Schema& schema, Normal& normal, DType dtype, uint64_t seed) {
  std::vector<const TensorSpec*> specs;
  int64_t values = 0;
  for (const TensorSpec& spec : schema.tensors) {
    if (spec.optional) continue;  // tied weights (T5's encoder.embed_tokens) are not stored
    specs.push_back(&spec);
    values += shape_numel(spec.shape);
  }
  std::vector<std::pair<std::string, HostTensor>> tensors(specs.size());
  if (values <= kParallelValues) {
    for (size_t i = 0; i < specs.size(); ++i) tensors[i] = {specs[i]->name, random_tensor(*specs[i], normal, dtype)};
  } else {
    std::atomic<size_t> next{0};
    std::exception_ptr failure;
    std::mutex failure_mutex;
    auto work = [&] {
      for (size_t i = next++; i < specs.size(); i = next++) {
        try {
          Normal own(seed * 0x9E3779B97F4A7C15ull + i + 1);
          tensors[i] = {specs[i]->name, random_tensor(*specs[i], own, dtype)};
        } catch (...) {
          std::lock_guard<std::mutex> lock(failure_mutex);
          failure = std::current_exception();
        }
      }
    };
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < std::max(1u, std::thread::hardware_concurrency()); ++t) pool.emplace_back(work);
    for (std::thread& t : pool) t.join();
    if (failure) std::rethrow_exception(failure);
  }
  std::filesystem::create_directories(file.parent_path());
  write_safetensors(file, tensors);
}

// Caption-like lines for the tokenizer's vocabulary.
std::string caption_corpus() {
  const char* subjects[] = {"a red fox", "a dog", "an old woman", "a cat with glasses", "a corgi", "a man", "two children",
                            "a bird", "a small boat", "a horse"};
  const char* verbs[] = {"walks along", "sits on", "runs across", "looks at", "jumps over", "reads near", "plays by",
                         "sleeps under"};
  const char* places[] = {"the beach", "a kitchen table", "the green hills", "a busy street", "the river bank",
                          "a wooden desk", "the snowy forest", "a sunny garden", "the blue sea", "a red armchair"};
  std::ostringstream out;
  for (int i = 0; i < 400; ++i)
    out << subjects[i % 10] << " " << verbs[(i / 10) % 8] << " " << places[(i * 7) % 10] << ", in soft light.\n";
  return out.str();
}

void write_tokenizer(const std::filesystem::path& dir, const TinyModelSpec& s) {
  std::filesystem::create_directories(dir);
  const std::filesystem::path corpus = dir / "corpus.txt.tmp";
  std::ofstream(corpus) << caption_corpus();
  std::ostringstream args;
  args << "--input=" << corpus.string() << " --model_prefix=" << (dir / "spiece").string() << " --vocab_size=" << s.vocab
       << " --model_type=unigram --pad_id=0 --eos_id=1 --unk_id=2 --bos_id=-1 --character_coverage=1.0"
       << " --normalization_rule_name=nmt_nfkc --hard_vocab_limit=false --num_threads=1 --seed_sentencepiece_size=100000"
       << " --minloglevel=2";
  auto status = [&] {
    const QuietStderr quiet;  // the trainer prints its command line whatever --minloglevel says
    return sentencepiece::SentencePieceTrainer::Train(args.str());
  }();
  std::filesystem::remove(corpus);
  std::filesystem::remove(dir / "spiece.vocab");
  if (!status.ok()) throw Error(dir.string() + ": training the tiny tokenizer failed: " + status.ToString());
  auto special = [](const char* content) {
    return json{{"content", content}, {"lstrip", false}, {"normalized", false}, {"rstrip", false}, {"single_word", false}};
  };
  write_json(dir / "special_tokens_map.json",
             {{"eos_token", special("</s>")}, {"pad_token", special("<pad>")}, {"unk_token", special("<unk>")}});
  json added = json::object();
  const char* names[] = {"<pad>", "</s>", "<unk>"};
  for (int i = 0; i < 3; ++i) {
    json e = special(names[i]);
    e["special"] = true;
    added[std::to_string(i)] = e;
  }
  write_json(dir / "tokenizer_config.json",
             {{"add_prefix_space", true}, {"added_tokens_decoder", added}, {"additional_special_tokens", json::array()},
              {"clean_up_tokenization_spaces", false}, {"eos_token", "</s>"}, {"extra_ids", 0}, {"legacy", true},
              {"model_max_length", s.text_len}, {"pad_token", "<pad>"}, {"sp_model_kwargs", json::object()},
              {"tokenizer_class", "T5Tokenizer"}, {"unk_token", "<unk>"}});
}

}  // namespace

void write_tiny_model(const std::filesystem::path& dir, const TinyModelSpec& s) {
  if (s.dtype != DType::f32 && s.dtype != DType::bf16) throw Error("make-tiny: --dtype must be f32 or bf16");
  if (s.head_dim % 16 != 0) throw Error("make-tiny: --head-dim must be a multiple of 16 (3D RoPE splits it t:h:w = 2:3:3 in pairs)");
  for (int c : s.vae_channels)
    if (c % s.vae_groups != 0) throw Error("make-tiny: every VAE channel count must be divisible by --vae-groups");
  if (s.vae_channels.size() < 3) throw Error("make-tiny: the VAE needs at least 3 blocks (spatial ×8)");
  if (s.vocab < 16) throw Error("make-tiny: --vocab must be at least 16");
  std::filesystem::create_directories(dir);
  write_json(dir / "model_index.json",
             {{"_class_name", "CogVideoXImageToVideoPipeline"}, {"scheduler", {"diffusers", "CogVideoXDDIMScheduler"}},
              {"text_encoder", {"transformers", "T5EncoderModel"}}, {"tokenizer", {"transformers", "T5Tokenizer"}},
              {"transformer", {"diffusers", "CogVideoXTransformer3DModel"}}, {"vae", {"diffusers", "AutoencoderKLCogVideoX"}}});
  write_json(dir / "scheduler" / "scheduler_config.json", scheduler_config());
  write_tokenizer(dir / "tokenizer", s);

  Normal normal(s.seed);
  const json t5 = t5_config(s), tr = transformer_config(s), vae = vae_config(s);
  write_json(dir / "text_encoder" / "config.json", t5);
  write_weights(dir / "text_encoder" / "model.safetensors", schema_for("T5EncoderModel", nlohmann::json::parse(t5.dump())),
                normal, s.dtype, s.seed);
  write_json(dir / "transformer" / "config.json", tr);
  write_weights(dir / "transformer" / "diffusion_pytorch_model.safetensors",
                schema_for("CogVideoXTransformer3DModel", nlohmann::json::parse(tr.dump())), normal, s.dtype, s.seed);
  write_json(dir / "vae" / "config.json", vae);
  write_weights(dir / "vae" / "diffusion_pytorch_model.safetensors",
                schema_for("AutoencoderKLCogVideoX", nlohmann::json::parse(vae.dump())), normal, DType::f32, s.seed);
}

}  // namespace dvs::models
