#include "io/pth_file.hpp"

#include <zip.h>

#include <algorithm>
#include <cstring>

#include "dvs/error.hpp"
#include "io/pickle_state_dict.hpp"
#include "io/safetensors.hpp"

namespace dvs {

namespace {

constexpr uint64_t kMaxPickleBytes = uint64_t(1) << 26;  // a vitl state_dict pickle is ~100 KB

bool mul_ok(uint64_t a, uint64_t b, uint64_t& out) { return !__builtin_mul_overflow(a, b, &out); }
bool add_ok(uint64_t a, uint64_t b, uint64_t& out) { return !__builtin_add_overflow(a, b, &out); }

std::string zip_open_error(int code) {
  zip_error_t e;
  zip_error_init_with_code(&e, code);
  std::string msg = zip_error_strerror(&e);
  zip_error_fini(&e);
  return msg;
}

}  // namespace

PthFile::PthFile(PthFile&& o) noexcept { *this = std::move(o); }

PthFile& PthFile::operator=(PthFile&& o) noexcept {
  if (this != &o) {
    if (zip_) zip_discard(zip_);
    path_ = std::move(o.path_);
    zip_ = o.zip_;
    o.zip_ = nullptr;
    prefix_ = std::move(o.prefix_);
    unwrapped_ = std::move(o.unwrapped_);
    stripped_module_ = o.stripped_module_;
    tensors_ = std::move(o.tensors_);
    index_ = std::move(o.index_);
    records_ = std::move(o.records_);
  }
  return *this;
}

PthFile::~PthFile() {
  if (zip_) zip_discard(zip_);
}

const PthTensorInfo* PthFile::find(std::string_view name) const {
  auto it = index_.find(std::string(name));
  return it == index_.end() ? nullptr : &tensors_[it->second];
}

uint64_t PthFile::total_bytes() const {
  uint64_t n = 0;
  for (const auto& t : tensors_) n += t.nbytes();
  return n;
}

// The whole record (so libzip verifies its CRC), refusing one whose size differs from what open() saw.
std::vector<uint8_t> PthFile::read_record(const std::string& name, uint64_t expected_size) const {
  const std::string file = path_.string();
  const zip_int64_t idx = zip_name_locate(zip_, name.c_str(), 0);
  if (idx < 0) throw Error(file + ": record " + name + " is missing");
  std::vector<uint8_t> bytes(static_cast<size_t>(expected_size));
  zip_file_t* f = zip_fopen_index(zip_, zip_uint64_t(idx), 0);
  if (!f) throw Error(file + ": cannot open record " + name + ": " + zip_strerror(zip_));
  zip_int64_t got = expected_size ? zip_fread(f, bytes.data(), bytes.size()) : 0;
  uint8_t extra = 0;
  // Reading to the end is what makes libzip compare the CRC.
  const zip_int64_t more = got >= 0 && zip_uint64_t(got) == expected_size ? zip_fread(f, &extra, 1) : 0;
  const std::string ferr = (got < 0 || more < 0) ? zip_file_strerror(f) : "";
  zip_fclose(f);
  if (got < 0 || more < 0 || zip_uint64_t(got) != expected_size || more != 0)
    throw Error(file + ": record " + name + " is truncated or corrupt" + (ferr.empty() ? "" : ": " + ferr));
  return bytes;
}

PthFile PthFile::open(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::error_code ec;
  const uint64_t file_size = std::filesystem::file_size(path, ec);
  if (ec) throw Error(file + ": cannot read: " + ec.message());
  int code = 0;
  zip_t* za = zip_open(file.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &code);
  if (!za)
    throw Error(file + ": not a readable PyTorch checkpoint (zip archive): " + zip_open_error(code) +
                " (a truncated download, or a pre-1.6 legacy torch.save file, which dvs does not read: re-save it "
                "with a current torch)");
  PthFile f;
  f.path_ = path;
  f.zip_ = za;

  // The one data.pkl decides the record prefix.
  const zip_int64_t n = zip_get_num_entries(za, 0);
  std::vector<std::string> pickles;
  for (zip_int64_t i = 0; i < n; ++i) {
    const char* nm = zip_get_name(za, zip_uint64_t(i), 0);
    if (!nm) throw Error(file + ": zip entry " + std::to_string(i) + " has no readable name: " + zip_strerror(za));
    const std::string s = nm;
    if (s == "data.pkl" || (s.size() > 9 && s.compare(s.size() - 9, 9, "/data.pkl") == 0)) pickles.push_back(s);
  }
  if (pickles.empty())
    throw Error(file + ": no data.pkl record in the zip archive: not a torch.save checkpoint (" + std::to_string(n) +
                " entries)");
  if (pickles.size() > 1)
    throw Error(file + ": " + std::to_string(pickles.size()) + " data.pkl records (" + pickles[0] + ", " + pickles[1] +
                "): ambiguous checkpoint");
  f.prefix_ = pickles[0].substr(0, pickles[0].size() - 8);

  // Sizes of every record, bounded by the file so a lying directory cannot make us allocate terabytes.
  auto stat_record = [&](const std::string& name, zip_int64_t idx) -> Record {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(za, zip_uint64_t(idx), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE) ||
        !(st.valid & ZIP_STAT_COMP_SIZE))
      throw Error(file + ": cannot read the size of record " + name + ": " + zip_strerror(za));
    if (st.comp_size > file_size || st.size / 1100 > st.comp_size + 1)
      throw Error(file + ": record " + name + " claims " + std::to_string(st.size) + " bytes (" +
                  std::to_string(st.comp_size) + " compressed) in a " + std::to_string(file_size) +
                  "-byte file: corrupt archive");
    return Record{uint64_t(idx), st.size};
  };

