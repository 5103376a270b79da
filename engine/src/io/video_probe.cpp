#include "io/video_probe.hpp"

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <optional>
#include <vector>

#include "dvs/error.hpp"

namespace dvs {
namespace {

constexpr const char* kCopyAgain = "; export or copy it again";

uint64_t be(const uint8_t* p, int n) {
  uint64_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

// One ISO base media box: its four-character type and where its payload lies.
struct Box {
  std::string type;
  uint64_t offset = 0, size = 0, header = 0;  // size includes the header
};

// The box starting at `at` of a buffer of `end` bytes, or nothing when its header does not fit or is malformed.
std::optional<Box> box_at(const uint8_t* data, uint64_t at, uint64_t end) {
  if (end - at < 8) return std::nullopt;
  Box b{std::string(reinterpret_cast<const char*>(data + at + 4), 4), at, be(data + at, 4), 8};
  if (b.size == 1) {
    if (end - at < 16) return std::nullopt;
    b.size = be(data + at + 8, 8), b.header = 16;
  } else if (b.size == 0) {
    b.size = end - at;  // runs to the end of its parent
  }
  if (b.size < b.header) return std::nullopt;
  return b;
}

// The children of a box held in `data` [begin, end).
std::vector<Box> children(const std::vector<uint8_t>& data, uint64_t begin, uint64_t end) {
  std::vector<Box> out;
  for (uint64_t at = begin; at < end;) {
    const auto b = box_at(data.data(), at, end);
    if (!b || b->size > end - at) break;
    out.push_back(*b);
    at += b->size;
  }
  return out;
}

std::string track_kind(const std::string& handler) {
  if (handler == "vide") return "video";
  if (handler == "soun") return "audio";
  if (handler == "text" || handler == "sbtl" || handler == "subt") return "subtitles";
  if (handler == "meta") return "metadata";
  if (handler == "hint") return "hint";
  return "'" + handler + "'";
}

// The handler type ('vide', 'soun', ...) of every track of a 'moov' box's bytes.
std::vector<std::string> track_handlers(const std::vector<uint8_t>& moov) {
  std::vector<std::string> out;
  for (const Box& trak : children(moov, 0, moov.size())) {
    if (trak.type != "trak") continue;
    for (const Box& mdia : children(moov, trak.offset + trak.header, trak.offset + trak.size)) {
      if (mdia.type != "mdia") continue;
      for (const Box& hdlr : children(moov, mdia.offset + mdia.header, mdia.offset + mdia.size))
        if (hdlr.type == "hdlr" && hdlr.size >= hdlr.header + 12)  // version+flags, pre_defined, handler_type
          out.emplace_back(reinterpret_cast<const char*>(moov.data() + hdlr.offset + hdlr.header + 8), 4);
    }
  }
  return out;
}

bool is_top_level_type(const std::string& t) {
  for (const char* k : {"ftyp", "moov", "mdat", "free", "skip", "wide", "pdin", "styp", "uuid", "meta"})
    if (t == k) return true;
  return false;
}

// The problem of an ISO base media file (mp4/mov), "" when it is not one or looks sound.
std::string iso_media_problem(std::ifstream& in, uint64_t file_size) {
  uint8_t head[16];
  std::vector<std::string> types;
  std::optional<std::vector<uint8_t>> moov;
  for (uint64_t at = 0; at < file_size;) {
    const uint64_t n = std::min<uint64_t>(16, file_size - at);
    in.seekg(std::streamoff(at));
    if (!in.read(reinterpret_cast<char*>(head), std::streamsize(n))) return "";
    const auto b = box_at(head, 0, n);
    if (!b) {
      if (types.empty()) return "";
      return "the file is truncated: it ends at byte " + std::to_string(file_size) + ", inside a box header" +
             (moov ? "" : ", and its index ('moov' box) is missing, so no frame can be found") + kCopyAgain;
    }
    if (types.empty() && !is_top_level_type(b->type)) return "";  // not an ISO base media file
    types.push_back(b->type);
    if (b->size > file_size - at)
      return "the file is truncated: it ends at byte " + std::to_string(file_size) + ", inside its '" + b->type +
             "' box of " + std::to_string(b->size) + " bytes that starts at byte " + std::to_string(at) +
             (moov || b->type == "moov" ? "" : ", and its index ('moov' box) is missing, so no frame can be found") +
             kCopyAgain;
    if (b->type == "moov" && b->size <= (uint64_t(64) << 20)) {
      moov.emplace(size_t(b->size - b->header));
      in.seekg(std::streamoff(at + b->header));
      if (!in.read(reinterpret_cast<char*>(moov->data()), std::streamsize(moov->size()))) return "";
    }
    at += b->size;
  }
  if (std::find(types.begin(), types.end(), "moov") == types.end())
    return "its index ('moov' box) is missing, so no frame can be found (a recording that was never finished?)" +
           std::string(kCopyAgain);
  if (!moov) return "";
  const std::vector<std::string> handlers = track_handlers(*moov);
  if (std::find(handlers.begin(), handlers.end(), "vide") != handlers.end()) return "";
  if (handlers.empty()) return "holds no tracks at all" + std::string(kCopyAgain);
  std::string kinds;
  for (const std::string& h : handlers) kinds += (kinds.empty() ? "" : ", ") + track_kind(h);
  return "holds no video stream (its tracks: " + kinds + "): give the video itself";
}

}  // namespace

std::string video_file_problem(const std::filesystem::path& path) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) return "";
  if (size == 0) return "the file is empty (0 bytes): it was not written or copied completely" + std::string(kCopyAgain);
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  return iso_media_problem(in, size);
}

// A video that holds fewer frames than were asked for (--frames). `announced` is the container's own count (0 when
// it does not say); more than were decoded means the file stops early. run needs 4k+1 frames, render and depth
// take any count, so both are suggested.
void throw_too_few_frames(const std::string& name, int have, int wanted, int announced) {
  const int fit = (have - 1) / 4 * 4 + 1;
  std::string why;
  if (announced > have)
    why = " (the file is truncated or damaged: its header announces " + std::to_string(announced) +
          " frames but decoding stops after frame " + std::to_string(have) + ")";
  throw Error(name + ": holds " + std::to_string(have) + " frames, fewer than --frames " + std::to_string(wanted) + why +
              "; use --frames " + std::to_string(fit) + " (the largest 4k+1 it has, as dvs run needs; dvs render and "
              "dvs depth take any count up to " + std::to_string(have) + "), or leave --frames out to use them all");
}

}  // namespace dvs
