// A restricted reader for the pickle inside a PyTorch checkpoint (`data.pkl` of a torch.save zip archive),
// that understands exactly what a state_dict needs and nothing else.
//
// It interprets the protocol-2 opcodes torch.save writes for a dict of tensors (PROTO, EMPTY_DICT,
// EMPTY_TUPLE, MARK, BINUNICODE, BININT/BININT1/BININT2, LONG1, GLOBAL, BINPERSID, TUPLE/TUPLE1-3, REDUCE,
// SETITEM(S), BINPUT/LONG_BINPUT, BINGET/LONG_BINGET, NEWTRUE/NEWFALSE, NONE, BUILD, STOP) and only the
// globals collections.OrderedDict, torch._utils._rebuild_tensor_v2 and torch.<T>Storage. Nothing is ever
// imported or executed: a global is a name compared against that list, REDUCE builds one of three known
// values. Any other opcode or global, a malformed argument, a stack underflow or a truncated stream is a
// dvs::Error naming the file, the opcode or global and the byte offset inside data.pkl.
#pragma once
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "io/host_tensor.hpp"

namespace dvs {

// A torch storage class: its dtype, named like safetensors dtypes ("F32", "BF16", "I64", ...).
struct TorchStorageType {
  std::string torch_name;  // "FloatStorage"
  std::string dtype_name;  // "F32"
  size_t elem_size = 0;
};

// The storage class torch.<name>, or nullptr when dvs does not know it.
const TorchStorageType* torch_storage_type(std::string_view name);

// One tensor of the state_dict as the pickle describes it; storages are not read here.
struct PickledTensor {
  std::string name;
  const TorchStorageType* storage_type = nullptr;
  std::string storage_key;       // the record data/<key> inside the archive
  std::string storage_location;  // "cpu", "cuda:0", ...
  uint64_t storage_numel = 0;    // elements of the storage, as the pickle declares it
  int64_t storage_offset = 0;    // in elements
  Shape shape, strides;          // strides in elements
};

struct PickledStateDict {
  std::vector<PickledTensor> tensors;  // in the pickle's (the state_dict's) order
  std::string unwrapped;               // "" or the wrapper key that held the state_dict ("state_dict", "model")
  bool stripped_module_prefix = false; // every key began with "module." (DataParallel) and it was removed
};

// Parses `pickle` (the bytes of data.pkl). `file` names the checkpoint in error messages.
// The top level must be a dict of tensors, or a dict whose "state_dict" or "model" entry is one; a "module."
// prefix shared by every key is removed. Duplicate keys and non-tensor values are errors.
PickledStateDict parse_state_dict_pickle(std::span<const uint8_t> pickle, const std::string& file);

}  // namespace dvs
