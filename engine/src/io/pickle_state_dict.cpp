#include "io/pickle_state_dict.hpp"

#include <array>
#include <cstdio>
#include <deque>
#include <unordered_map>
#include <unordered_set>

#include "dvs/error.hpp"

namespace dvs {

const TorchStorageType* torch_storage_type(std::string_view name) {
  static const std::array<TorchStorageType, 10> kTypes{{
      {"FloatStorage", "F32", 4},
      {"HalfStorage", "F16", 2},
      {"BFloat16Storage", "BF16", 2},
      {"DoubleStorage", "F64", 8},
      {"LongStorage", "I64", 8},
      {"IntStorage", "I32", 4},
      {"ShortStorage", "I16", 2},
      {"CharStorage", "I8", 1},
      {"ByteStorage", "U8", 1},
      {"BoolStorage", "BOOL", 1},
  }};
  for (const auto& t : kTypes)
    if (t.torch_name == name) return &t;
  return nullptr;
}

namespace {

// The values a state_dict pickle can build. Nodes live in an arena owned by the parser, so memo
// references and even cyclic containers (a crafted file can make them) need no reference counting.
struct Node {
  enum Kind { None, Bool, Int, Str, Tuple, Dict, Global, Storage, Tensor } kind = None;
  int64_t i = 0;                                // Bool, Int
  std::string s;                                // Str; Storage key
  std::vector<Node*> items;                     // Tuple
  std::vector<std::pair<Node*, Node*>> entries; // Dict, in insertion order
  std::unordered_set<std::string> str_keys;     // Dict: its str keys, to refuse duplicates in O(1)
  enum GlobalKind { OrderedDict, RebuildTensorV2, StorageClass } global = OrderedDict;
  const TorchStorageType* storage_type = nullptr;  // Global StorageClass, Storage
  std::string location;                          // Storage
  uint64_t numel = 0;                            // Storage
  const Node* storage = nullptr;                 // Tensor
  int64_t offset = 0;                            // Tensor
  Shape shape, strides;                          // Tensor
};

const char* kind_name(Node::Kind k) {
  switch (k) {
    case Node::None: return "None";
    case Node::Bool: return "bool";
    case Node::Int: return "int";
    case Node::Str: return "str";
    case Node::Tuple: return "tuple";
    case Node::Dict: return "dict";
    case Node::Global: return "global";
    case Node::Storage: return "storage";
    case Node::Tensor: return "tensor";
  }
  return "?";
}

std::string opcode_text(uint8_t op) {
  char buf[32];
  if (op >= 0x20 && op < 0x7f) std::snprintf(buf, sizeof buf, "0x%02x ('%c')", op, op);
  else std::snprintf(buf, sizeof buf, "0x%02x", op);
  return buf;
}

constexpr size_t kMaxObjects = size_t(1) << 19;

class Parser {
 public:
  Parser(std::span<const uint8_t> p, const std::string& file) : p_(p), file_(file) {}