  const zip_int64_t bo = zip_name_locate(za, (f.prefix_ + "byteorder").c_str(), 0);
  if (bo >= 0) {
    const Record r = stat_record(f.prefix_ + "byteorder", bo);
    if (r.size > 16) throw Error(file + ": record " + f.prefix_ + "byteorder is " + std::to_string(r.size) + " bytes");
    const auto b = f.read_record(f.prefix_ + "byteorder", r.size);
    const std::string order(b.begin(), b.end());
    if (order != "little")
      throw Error(file + ": storages are stored '" + order + "'-endian; dvs reads only little-endian checkpoints");
  }

  const Record pk = stat_record(pickles[0], zip_name_locate(za, pickles[0].c_str(), 0));
  if (pk.size > kMaxPickleBytes)
    throw Error(file + ": " + pickles[0] + " is " + std::to_string(pk.size) + " bytes, too large for a state_dict pickle");
  const std::vector<uint8_t> pickle = f.read_record(pickles[0], pk.size);
  PickledStateDict sd = parse_state_dict_pickle(pickle, file);
  f.unwrapped_ = sd.unwrapped;
  f.stripped_module_ = sd.stripped_module_prefix;

  std::unordered_map<std::string, const TorchStorageType*> storage_types;
  for (auto& p : sd.tensors) {
    const std::string where = file + ": tensor '" + p.name + "'";
    const std::string record = f.prefix_ + "data/" + p.storage_key;
    PthTensorInfo t;
    t.name = p.name;
    t.dtype_name = p.storage_type->dtype_name;
    t.dtype = safetensors_engine_dtype(t.dtype_name);  // the dtype names are safetensors'
    t.elem_size = p.storage_type->elem_size;
    t.shape = p.shape;
    t.strides = p.strides;
    t.storage_key = p.storage_key;
    t.storage_offset = p.storage_offset;

    // The storage record: present, and exactly as large as the pickle declares.
    auto [st_it, fresh] = storage_types.emplace(p.storage_key, p.storage_type);
    if (!fresh && st_it->second != p.storage_type)
      throw Error(where + ": storage " + p.storage_key + " is declared both " + st_it->second->torch_name + " and " +
                  p.storage_type->torch_name);
    auto rec = f.records_.find(p.storage_key);
    if (rec == f.records_.end()) {
      const zip_int64_t idx = zip_name_locate(za, record.c_str(), 0);
      if (idx < 0) throw Error(where + ": its storage record " + record + " is missing from the archive");
      rec = f.records_.emplace(p.storage_key, stat_record(record, idx)).first;
    }
    uint64_t storage_bytes = 0;
    if (!mul_ok(p.storage_numel, t.elem_size, storage_bytes) || storage_bytes != rec->second.size)
      throw Error(where + ": storage record " + record + " holds " + std::to_string(rec->second.size) +
                  " bytes but the pickle declares " + std::to_string(p.storage_numel) + " elements of " +
                  std::to_string(t.elem_size) + " bytes");

    // numel, the last element addressed, and the bytes, all overflow-checked.
    uint64_t numel = 1, last = uint64_t(p.storage_offset);
    for (size_t d = 0; d < t.shape.size(); ++d) {
      uint64_t span = 0;
      if (!mul_ok(numel, uint64_t(t.shape[d]), numel) ||
          (t.shape[d] > 0 && (!mul_ok(uint64_t(t.shape[d] - 1), uint64_t(t.strides[d]), span) || !add_ok(last, span, last))))
        throw Error(where + ": size " + shape_str(t.shape) + " with stride " + shape_str(t.strides) +
                    " overflows 64-bit arithmetic: corrupt checkpoint");
    }
    t.numel = numel;
    uint64_t nbytes = 0;
    if (!mul_ok(numel, t.elem_size, nbytes)) throw Error(where + ": size " + shape_str(t.shape) + " overflows");
    if (numel > 0 && last >= p.storage_numel)
      throw Error(where + ": out of bounds of its storage " + record + ": offset " + std::to_string(p.storage_offset) +
                  ", size " + shape_str(t.shape) + ", stride " + shape_str(t.strides) + " reach element " +
                  std::to_string(last) + " of " + std::to_string(p.storage_numel));
    if (numel > p.storage_numel)
      throw Error(where + ": " + std::to_string(numel) + " elements from a storage of " + std::to_string(p.storage_numel) +
                  " (an expanded view that repeats elements); dvs reads only tensors that do not repeat storage "
                  "elements: save a .contiguous() copy");
    int64_t expect = 1;
    for (size_t d = t.shape.size(); d-- > 0;) {
      if (t.shape[d] != 1 && t.strides[d] != expect) t.contiguous = false;
      expect *= t.shape[d];
    }
    if (numel == 0) t.contiguous = true;
    // Distinct indices must address distinct elements for a gather to be a faithful copy; a strided tensor whose
    // strides make two indices collide (e.g. stride 0 on a size > 1 axis) is refused.
    if (!t.contiguous) {
      std::vector<std::pair<int64_t, int64_t>> axes;  // (stride, size) of axes with size > 1
      for (size_t d = 0; d < t.shape.size(); ++d)
        if (t.shape[d] > 1) axes.emplace_back(t.strides[d], t.shape[d]);
      std::sort(axes.begin(), axes.end());
      int64_t reach = 1;  // every axis must step over the whole extent of the smaller ones
      for (const auto& [stride, size] : axes) {
        if (stride < reach)
          throw Error(where + ": stride " + shape_str(t.strides) + " makes elements of size " + shape_str(t.shape) +
                      " overlap; dvs reads only non-overlapping tensors: save a .contiguous() copy");
        reach = stride * size;  // bounded: stride*(size-1) <= last < storage_numel was checked
      }
    }
    if (!f.index_.emplace(t.name, f.tensors_.size()).second) throw Error(where + ": duplicate tensor name");
    f.tensors_.push_back(std::move(t));
  }
  return f;
}

