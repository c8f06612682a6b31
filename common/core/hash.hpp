#pragma once
// Small, stable (platform-independent) hashes used for fingerprints and determinism checks.
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace syndds {

/// 64-bit FNV-1a, incremental. Stable across runs and machines.
class Fnv1a64 {
 public:
  void add_bytes(const void* data, std::size_t size) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) {
      state_ ^= bytes[i];
      state_ *= 1099511628211ULL;
    }
  }
  void add(std::string_view text) {
    add_bytes(text.data(), text.size());
    add_bytes("\0", 1);
  }
  void add(double value) { add_bytes(&value, sizeof value); }
  void add(std::int64_t value) { add_bytes(&value, sizeof value); }
  std::uint64_t value() const { return state_; }

 private:
  std::uint64_t state_ = 14695981039346656037ULL;
};

/// SplitMix64's finaliser (Steele, Lea and Flood 2014): a well-mixed 64-bit hash of a 64-bit
/// value, for deriving independent seeds from (seed, index) pairs.
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/// A 64-bit value as 16 lower-case hex digits (fingerprints, checksums).
inline std::string hex64(std::uint64_t v) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out(16, '0');
  for (int i = 15; i >= 0; --i, v >>= 4) out[static_cast<std::size_t>(i)] = kDigits[v & 0xf];
  return out;
}

inline std::uint64_t fnv1a64(std::string_view text) {
  Fnv1a64 h;
  h.add_bytes(text.data(), text.size());
  return h.value();
}

}  // namespace syndds