  Node* run() {
    for (;;) {
      op_pos_ = pos_;
      const uint8_t op = byte();
      switch (op) {
        case 0x80: {  // PROTO
          const uint8_t v = byte();
          if (v < 2 || v > 5) fail("pickle protocol " + std::to_string(v) + " (torch.save writes protocol 2)");
          break;
        }
        case '}': push(make(Node::Dict)); break;  // EMPTY_DICT
        case ')': push(make(Node::Tuple)); break;  // EMPTY_TUPLE
        case 'N': push(make(Node::None)); break;   // NONE
        case 0x88: push_int(Node::Bool, 1); break;  // NEWTRUE
        case 0x89: push_int(Node::Bool, 0); break;  // NEWFALSE
        case 'K': push_int(Node::Int, byte()); break;  // BININT1
        case 'M': push_int(Node::Int, int64_t(uint_le(2))); break;  // BININT2
        case 'J': push_int(Node::Int, int64_t(int32_t(uint32_t(uint_le(4))))); break;  // BININT
        case 0x8a: long1(); break;
        case 'X': {  // BINUNICODE
          const uint64_t n = uint_le(4);
          Node* s = make(Node::Str);
          s->s = std::string(reinterpret_cast<const char*>(take(n)), size_t(n));
          push(s);
          break;
        }
        case '(': marks_.push_back(stack_.size()); break;  // MARK
        case 't': {  // TUPLE
          const size_t m = pop_mark();
          Node* t = make(Node::Tuple);
          t->items.assign(stack_.begin() + std::ptrdiff_t(m), stack_.end());
          stack_.resize(m);
          push(t);
          break;
        }
        case 0x85: case 0x86: case 0x87: {  // TUPLE1..3
          const size_t n = size_t(op - 0x84);
          need(n);
          Node* t = make(Node::Tuple);
          t->items.assign(stack_.end() - std::ptrdiff_t(n), stack_.end());
          stack_.resize(stack_.size() - n);
          push(t);
          break;
        }
        case 'q': memo_put(byte()); break;          // BINPUT
        case 'r': memo_put(uint_le(4)); break;      // LONG_BINPUT
        case 'h': memo_get(byte()); break;          // BINGET
        case 'j': memo_get(uint_le(4)); break;      // LONG_BINGET
        case 'c': global(); break;
        case 'Q': persistent_id(); break;           // BINPERSID
        case 'R': reduce(); break;
        case 's': {  // SETITEM
          need(3);
          Node* v = pop();
          Node* k = pop();
          set_item(top(), k, v);
          break;
        }
        case 'u': {  // SETITEMS
          const size_t m = pop_mark();
          if ((stack_.size() - m) % 2) fail("SETITEMS with an odd number of items (a key without a value)");
          if (m == 0 || (!marks_.empty() && m - 1 < marks_.back()))
            fail("stack underflow: SETITEMS without a dict below its mark");
          Node* d = stack_[m - 1];
          for (size_t i = m; i < stack_.size(); i += 2) set_item(d, stack_[i], stack_[i + 1]);
          stack_.resize(m);
          break;
        }
        case 'b': {  // BUILD: only the `_metadata` attribute torch.save puts on a state_dict
          need(2);
          Node* state = pop();
          Node* obj = top();
          if (obj->kind != Node::Dict || state->kind != Node::Dict)
            fail(std::string("BUILD on a ") + kind_name(obj->kind) + " with a " + kind_name(state->kind) +
                 " state (only a state_dict's metadata dict is accepted)");
          break;  // metadata (module versions) is not needed: ignored
        }
        case '.': {  // STOP
          need(1);
          if (stack_.size() != 1) fail("STOP with " + std::to_string(stack_.size()) + " values on the stack (expected 1)");
          if (!marks_.empty()) fail("STOP with an unclosed MARK");
          return stack_.back();
        }
        default:
          fail("unsupported pickle opcode " + opcode_text(op) +
               "; a state_dict pickle needs only the protocol-2 opcodes torch.save writes");
      }
    }
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw Error(file_ + ": data.pkl byte " + std::to_string(op_pos_) + ": " + what +
                " (not a plain torch state_dict, or a corrupt file)");
  }

 private:
  uint8_t byte() { return *take(1); }

  const uint8_t* take(uint64_t n) {
    if (n > p_.size() - pos_) fail("truncated pickle: the opcode needs " + std::to_string(n) + " more bytes, " +
                                   std::to_string(p_.size() - pos_) + " left");
    const uint8_t* b = p_.data() + pos_;
    pos_ += size_t(n);
    return b;
  }

  uint64_t uint_le(int n) {
    const uint8_t* b = take(uint64_t(n));
    uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | b[i];
    return v;
  }

  void long1() {  // LONG1: n-byte two's complement little-endian integer
    const uint8_t n = byte();
    if (n > 8) fail("LONG1 integer of " + std::to_string(n) + " bytes does not fit in 64 bits");
    const uint8_t* b = take(n);
    uint64_t v = 0;
    for (int i = int(n) - 1; i >= 0; --i) v = (v << 8) | b[i];
    if (n > 0 && n < 8 && (b[n - 1] & 0x80)) v |= ~uint64_t(0) << (8 * n);  // sign-extend
    push_int(Node::Int, int64_t(v));
  }