std::vector<uint8_t> PthFile::read_bytes(const PthTensorInfo& t) const {
  const auto rec = records_.find(t.storage_key);
  if (rec == records_.end()) throw Error(path_.string() + ": tensor '" + t.name + "' is not from this file");
  const std::vector<uint8_t> storage = read_record(prefix_ + "data/" + t.storage_key, rec->second.size);
  const size_t es = t.elem_size;
  std::vector<uint8_t> out(size_t(t.nbytes()));
  if (t.numel == 0) return out;
  if (t.contiguous) {
    std::memcpy(out.data(), storage.data() + size_t(t.storage_offset) * es, out.size());
    return out;
  }
  // Gather, last axis fastest; bounds were proven by open().
  const size_t rank = t.shape.size();
  std::vector<int64_t> idx(rank, 0);
  for (uint64_t i = 0; i < t.numel; ++i) {
    int64_t e = t.storage_offset;
    for (size_t d = 0; d < rank; ++d) e += idx[d] * t.strides[d];
    std::memcpy(out.data() + i * es, storage.data() + size_t(e) * es, es);
    for (size_t d = rank; d-- > 0;) {
      if (++idx[d] < t.shape[d]) break;
      idx[d] = 0;
    }
  }
  return out;
}

std::vector<const WeightEntry*> PthFile::entries() const { return entry_list(tensors_); }

TensorBytes PthFile::bytes(const WeightEntry& entry) const {
  return TensorBytes(read_bytes(own_entry(find(entry.name), entry)));
}

HostTensor PthFile::load(const WeightEntry& entry) const {
  const PthTensorInfo& t = own_entry(find(entry.name), entry);
  if (!t.dtype)
    throw Error(path_.string() + ": tensor '" + t.name + "' is " + t.dtype_name +
                "; the engine reads only F32, F16, BF16, I32 and U8 tensors");
  HostTensor h;
  h.shape = t.shape;
  h.dtype = *t.dtype;
  h.data = read_bytes(t);
  return h;
}

}  // namespace dvs
