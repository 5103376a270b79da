#include "models/cogvideox/tokenizer.hpp"

#include <sentencepiece_processor.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dvs/error.hpp"

namespace dvs {

namespace fs = std::filesystem;

namespace {

// One added token of the slow tokenizer (transformers AddedToken): matched in the raw text before
// SentencePiece runs; lstrip/rstrip trim whitespace off the neighbouring chunks.
struct AddedToken {
  std::string content;
  int id = 0;
  bool lstrip = false;
  bool rstrip = false;
};

std::string read_file_bytes(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("tokenizer: cannot open " + path.string());
  std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) throw Error("tokenizer: cannot read " + path.string());
  return bytes;
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

std::string_view lstrip(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  return s;
}
std::string_view rstrip(std::string_view s) {
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

}  // namespace

struct T5Tokenizer::Impl {
  fs::path model_file;
  sentencepiece::SentencePieceProcessor sp;
  std::vector<AddedToken> added;  // sorted longest first, so the first match at a position is the longest
  int pad = 0, eos = 1, unk = 2;
  int size = 0;

  int token_id(const std::string& token) const {
    for (const auto& a : added)
      if (a.content == token) return a.id;
    return sp.PieceToId(token);
  }

  // SentencePiece ids of `text`, with added tokens found in the text mapped to their ids.
  std::vector<int32_t> pieces(std::string_view text) const {
    // Split around added tokens: earliest occurrence, longest token there (transformers' Trie.split).
    struct Chunk {
      std::string_view text;
      const AddedToken* token;  // null for plain text
    };
    std::vector<Chunk> chunks;
    size_t start = 0, i = 0;
    while (i < text.size()) {
      const AddedToken* hit = nullptr;
      for (const auto& a : added)
        if (!a.content.empty() && text.compare(i, a.content.size(), a.content) == 0) {
          hit = &a;
          break;
        }
      if (!hit) {
        ++i;
        continue;
      }
      if (i > start) chunks.push_back({text.substr(start, i - start), nullptr});
      chunks.push_back({text.substr(i, hit->content.size()), hit});
      i += hit->content.size();
      start = i;
    }
    if (start < text.size()) chunks.push_back({text.substr(start), nullptr});

    for (size_t c = 0; c < chunks.size(); ++c) {
      const AddedToken* t = chunks[c].token;
      if (!t) continue;
      if (t->rstrip && c + 1 < chunks.size() && !chunks[c + 1].token) chunks[c + 1].text = lstrip(chunks[c + 1].text);
      if (t->lstrip && c > 0 && !chunks[c - 1].token) chunks[c - 1].text = rstrip(chunks[c - 1].text);
    }

    std::vector<int32_t> ids;
    for (const auto& chunk : chunks) {
      if (chunk.token) {
        ids.push_back(chunk.token->id);
        continue;
      }
      if (chunk.text.empty()) continue;
      std::vector<int> chunk_ids;
      auto status = sp.Encode(absl::string_view(chunk.text.data(), chunk.text.size()), &chunk_ids);
      if (!status.ok()) throw Error("tokenizer: SentencePiece encode failed (" + model_file.string() + "): " + status.ToString());
      ids.insert(ids.end(), chunk_ids.begin(), chunk_ids.end());
    }
    return ids;
  }
};

T5Tokenizer::T5Tokenizer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
T5Tokenizer::T5Tokenizer(T5Tokenizer&&) noexcept = default;
T5Tokenizer& T5Tokenizer::operator=(T5Tokenizer&&) noexcept = default;
T5Tokenizer::~T5Tokenizer() = default;

T5Tokenizer T5Tokenizer::load(const fs::path& folder) {
  const fs::path dir = fs::exists(folder / "spiece.model") ? folder : folder / "tokenizer";
  auto impl = std::make_unique<Impl>();
  impl->model_file = dir / "spiece.model";
  if (!fs::exists(impl->model_file))
    throw Error("tokenizer: " + impl->model_file.string() + " not found (expected the T5 SentencePiece model of the "
                "model folder's tokenizer/)");
  const std::string bytes = read_file_bytes(impl->model_file);
  if (bytes.empty()) throw Error("tokenizer: " + impl->model_file.string() + " is empty (corrupt SentencePiece model)");
  auto status = impl->sp.LoadFromSerializedProto(absl::string_view(bytes.data(), bytes.size()));
  if (!status.ok() || impl->sp.GetPieceSize() <= 0)
    throw Error("tokenizer: " + impl->model_file.string() + " is not a valid SentencePiece model: " +
                (status.ok() ? std::string("no pieces") : status.ToString()));

  // tokenizer_config.json: special tokens and added tokens (optional; T5 defaults otherwise).
  std::string eos_token = "</s>", pad_token = "<pad>", unk_token = "<unk>";
  int extra_ids = 0;
  bool have_added_decoder = false;
  const fs::path config_file = dir / "tokenizer_config.json";
  if (fs::exists(config_file)) {
    nlohmann::json cfg;
    try {
      cfg = nlohmann::json::parse(read_file_bytes(config_file));
      auto token_text = [](const nlohmann::json& v) {
        return v.is_object() ? v.at("content").get<std::string>() : v.get<std::string>();
      };
      if (cfg.contains("eos_token") && !cfg["eos_token"].is_null()) eos_token = token_text(cfg["eos_token"]);
      if (cfg.contains("pad_token") && !cfg["pad_token"].is_null()) pad_token = token_text(cfg["pad_token"]);
      if (cfg.contains("unk_token") && !cfg["unk_token"].is_null()) unk_token = token_text(cfg["unk_token"]);
      if (cfg.contains("extra_ids")) extra_ids = cfg["extra_ids"].get<int>();
      if (cfg.contains("added_tokens_decoder") && cfg["added_tokens_decoder"].is_object()) {
        have_added_decoder = true;
        for (const auto& [key, v] : cfg["added_tokens_decoder"].items()) {
          AddedToken t;
          t.id = std::stoi(key);
          t.content = v.at("content").get<std::string>();
          t.lstrip = v.value("lstrip", false);
          t.rstrip = v.value("rstrip", false);
          impl->added.push_back(std::move(t));
        }
      }
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {
      throw Error("tokenizer: " + config_file.string() + " is not a valid tokenizer config: " + e.what());
    }
  }
  const int sp_size = impl->sp.GetPieceSize();
  if (!have_added_decoder) {
    // What T5Tokenizer.__init__ builds without added_tokens_decoder: the special tokens, and
    // <extra_id_i> at id sp_size + extra_ids - 1 - i, stripping both sides.
    for (const std::string& s : {pad_token, eos_token, unk_token}) {
      int id = impl->sp.PieceToId(s);
      if (id != impl->sp.unk_id() || s == unk_token) impl->added.push_back({s, id, false, false});
    }
    for (int i = 0; i < extra_ids; ++i)
      impl->added.push_back({"<extra_id_" + std::to_string(i) + ">", sp_size + extra_ids - 1 - i, true, true});
  }
  std::stable_sort(impl->added.begin(), impl->added.end(),
                   [](const AddedToken& a, const AddedToken& b) { return a.content.size() > b.content.size(); });
  impl->size = sp_size;
  for (const auto& a : impl->added) impl->size = std::max(impl->size, a.id + 1);

  auto resolve = [&](const std::string& token, const char* what) {
    int id = impl->token_id(token);
    if (id < 0 || (id == impl->sp.unk_id() && token != unk_token))
      throw Error("tokenizer: " + impl->model_file.string() + " has no " + what + " token '" + token + "'");
    return id;
  };
  impl->eos = resolve(eos_token, "end-of-sequence");
  impl->pad = resolve(pad_token, "padding");
  impl->unk = resolve(unk_token, "unknown");
  return T5Tokenizer(std::move(impl));
}

std::vector<int32_t> T5Tokenizer::encode(std::string_view text) const {
  std::vector<int32_t> ids = impl_->pieces(text);
  if (ids.empty() || ids.back() != impl_->eos) ids.push_back(impl_->eos);
  return ids;
}

std::vector<int32_t> T5Tokenizer::encode_padded(std::string_view text, int max_length) const {
  if (max_length < 1) throw Error("tokenizer: max_length must be >= 1 (got " + std::to_string(max_length) + ")");
  std::vector<int32_t> ids = impl_->pieces(text);
  // Room for the one special token T5 adds (num_special_tokens_to_add = 1).
  if (ids.size() > size_t(max_length - 1)) ids.resize(size_t(max_length - 1));
  if (ids.empty() || ids.back() != impl_->eos) ids.push_back(impl_->eos);
  ids.resize(size_t(max_length), impl_->pad);
  return ids;
}

int T5Tokenizer::pad_id() const { return impl_->pad; }
int T5Tokenizer::eos_id() const { return impl_->eos; }
int T5Tokenizer::unk_id() const { return impl_->unk; }
int T5Tokenizer::vocab_size() const { return impl_->size; }
const fs::path& T5Tokenizer::model_file() const { return impl_->model_file; }

std::string T5Tokenizer::id_to_piece(int id) const {
  for (const auto& a : impl_->added)
    if (a.id == id) return a.content;
  if (id < 0 || id >= impl_->sp.GetPieceSize())
    throw Error("tokenizer: id " + std::to_string(id) + " is outside the vocabulary of " + impl_->model_file.string());
  return impl_->sp.IdToPiece(id);
}

int max_text_seq_length(const fs::path& model_folder) {
  const fs::path file = model_folder / "transformer" / "config.json";
  if (!fs::exists(file)) throw Error("config: " + file.string() + " not found");
  try {
    auto cfg = nlohmann::json::parse(read_file_bytes(file));
    int n = cfg.value("max_text_seq_length", 226);
    if (n < 1) throw Error("config: " + file.string() + ": max_text_seq_length must be >= 1");
    return n;
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error("config: " + file.string() + " is not valid JSON: " + e.what());
  }
}

}  // namespace dvs