  Node* make(Node::Kind k) {
    // A state_dict builds ~10 objects per tensor and ~5 per module; this bounds the memory a crafted pickle of
    // tiny opcodes can claim (each node is a few hundred bytes).
    if (arena_.size() >= kMaxObjects)
      fail("the pickle builds more than " + std::to_string(kMaxObjects) + " objects; not a plausible state_dict");
    arena_.emplace_back();
    arena_.back().kind = k;
    return &arena_.back();
  }
  void push(Node* n) { stack_.push_back(n); }
  void push_int(Node::Kind k, int64_t v) {
    Node* n = make(k);
    n->i = v;
    push(n);
  }
  void need(size_t n) {
    const size_t floor = marks_.empty() ? 0 : marks_.back();
    if (stack_.size() < floor + n) fail("stack underflow: the opcode needs " + std::to_string(n) + " value(s)");
  }
  Node* pop() {
    need(1);
    Node* n = stack_.back();
    stack_.pop_back();
    return n;
  }
  Node* top() {
    need(1);
    return stack_.back();
  }
  size_t pop_mark() {
    if (marks_.empty()) fail("stack underflow: no MARK to close");
    const size_t m = marks_.back();
    marks_.pop_back();
    return m;
  }
  void memo_put(uint64_t k) { memo_[k] = top(); }
  void memo_get(uint64_t k) {
    auto it = memo_.find(k);
    if (it == memo_.end()) fail("memo key " + std::to_string(k) + " read before it was written");
    push(it->second);
  }

  void set_item(Node* d, Node* k, Node* v) {
    if (d->kind != Node::Dict) fail(std::string("SETITEM(S) on a ") + kind_name(d->kind) + ", not a dict");
    if (k->kind == Node::Str && !d->str_keys.insert(k->s).second) fail("duplicate key '" + k->s + "'");
    d->entries.emplace_back(k, v);
  }

  std::string line() {  // GLOBAL's newline-terminated arguments
    std::string s;
    for (;;) {
      const uint8_t c = byte();
      if (c == '\n') return s;
      if (s.size() > 200) fail("GLOBAL name longer than 200 bytes");
      s.push_back(char(c));
    }
  }

  void global() {
    const std::string module = line(), name = line();
    Node* g = make(Node::Global);
    if (module == "collections" && name == "OrderedDict") g->global = Node::OrderedDict;
    else if (module == "torch._utils" && name == "_rebuild_tensor_v2") g->global = Node::RebuildTensorV2;
    else if (module == "torch" && torch_storage_type(name)) {
      g->global = Node::StorageClass;
      g->storage_type = torch_storage_type(name);
    } else {
      fail("global '" + module + "." + name +
           "' is not allowed (only collections.OrderedDict, torch._utils._rebuild_tensor_v2 and torch.<T>Storage); "
           "dvs never imports or runs anything from a checkpoint");
    }
    push(g);
  }

  int64_t int_arg(const Node* n, const std::string& what) {
    if (n->kind != Node::Int) fail(what + " is a " + kind_name(n->kind) + ", not an int");
    return n->i;
  }
  const std::string& str_arg(const Node* n, const std::string& what) {
    if (n->kind != Node::Str) fail(what + " is a " + kind_name(n->kind) + ", not a str");
    return n->s;
  }
  Shape int_tuple(const Node* n, const std::string& what) {
    if (n->kind != Node::Tuple) fail(what + " is a " + kind_name(n->kind) + ", not a tuple");
    if (n->items.size() > 16) fail(what + " has " + std::to_string(n->items.size()) + " dimensions (at most 16)");
    Shape s;
    for (const Node* x : n->items) {
      const int64_t v = int_arg(x, what + " entry");
      if (v < 0) fail(what + " has a negative entry " + std::to_string(v));
      s.push_back(v);
    }
    return s;
  }

  // BINPERSID: ('storage', torch.<T>Storage, key, location, numel) -> a storage reference.
  void persistent_id() {
    const Node* pid = pop();
    if (pid->kind != Node::Tuple || pid->items.size() != 5)
      fail("persistent id is not a 5-tuple ('storage', type, key, location, numel)");
    if (str_arg(pid->items[0], "persistent id tag") != "storage")
      fail("persistent id tag '" + pid->items[0]->s + "' (only 'storage' is known)");
    const Node* type = pid->items[1];
    if (type->kind != Node::Global || type->global != Node::StorageClass)
      fail("persistent id storage type is not a torch.<T>Storage class");
    Node* s = make(Node::Storage);
    s->storage_type = type->storage_type;
    s->s = str_arg(pid->items[2], "storage key");
    s->location = str_arg(pid->items[3], "storage location");
    const int64_t n = int_arg(pid->items[4], "storage size");
    if (n < 0) fail("storage '" + s->s + "' has a negative size " + std::to_string(n));
    s->numel = uint64_t(n);
    if (s->s.empty() || s->s.find('/') != std::string::npos || s->s.find("..") != std::string::npos)
      fail("storage key '" + s->s + "' is not a plain record name");
    push(s);
  }

