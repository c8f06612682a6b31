#include "protocol/vertex_codec.hpp"

#include <bit>
#include <limits>
#include <string>

#include "core/error.hpp"

namespace syndds::proto {
namespace {

constexpr int kFields = 4;
// The smallest a vertex can be: two one-byte varints and the two length bytes.
constexpr std::size_t kMinVertexBytes = 4;

double TerrainVertexMsg::*const kDoubles[kFields] = {
    &TerrainVertexMsg::height, &TerrainVertexMsg::level_initial,
    &TerrainVertexMsg::sinkage_plastic, &TerrainVertexMsg::sigma_yield};

// Where encoded bytes go: into a vector, or only counted (packed_size).
struct ByteCounter {
  std::size_t size = 0;
  void push_back(std::uint8_t) { ++size; }
};

template <typename Out>
void put_varint(Out& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<std::uint8_t>(v | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<std::uint8_t>(v));
}

std::uint64_t zigzag(std::int64_t v) {
  return (static_cast<std::uint64_t>(v) << 1) ^ static_cast<std::uint64_t>(v >> 63);
}
std::int64_t unzigzag(std::uint64_t v) {
  return static_cast<std::int64_t>(v >> 1) ^ -static_cast<std::int64_t>(v & 1);
}

// Bytes needed for the significant low part of x (0 for 0).
int significant_bytes(std::uint64_t x) { return (64 - std::countl_zero(x) + 7) / 8; }

class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}
  std::size_t position() const { return pos_; }
  std::size_t left() const { return bytes_.size() - pos_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw ProtocolError("packed vertices: " + what + " at byte " + std::to_string(pos_) + " of " +
                        std::to_string(bytes_.size()));
  }
  std::uint8_t byte() {
    if (pos_ >= bytes_.size()) fail("truncated list");
    return bytes_[pos_++];
  }
  std::uint64_t varint() {
    std::uint64_t v = 0;
    for (int shift = 0; shift < 70; shift += 7) {
      const std::uint8_t b = byte();
      if (shift == 63 && b > 1) fail("varint overflows 64 bits");
      v |= static_cast<std::uint64_t>(b & 0x7f) << shift;
      if (!(b & 0x80)) return v;
    }
    fail("varint longer than 10 bytes");
  }
  std::uint64_t low_bytes(int n) {
    if (left() < static_cast<std::size_t>(n)) fail("truncated list");
    std::uint64_t v = 0;
    for (int k = 0; k < n; ++k) v |= static_cast<std::uint64_t>(bytes_[pos_ + k]) << (8 * k);
    pos_ += static_cast<std::size_t>(n);
    return v;
  }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 0;
};

std::int32_t next_index(Reader& in, std::int32_t previous, const char* name) {
  const std::int64_t v = static_cast<std::int64_t>(previous) + unzigzag(in.varint());
  if (v < std::numeric_limits<std::int32_t>::min() || v > std::numeric_limits<std::int32_t>::max()) {
    in.fail(std::string("vertex index ") + name + " outside int32");
  }
  return static_cast<std::int32_t>(v);
}

}  // namespace

namespace {

template <typename Out>
void encode(const std::vector<TerrainVertexMsg>& vertices, Out& out) {
  put_varint(out, vertices.size());
  TerrainVertexMsg prev;
  for (const TerrainVertexMsg& v : vertices) {
    put_varint(out, zigzag(static_cast<std::int64_t>(v.i) - prev.i));
    put_varint(out, zigzag(static_cast<std::int64_t>(v.j) - prev.j));
    std::uint64_t x[kFields];
    int n[kFields];
    for (int f = 0; f < kFields; ++f) {
      x[f] = std::bit_cast<std::uint64_t>(v.*kDoubles[f]) ^
             std::bit_cast<std::uint64_t>(prev.*kDoubles[f]);
      n[f] = significant_bytes(x[f]);
    }
    out.push_back(static_cast<std::uint8_t>(n[0] | (n[1] << 4)));
    out.push_back(static_cast<std::uint8_t>(n[2] | (n[3] << 4)));
    for (int f = 0; f < kFields; ++f) {
      for (int k = 0; k < n[f]; ++k) out.push_back(static_cast<std::uint8_t>(x[f] >> (8 * k)));
    }
    prev = v;
  }
}

}  // namespace

std::vector<std::uint8_t> pack_vertices(const std::vector<TerrainVertexMsg>& vertices) {
  std::vector<std::uint8_t> out;
  out.reserve(4 + vertices.size() * 24);
  encode(vertices, out);
  return out;
}

std::size_t packed_size(const std::vector<TerrainVertexMsg>& vertices) {
  ByteCounter count;
  encode(vertices, count);
  return count.size;
}

std::vector<TerrainVertexMsg> unpack_vertices(std::span<const std::uint8_t> bytes) {
  Reader in(bytes);
  const std::uint64_t count = in.varint();
  if (count > in.left() / kMinVertexBytes) {
    in.fail(std::to_string(count) + " vertices announced, room for at most " +
            std::to_string(in.left() / kMinVertexBytes));
  }
  std::vector<TerrainVertexMsg> out(static_cast<std::size_t>(count));
  TerrainVertexMsg prev;
  for (TerrainVertexMsg& v : out) {
    v.i = next_index(in, prev.i, "i");
    v.j = next_index(in, prev.j, "j");
    const std::uint8_t a = in.byte();
    const std::uint8_t b = in.byte();
    const int n[kFields] = {a & 0xf, a >> 4, b & 0xf, b >> 4};
    for (int f = 0; f < kFields; ++f) {
      if (n[f] > 8) in.fail("field length " + std::to_string(n[f]) + " over 8");
      v.*kDoubles[f] = std::bit_cast<double>(std::bit_cast<std::uint64_t>(prev.*kDoubles[f]) ^
                                             in.low_bytes(n[f]));
    }
    prev = v;
  }
  if (in.left() > 0) in.fail(std::to_string(in.left()) + " bytes after the last vertex");
  return out;
}

}  // namespace syndds::proto
