#pragma once
// Sparse storage of SCM grid vertices: an open-addressing hash index from the packed vertex key
// (i, j) to a dense vector of records. Records are never erased (only clear()), so an index into
// the record vector stays valid until the next insertion that grows the vector.
#include <cstdint>
#include <vector>

namespace syndds::scm {

/// Packs signed grid indices into one 64-bit key (i in the high word).
inline std::uint64_t vertex_key(std::int32_t i, std::int32_t j) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(i)) << 32) |
         static_cast<std::uint32_t>(j);
}
inline std::int32_t key_i(std::uint64_t key) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(key >> 32));
}
inline std::int32_t key_j(std::uint64_t key) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(key & 0xffffffffULL));
}

/// Open-addressing (linear probing) map from vertex key to a 32-bit index. No erase.
class KeyIndexMap {
 public:
  static constexpr std::int32_t kNone = -1;

  KeyIndexMap() { rehash(64); }

  std::int32_t find(std::uint64_t key) const {
    std::size_t slot = mix(key) & mask_;
    while (true) {
      const Slot& s = slots_[slot];
      if (s.value == kNone) return kNone;
      if (s.key == key) return s.value;
      slot = (slot + 1) & mask_;
    }
  }

  /// Inserts key -> value if absent; returns the stored value (existing or new).
  std::int32_t insert(std::uint64_t key, std::int32_t value) {
    if ((size_ + 1) * 4 > slots_.size() * 3) rehash(slots_.size() * 2);
    std::size_t slot = mix(key) & mask_;
    while (true) {
      Slot& s = slots_[slot];
      if (s.value == kNone) {
        s.key = key;
        s.value = value;
        ++size_;
        return value;
      }
      if (s.key == key) return s.value;
      slot = (slot + 1) & mask_;
    }
  }

  std::size_t size() const { return size_; }

  /// Calls fn(key, value) for every entry, in slot order (which depends on the insertion
  /// history: callers that need a stable order sort what they collect).
  template <class Fn>
  void for_each(Fn&& fn) const {
    for (const auto& s : slots_) {
      if (s.value != kNone) fn(s.key, s.value);
    }
  }

  void clear() {
    if (size_ == 0) return;
    for (auto& s : slots_) s.value = kNone;
    size_ = 0;
  }

 private:
  struct Slot {
    std::uint64_t key = 0;
    std::int32_t value = kNone;
  };

  static std::size_t mix(std::uint64_t x) {  // splitmix64 finaliser
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return static_cast<std::size_t>(x);
  }

  void rehash(std::size_t capacity) {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(capacity, Slot{});
    mask_ = capacity - 1;
    size_ = 0;
    for (const auto& s : old) {
      if (s.value != kNone) insert(s.key, s.value);
    }
  }

  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

}  // namespace syndds::scm