  void reduce() {
    need(2);
    const Node* args = pop();
    const Node* fn = pop();
    if (fn->kind != Node::Global) fail(std::string("REDUCE calls a ") + kind_name(fn->kind) + ", not an allowed global");
    if (args->kind != Node::Tuple) fail("REDUCE arguments are not a tuple");
    if (fn->global == Node::OrderedDict) {
      if (!args->items.empty()) fail("OrderedDict called with arguments (a state_dict pickle builds it empty)");
      push(make(Node::Dict));
    } else if (fn->global == Node::RebuildTensorV2) {
      // (storage, storage_offset, size, stride, requires_grad, backward_hooks[, metadata])
      if (args->items.size() != 6 && args->items.size() != 7)
        fail("_rebuild_tensor_v2 takes 6 or 7 arguments, got " + std::to_string(args->items.size()));
      Node* t = make(Node::Tensor);
      if (args->items[0]->kind != Node::Storage) fail("_rebuild_tensor_v2's first argument is not a storage");
      t->storage = args->items[0];
      t->offset = int_arg(args->items[1], "storage offset");
      if (t->offset < 0) fail("negative storage offset " + std::to_string(t->offset));
      t->shape = int_tuple(args->items[2], "tensor size");
      t->strides = int_tuple(args->items[3], "tensor stride");
      if (t->shape.size() != t->strides.size())
        fail("tensor size has " + std::to_string(t->shape.size()) + " dimensions but its stride has " +
             std::to_string(t->strides.size()));
      if (args->items[4]->kind != Node::Bool) fail("requires_grad is not a bool");
      push(t);
    } else {
      fail("a storage class called directly (only through a persistent id)");
    }
  }

  std::span<const uint8_t> p_;
  const std::string& file_;
  size_t pos_ = 0, op_pos_ = 0;
  std::deque<Node> arena_;
  std::vector<Node*> stack_;
  std::vector<size_t> marks_;
  std::unordered_map<uint64_t, Node*> memo_;
};

bool is_tensor_dict(const Node* d) {
  for (const auto& [k, v] : d->entries)
    if (v->kind != Node::Tensor) return false;
  return true;
}

}  // namespace

PickledStateDict parse_state_dict_pickle(std::span<const uint8_t> pickle, const std::string& file) {
  Parser parser(pickle, file);
  const Node* root = parser.run();
  const std::string where = file + ": data.pkl";
  if (root->kind != Node::Dict)
    throw Error(where + ": the pickled object is a " + kind_name(root->kind) + ", not a state_dict (a dict of tensors)");
  PickledStateDict out;
  if (!is_tensor_dict(root)) {  // {"state_dict": {...}, ...} or {"model": {...}, ...} as training scripts save
    for (const char* wrapper : {"state_dict", "model"})
      for (const auto& [k, v] : root->entries)
        if (out.unwrapped.empty() && k->kind == Node::Str && k->s == wrapper && v->kind == Node::Dict) {
          root = v;
          out.unwrapped = wrapper;
        }
  }
  bool all_module = !root->entries.empty();
  for (const auto& [k, v] : root->entries) {
    if (k->kind != Node::Str) throw Error(where + ": a state_dict key is a " + std::string(kind_name(k->kind)) + ", not a str");
    if (v->kind != Node::Tensor)
      throw Error(where + ": entry '" + k->s + "' is a " + kind_name(v->kind) + ", not a tensor" +
                  (out.unwrapped.empty() ? " (and there is no 'state_dict' or 'model' entry holding one)" : ""));
    if (k->s.rfind("module.", 0) != 0) all_module = false;
  }
  std::unordered_set<std::string> seen;
  for (const auto& [k, v] : root->entries) {
    PickledTensor t;
    t.name = all_module ? k->s.substr(7) : k->s;
    if (!seen.insert(t.name).second) throw Error(where + ": duplicate key '" + t.name + "'");
    t.storage_type = v->storage->storage_type;
    t.storage_key = v->storage->s;
    t.storage_location = v->storage->location;
    t.storage_numel = v->storage->numel;
    t.storage_offset = v->offset;
    t.shape = v->shape;
    t.strides = v->strides;
    out.tensors.push_back(std::move(t));
  }
  out.stripped_module_prefix = all_module;
  return out;
}

}  // namespace dvs
